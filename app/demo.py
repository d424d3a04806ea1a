"""The headless demo: render the sample swatch and two hairstyles, and say where they are."""
from __future__ import annotations

from pathlib import Path

from render.imageio import save_png
from render.params import load_params
from render.renderer import SceneSpec, render
from resources import SAMPLE_PARAMS


def run_demo(out: Path, quick: bool = False) -> list[Path]:
    """Render the sample hair as a rig frame and as two hairstyles; return the written files."""
    params = load_params(SAMPLE_PARAMS)
    print(f"hair parameters ({SAMPLE_PARAMS.name}): {params.to_dict()}")
    jobs = [
        ("swatch", SceneSpec("swatch", framing="rig"), 64 if quick else 256, 4 if quick else 32),
        ("straight", SceneSpec("straight", env="studio", strands=300 if quick else None), 64 if quick else 384, 2 if quick else 16),
        ("curly", SceneSpec("curly", env="soft", strands=300 if quick else None), 64 if quick else 384, 2 if quick else 16),
    ]
    written = []
    for name, spec, size, spp in jobs:
        result = render(params, spec, size, spp, seed=0)
        path = save_png(out / f"{name}.png", result.srgb)
        print(f"  {path}  ({size}x{size}, {spp} spp, {result.seconds:.1f} s)")
        written.append(path)
    print(f"demo images are in {out.resolve()}")
    return written
