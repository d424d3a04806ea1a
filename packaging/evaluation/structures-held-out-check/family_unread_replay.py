"""The family mode without single-light frames (a RAW still): every swatch's assumed answer mapped to the whole
family's mean, rendered on its hidden strands. Rows the ruled-out replay already mapped with the whole family reuse
its figures.

Run from packaging/evaluation after family_ruled_out_replay.py (about 15 minutes on 2 cores):
  python structures-held-out-check/family_unread_replay.py OUT.json family_ruled_out_replay.json \
      structures-held-out-tuning/structures_evaluation.json structures-held-out-check/structures_evaluation.json
Its last two lines (family_unread_replay.txt) are the shipped "family_unread" interval and the figures on other
structures. hairdigi evaluate --structures now measures this column itself ("family_unread")."""
import json, sys
import numpy as np
from hairdigi.inference.refine import RefineSettings
from hairdigi.inference.structure import family_curves, to_family
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.app.evaluation.structures_evaluation import _Mitsuba, StructureSet, _de

out, replay = sys.argv[1], json.load(open(sys.argv[2]))
family = family_curves(RIG_SWATCH_POSE, RefineSettings())
render = _Mitsuba(StructureSet(size=64, spp=64))
done = {(r["set"], r["hidden"], r["structure"], r["layout"]): r for r in replay}
res = []
for path in sys.argv[3:]:
    for r in [r for r in json.load(open(path))["rows"] if "shipped_fit" in r]:
        key = (path.split("/")[-2], r["hidden"], r["structure"], r["layout"])
        prev = done[key]
        row = {"set": key[0], "hidden": r["hidden"], "structure": r["structure"], "layout": r["layout"]}
        if prev["path"] == "mapped":
            row["unread"], row["unread_t"] = prev["Rall"], prev["Rall_t"]
        else:
            s, lay = r["structure"], r["layout"]
            truth = np.asarray(r["true_sigma_a"], float)
            ans = to_family(np.asarray(r["shipped_sigma_a"], float), family)
            row["unread"] = _de(render.mean(ans, s, lay, "rig", r["est_shine"]), render.mean(truth, s, lay, "rig", r["true_shine"]))
            row["unread_t"] = _de(render.mean(ans, s, lay, "transfer", r["est_shine"]), render.mean(truth, s, lay, "transfer", r["true_shine"]))
        res.append(row); print(row, flush=True)
        json.dump(res, open(out, "w"), indent=1)
v = np.array([x["unread"] for x in res])
print("all", len(v), "p68 %.3f p95 %.3f median %.2f" % (np.quantile(v, .68), np.quantile(v, .95), np.median(v)))
o = np.array([x["unread"] for x in res if x["structure"] != "layered"]); t = np.array([x["unread_t"] for x in res if x["structure"] != "layered"])
print("other", len(o), "fit %.2f / %.2f transfer %.2f / %.2f" % (np.median(o), np.quantile(o, .95), np.median(t), np.quantile(t, .95)))
