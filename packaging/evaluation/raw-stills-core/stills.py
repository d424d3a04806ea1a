"""RAW stills only, as evaluate --rig makes them (through the rig session's import_still): python stills.py OUT.json structure hidden_structures(comma or 'layered')"""
import sys, tempfile, time, json
from pathlib import Path
import numpy as np
from hairdigi.app.evaluation.rig import hidden_set, RigSet, SEED, _row
from hairdigi.app.session.rig_session import RigSession
from hairdigi.hardware.sim_still import write_raw_still
from hairdigi.inference.encoder import Encoder
out, structure, hs = sys.argv[1], sys.argv[2], sys.argv[3]
hs = () if hs == "layered" else tuple(hs.split(","))
cfg = RigSet(structure=structure, hidden_structures=hs)
hidden = hidden_set(cfg)
rng = np.random.default_rng(SEED + 1)
draws = [(tuple(float(v) for v in rng.uniform(0.9, 1.1, 3)), float(rng.uniform(-0.5, 0.3))) for _ in hidden]
enc = Encoder(); rows = []
with tempfile.TemporaryDirectory() as tmp:
    for k, (name, params) in enumerate(hidden):
        built = hs[k % len(hs)] if hs else None
        cast, ev = draws[k]
        s = RigSession.simulated_rig(Path(tmp)/f"s{k}", hidden=params, spp=32, encoder=enc, swatch_model=built, structure=structure)
        still = write_raw_still(Path(tmp)/f"IMG_{k}.dng", s.camera.radiance().repeat(2, 0).repeat(2, 1)*np.array(cast)*2.0**ev*0.8)
        t = time.perf_counter(); s.calibrate(); res = s.import_still(still); dt = time.perf_counter()-t
        row = _row(name, params, "raw still", cast, ev, res, dt, built)
        row["roi"] = res.record.refinement.region.rig.roi if res.record else None
        rows.append(row); s.close()
        print(k, name, built, round(row.get("de2000", -1), 2), row.get("residual_de2000"), round(dt, 1), row.get("structure_reading", "")[:90], flush=True)
        json.dump(rows, open(out, "w"), default=str, indent=1)
de = [r["de2000"] for r in rows if "de2000" in r]
print("median", np.median(de), "p95", np.quantile(de, 0.95), "worst", max(de))
