"""Replay the family mode's mapping on an evaluation's rows: hard rule (decisive read, else the whole family's
mean) against a subset rule (decisive read, else the mean of the members the frames do not rule out)."""
import json, sys
import numpy as np
from hairdigi.inference.refine import RefineSettings
from hairdigi.inference.structure import family_curves, family_weight, _averaged, DARK_SIGMA
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.app.evaluation.structures_evaluation import _Mitsuba, StructureSet, _de

path, out = sys.argv[1], sys.argv[2]
RATIO = float(sys.argv[3]) if len(sys.argv) > 3 else 2.0
rows = [r for r in json.load(open(path))["rows"] if "shipped_fit" in r]
family = family_curves(RIG_SWATCH_POSE, RefineSettings())
render = _Mitsuba(StructureSet(size=48, spp=64))
res = []
for r in rows:
    m = r["misfits"]; best = min(m.values())
    P = [k for k, v in m.items() if v <= RATIO * best]
    if "deposited" in P: P.append("wavy")
    sigma = np.asarray(r["shipped_sigma_a"], float)
    row = {"hidden": r["hidden"], "structure": r["structure"], "P": P, "old_family": r["family_fit"], "read": r["read_fit"],
           "shipped": r["shipped_fit"], "old_family_t": r["family_transfer"], "read_t": r["read_transfer"], "shipped_t": r["shipped_transfer"]}
    if len(P) == 1 or (len(P) == 2 and "wavy" in P and False):
        row["subset"] = r["read_fit"]; row["subset_t"] = r["read_transfer"]; row["how"] = "decisive"
    elif r["family_sigma_a"] == r["shipped_sigma_a"]:
        row["subset"] = r["family_fit"]; row["subset_t"] = r["family_transfer"]; row["how"] = "kept"
    else:
        sub = _averaged([family.members[k] for k in P])
        w = family_weight(sigma)
        mapped = sub.inverse(family.default(sigma))[0]
        ans = sigma * (np.clip(mapped, 1e-9, None) / np.clip(sigma, 1e-9, None)) ** w
        s, lay, shine = r["structure"], r["layout"], r["est_shine"]
        truth = np.asarray(r["true_sigma_a"], float)
        row["subset"] = _de(render.mean(ans, s, lay, "rig", shine), render.mean(truth, s, lay, "rig", r["true_shine"]))
        row["subset_t"] = _de(render.mean(ans, s, lay, "transfer", shine), render.mean(truth, s, lay, "transfer", r["true_shine"]))
        row["how"] = "subset"
    row["hard"] = r["read_fit"] if len([k for k in P if k != "wavy"]) == 1 else r["family_fit"]
    row["hard_t"] = r["read_transfer"] if len([k for k in P if k != "wavy"]) == 1 else r["family_transfer"]
    res.append(row); print(row, flush=True)
json.dump(res, open(out, "w"), indent=1)
o = [x for x in res if x["structure"] != "layered"]
for k in ["shipped", "old_family", "read", "hard", "subset"]:
    v = np.array([x[k] for x in o]); t = np.array([x[k + ("_t" if k != "hard" and k != "subset" else "_t")] for x in o])
    print(k, len(v), "fit %.2f / %.2f  transfer %.2f / %.2f" % (np.median(v), np.quantile(v, .95), np.median(t), np.quantile(t, .95)))
lay = [x for x in res if x["structure"] == "layered"]
print("layered", [(x["hidden"], x["shipped"], x["hard"], x["subset"]) for x in lay])
