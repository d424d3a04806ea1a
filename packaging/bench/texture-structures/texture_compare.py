"""The shipped texture model (fitted on layered swatches) on samples of every family structure, by structure:
its grey share's bias and error, and how often it reports greys (95% interval above 0) where there are few."""
import json, sys, numpy as np
from pathlib import Path
from hairdigi.inference import texture
from hairdigi.inference.training import fit_texture as ft
model_path = sys.argv[1] if len(sys.argv) > 1 else None
model = texture.load_model(model_path)
samples = ft.load_samples()
hold = None
if len(sys.argv) > 2:   # only the held-out split of a refit on these samples
    n = len(samples); order = np.random.default_rng(ft.SEED).permutation(n)
    n_hold = max(5, int(round(ft.HOLDOUT_SHARE * n))); hold = set(order[:n_hold].tolist())
by = {}
for i, (truth, lights) in enumerate(samples):
    if hold is not None and i not in hold: continue
    f, cov, tgt = ft.sample_inputs(truth, lights)
    sigma, shine = ft.estimate_inputs(truth)
    r = texture.reading_from(model, f, sigma, shine)
    reported = r.intervals["grey_fraction"]["p95"][0] > 1e-3
    by.setdefault(truth.get("structure", "layered"), []).append((r.grey_fraction - tgt[1], reported, tgt[1]))
allv = []
for s, v in sorted(by.items()):
    e = np.array([x[0] for x in v]); allv += v
    print(f"{s:17s} n {len(v):3d}  grey bias {e.mean():+.3f}  MAE {np.abs(e).mean():.3f}  reported {np.mean([x[1] for x in v]):.2f}")
e = np.array([x[0] for x in allv]); print(f"{'all':17s} n {len(allv):3d}  grey bias {e.mean():+.3f}  MAE {np.abs(e).mean():.3f}")
