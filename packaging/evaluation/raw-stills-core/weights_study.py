"""For RAW stills: the assumed (layered) refinement's sigma mapped under several member weightings, judged."""
import sys, tempfile, json
from pathlib import Path
import numpy as np
from hairdigi.app.evaluation.rig import hidden_set, RigSet, SEED
from hairdigi.app.session.rig_session import RigSession
from hairdigi.hardware.sim_still import write_raw_still
from hairdigi.inference.encoder import Encoder
from hairdigi.inference.structure import family_curves, family_view, to_family, TEXTURE_MEMBERS
from hairdigi.inference.refine import params_for_sigma, RefineSettings
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.judge import judge, judge_scene
out, hs = sys.argv[1], sys.argv[2]
hs = () if hs == "layered" else tuple(hs.split(","))
hidden = hidden_set(RigSet(hidden_structures=hs))
rng = np.random.default_rng(SEED + 1)
draws = [(tuple(float(v) for v in rng.uniform(0.9, 1.1, 3)), float(rng.uniform(-0.5, 0.3))) for _ in hidden]
enc = Encoder(); rows = []
MEMBERS = ("layered","deposited","deposited-coarse","spread","wavy","tilted","loose")
with tempfile.TemporaryDirectory() as tmp:
    for k, (name, params) in enumerate(hidden):
        built = hs[k % len(hs)] if hs else None
        cast, ev = draws[k]
        s = RigSession.simulated_rig(Path(tmp)/f"s{k}", hidden=params, spp=32, encoder=enc, swatch_model=built, structure="assumed")
        still = write_raw_still(Path(tmp)/f"IMG_{k}.dng", s.camera.radiance().repeat(2, 0).repeat(2, 1)*np.array(cast)*2.0**ev*0.8)
        res = s.import_still(still); s.close()
        rec = res.record
        view = rec.refinement.region.rig
        sigma = np.asarray(rec.refinement.sigma_a, float)
        fam = family_curves(family_view(view), RefineSettings())
        scene = judge_scene(built)
        variants = {"assumed": None, "all": {}, "streakfree": TEXTURE_MEMBERS["streak-free"],
                    "streaked": {"deposited": 1, "deposited-coarse": 1, "spread": 1, "wavy": 1}}
        variants.update({m: {m: 1.0} for m in MEMBERS})
        row = {"k": k, "hidden": name, "structure": built or "layered", "roi": list(view.roi)}
        for v, w in variants.items():
            sig = sigma if w is None else to_family(sigma, fam, weights=w or None)
            p, _ = params_for_sigma(sig, rec.encoder.hair)
            row[v] = round(judge(params, hair_sigma_a(p), scene).de2000, 3)
        rows.append(row); print(row, flush=True)
        json.dump(rows, open(out, "w"), indent=1)
