"""RAW stills through the simulated rig, estimated on the swatch core (the study behind `inference.preprocess.swatch_core`).

stills.py: the rig evaluation's ten stills alone (python stills.py OUT.json MODE STRUCTURES): stills_drawn_core.json
(the core, mapped to the family's mean), stills_drawn_borrow.json (the rig's reading borrowed).
weights_study.py: each still's layered answer mapped through each member's curves alone (weights_drawn.json).
map_regions.py: the family map at a still's region against the live region's (map_regions.txt)."""
import json, numpy as np
from hairdigi.app.evaluation.rig import hidden_set, RigSet
from hairdigi.inference.structure import family_curves, family_view, to_family, TEXTURE_MEMBERS
from hairdigi.inference.refine import RefineSettings
from hairdigi.render.domain.rig_geometry import RigRegion
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.metrics import delta_e2000
from pathlib import Path
rows = json.load(open(Path(__file__).with_name("stills_drawn_core.json")))
live = family_curves(family_view(RigRegion((400, 300), (30, 56, 130, 189))), RefineSettings())
sigmas = [hair_sigma_a(p) for _, p in hidden_set(RigSet(random=20))]
for r in rows:
    v = family_view(RigRegion((800, 600), tuple(r["roi"])))
    fam = family_curves(v, RefineSettings())
    for w in (None, TEXTURE_MEMBERS["streak-free"]):
        d = [float(delta_e2000(np.clip(live.default(to_family(s, fam, weights=w)), 1e-9, None),
                               np.clip(live.default(to_family(s, live, weights=w)), 1e-9, None))) for s in sigmas]
        print(r["roi"], v.roi, "weights" if w else "all", "median", round(np.median(d), 3), "max", round(max(d), 3))
