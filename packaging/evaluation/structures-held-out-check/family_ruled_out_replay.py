"""Replay the family mode's mapping on structures evaluations' rows: the whole family's mean (today) against the
mean of the members the single-light frames do not rule out (misfit under R times the best's), R in RULES.

Run from packaging/evaluation (about 30 minutes on 2 cores; the family's curves at the rig's pose cached):
  python structures-held-out-check/family_ruled_out_replay.py OUT.json structures-held-out-tuning/structures_evaluation.json \
      structures-held-out-check/structures_evaluation.json
Rows "decided" take the read mode's figures, "reread" the recorded family figures (the out-of-reach rule read them),
"mapped" are rendered again on their hidden strands at the evaluation's size and samples. The summary is in
family_ruled_out_replay.txt ("all" is the whole family, the rule before this one)."""
import json, sys
import numpy as np
from hairdigi.inference.refine import RefineSettings
from hairdigi.inference.structure import family_curves, family_weight, _averaged, decisive
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.app.evaluation.structures_evaluation import _Mitsuba, StructureSet, _de

out = sys.argv[1]
RULES = [3.0, 5.0, 10.0]
family = family_curves(RIG_SWATCH_POSE, RefineSettings())
render = _Mitsuba(StructureSet(size=64, spp=64))
res = []
for path in sys.argv[2:]:
    rows = [r for r in json.load(open(path))["rows"] if "shipped_fit" in r]
    for r in rows:
        m = r["misfits"]; best = min(m.values())
        decided = decisive(m)
        sigma = np.asarray(r["shipped_sigma_a"], float)
        row = {"set": path.split("/")[-2], "hidden": r["hidden"], "structure": r["structure"], "layout": r["layout"],
               "shipped": r["shipped_fit"], "shipped_t": r["shipped_transfer"], "read": r["read_fit"], "read_t": r["read_transfer"],
               "ratio": sorted(m.values())[1] / max(best, 1e-9)}
        if "family_structure" in r:
            path_ = "decided" if decided else ("mapped" if r["family_structure"] == "layered" else "reread")
        else:
            path_ = "decided" if decided else ("reread" if r["family_sigma_a"] == r["read_sigma_a"] and r["family_sigma_a"] != r["shipped_sigma_a"] else "mapped")
        row["path"] = path_
        if path_ == "decided":
            for R in RULES + ["all"]:
                row[f"R{R}"], row[f"R{R}_t"] = r["read_fit"], r["read_transfer"]
        elif path_ == "reread":
            for R in RULES + ["all"]:
                row[f"R{R}"], row[f"R{R}_t"] = r["family_fit"], r["family_transfer"]
        else:
            s, lay = r["structure"], r["layout"]
            truth = np.asarray(r["true_sigma_a"], float)
            t_rig = render.mean(truth, s, lay, "rig", r["true_shine"]); t_tr = render.mean(truth, s, lay, "transfer", r["true_shine"])
            for R in RULES + ["all"]:
                P = list(m) if R == "all" else [k for k, v in m.items() if v < R * best]
                if "deposited" in P or R == "all": P.append("wavy")
                P = [k for k in dict.fromkeys(P) if k in family.members]
                w = family_weight(sigma)
                mapped = _averaged([family.members[k] for k in P]).inverse(family.default(sigma))[0]
                ans = sigma * (np.clip(mapped, 1e-9, None) / np.clip(sigma, 1e-9, None)) ** w
                row[f"R{R}"] = _de(render.mean(ans, s, lay, "rig", r["est_shine"]), t_rig)
                row[f"R{R}_t"] = _de(render.mean(ans, s, lay, "transfer", r["est_shine"]), t_tr)
                row[f"P{R}"] = P
            row["family_recorded"] = r["family_fit"]
        res.append(row); print(row, flush=True)
        json.dump(res, open(out, "w"), indent=1)
for name, sel in [("other", lambda x: x["structure"] != "layered"), ("layered", lambda x: x["structure"] == "layered")]:
    o = [x for x in res if sel(x)]
    for k in ["shipped", "read"] + [f"R{R}" for R in RULES + ["all"]]:
        v = np.array([x[k] for x in o]); t = np.array([x[k + "_t"] for x in o])
        print(name, k, len(v), "fit %.2f / %.2f  transfer %.2f / %.2f" % (np.median(v), np.quantile(v, .95), np.median(t), np.quantile(t, .95)))
