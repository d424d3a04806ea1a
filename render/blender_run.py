"""Run an exported Blender script with a Blender that hairdigi does not import: a ``.blend`` with the
swatch groom, and the Cycles-against-Mitsuba check of an export.

``bpy`` 5.0.1 (the Blender-as-a-module package, 374 MB, Python 3.11) pins ``numpy<2``, while
hairdigi's OpenCV 5 and colour-science need numpy 2: the two cannot share one environment. So
Blender runs in its own process: ``HAIRDIGI_BLENDER`` names a Python that has ``bpy`` (a separate
venv) or a ``blender`` executable; without it, ``blender`` on the PATH is used.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hairdigi.render.domain import rig_geometry as rg
from hairdigi.render.domain.bounds import Environment
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import atomic_path
from hairdigi.render.interchange import HairLook, blender_script_text
from hairdigi.render.strands import SWATCH_LENGTH, SWATCH_WIDTH, Strands


class BlenderError(HairdigiError, RuntimeError):
    """No Blender to run, or Blender failed; the message says which and how to fix it."""


def blender_command() -> list[str] | None:
    """How to run a script in Blender: ``[python]`` (a Python with bpy) or ``[blender, -b, --python]``."""
    chosen = os.environ.get("HAIRDIGI_BLENDER") or shutil.which("blender")
    if not chosen:
        return None
    if not Path(chosen).exists() and not shutil.which(chosen):
        raise BlenderError(f"HAIRDIGI_BLENDER is {chosen!r}: no such program; name a Python that has bpy "
                           f"or a blender executable")
    if "blender" in Path(chosen).name.lower():
        return [chosen, "-b", "--factory-startup", "--python"]
    return [chosen]


def run_script(script: Path, args: list[str], timeout: float = 1800.0) -> str:
    """Run ``script`` in Blender with ``args`` (after ``--``); returns its output."""
    command = blender_command()
    if command is None:
        raise BlenderError("no Blender found: set HAIRDIGI_BLENDER to a Python that has bpy (python3.11 -m venv "
                           "VENV && VENV/bin/pip install bpy==5.0.1) or to a blender executable")
    proc = subprocess.run([*command, str(script), "--", *args], capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["no output"]
        raise BlenderError(f"Blender failed (exit {proc.returncode}): {tail[0]}")
    return proc.stdout


def probe_blender(timeout: float = 300.0) -> None:
    """Run a two-line script in the chosen Blender (it must import bpy and print); BlenderError if it does not,
    so that a broken ``HAIRDIGI_BLENDER`` stops a job before its work, not after it."""
    with tempfile.TemporaryDirectory(prefix="hairdigi-probe-") as tmp:
        script = Path(tmp) / "probe.py"
        script.write_text("import bpy\nprint('hairdigi-blender-ok', bpy.app.version_string)\n", encoding="utf-8")
        try:
            out = run_script(script, [], timeout=timeout)
        except subprocess.TimeoutExpired:
            raise BlenderError(f"HAIRDIGI_BLENDER did not answer a two-line script within {timeout:g} s; check "
                               f"that it runs: {os.environ.get('HAIRDIGI_BLENDER') or 'blender'}") from None
        except OSError as exc:
            raise BlenderError(f"Blender cannot be started ({exc.strerror or exc}); set HAIRDIGI_BLENDER to a Python "
                               f"that has bpy or to a blender executable") from None
    if "hairdigi-blender-ok" not in out:
        raise BlenderError("Blender ran but did not import bpy and print; set HAIRDIGI_BLENDER to a Python that "
                           "has bpy or to a blender executable")


#: The check's swatch: fibres in staggered layers that never pass through one another. The rig's own
#: swatch (``strands.swatch_strands``) lets fibres interpenetrate; Mitsuba's curves let a ray that
#: starts inside a fibre leave through it, Cycles intersects it, and the two then differ by up to ΔE2000
#: 6.4 for light hair (measured here, README). On these strands they agree, so the check compares the
#: BSDF mapping, not how each renderer handles fibres inside fibres.
CHECK_LAYERS, CHECK_RADIUS, CHECK_GAP = 3, 0.004, 1.25


def layered_swatch(layers: int = CHECK_LAYERS, radius: float = CHECK_RADIUS, gap: float = CHECK_GAP,
                   points: int = 12) -> Strands:
    """A swatch (1 x 1.4, strands along y, root at -y) of straight fibres in staggered layers, none touching."""
    pitch = 2 * radius * gap
    xs = np.arange(-SWATCH_WIDTH / 2, SWATCH_WIDTH / 2, pitch)
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, points)
    grid = [np.stack([np.full(points, x), y, np.full(points, radius * (1.01 + 1.74 * gap * k))], 1)
            for k in range(layers) for x in xs + (pitch / 2 if k % 2 else 0.0)]
    return Strands.from_grid(np.array(grid), radius)


def rig_for_blender(strands: Strands, pose: rg.CameraPose = rg.RIG_SWATCH_POSE, framing: rg.Framing = rg.Framing.CROP,
                    size: int | tuple[int, int] = 64, max_depth: int = 32, lights=(1.0,) * rg.N_LIGHTS,
                    env: Environment = Environment.STUDIO, bspline: bool = True) -> dict:
    """hairdigi's swatch rig as the Blender script builds it: ``strands`` as Mitsuba draws them (its
    B-splines sampled 4 times a segment; ``bspline=False``: the points as they are, for strands that
    are not Mitsuba's), the holder, the rig's lights at ``lights`` of full power and the camera at
    ``pose``; ``env`` ``"key-sky"`` adds the key light and the grey sky of ``scenes.key_and_sky``."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render import scenes

    curves = strands.curves(per_segment=4) if bspline else strands
    m = rg.look_at_matrix(pose.position(), np.zeros(3))
    width, height = (size, size) if isinstance(size, int) else size
    (cx, cy), (w, h) = rg.HOLDER_CENTER, rg.HOLDER_SIZE
    return {
        "strands": {"points": curves.points.astype(float).ravel().tolist(),
                    "radii": curves.radii.astype(float).tolist(), "counts": curves.counts.tolist()},
        "holder": {"corners": [[cx - w / 2, cy - h / 2, 0], [cx + w / 2, cy - h / 2, 0], [cx + w / 2, cy + h / 2, 0],
                               [cx - w / 2, cy + h / 2, 0]], "albedo": scenes.HOLDER_ALBEDO},
        "lights": [{"corners": rg.light_corners(i).tolist(), "radiance": scenes.LIGHT_RADIANCE * float(k)}
                   for i, k in enumerate(lights) if k > 0]
                  + ([{"corners": rg.square_corners(scenes.KEY_POSITION, scenes.KEY_SIZE).tolist(),
                       "radiance": scenes.KEY_RADIANCE}] if env == Environment.KEY_SKY else []),
        "sky": scenes.SKY_RADIANCE if env == Environment.KEY_SKY else 0.0,
        "camera": {"origin": m[:3, 3].tolist(), "left": m[:3, 0].tolist(), "up": m[:3, 1].tolist(),
                   "forward": m[:3, 2].tolist(), "fov_deg": rg.framing_fov(framing, pose.distance)},
        "size": [width, height], "max_depth": max_depth,
    }


def mitsuba_mean(look: HairLook, strands: Strands, pose: rg.CameraPose = rg.RIG_SWATCH_POSE,
                 framing: rg.Framing = rg.Framing.CROP, size: int = 64, spp: int = 256, max_depth: int = 32) -> tuple[np.ndarray, float]:
    """hairdigi's twin of ``look`` on ``strands`` in the rig (Mitsuba): mean linear colour and seconds. Rendered
    on the renderer's one path (``renderer.render_scene``: its lock, its scene order, its NaN count)."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render import scenes
    from hairdigi.render.renderer import render_scene
    from hairdigi.render.variant import select_variant

    select_variant(None)
    bsdf = {"type": "hair", "sigma_a": {"type": "rgb", "value": list(look.sigma_a)},
            "longitudinal_roughness": look.longitudinal_roughness, "azimuthal_roughness": look.azimuthal_roughness,
            "scale_tilt": look.tilt_deg, "int_ior": look.ior}
    with tempfile.TemporaryDirectory(prefix="hairdigi-twin-") as tmp:
        curve_file = Path(tmp) / "strands.txt"
        curve_file.write_text(strands.with_dummy().to_curve_text())
        start = time.perf_counter()
        image, _ = render_scene(scenes.swatch_scene(str(curve_file), bsdf, pose, size, framing=framing,
                                                    max_depth=max_depth), size, spp, seed=0)
    return image.reshape(-1, 3).mean(0), time.perf_counter() - start


@dataclass
class CyclesRender:
    """One Cycles render's output, checked as the renderer checks its own (``renderer.finite_image``)."""

    mean_linear: tuple[float, float, float]   # of the image with its NaN and Inf values set to 0
    seconds: float
    spp: int
    seed: int
    nonfinite: int                  # NaN or Inf values in Cycles' image, replaced by 0
    pixels: np.ndarray | None       # (H, W, 3) linear RGB, rows from the top, when asked for
    blender: str                    # Blender's version


def render_cycles(look: HairLook, rig: dict, spp: int, seed: int, threads: int = 0, pixels: bool = False,
                  folder: Path | None = None) -> CyclesRender:
    """The one way hairdigi renders in Cycles: ``look`` in ``rig`` (``rig_for_blender``) at ``spp`` and ``seed``.

    What of ``renderer.Renderer``'s guarantees hold for a render in another process: its seed fixes its
    image (the script sets ``cycles.seed`` and turns adaptive sampling and denoising off, so a seed and
    spp give one image whatever the threads); its NaN and Inf values are counted and replaced by 0 here,
    as ``renderer.finite_image`` does (the script returns its pixels for that), and the mean is then that
    image's. ``renderer.RENDER_LOCK`` does not apply: it keeps two Dr.Jit renders of one process apart, and
    Cycles runs in its own. ``folder`` keeps the script's files (default: a temporary folder).
    """
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import finite_image

    with tempfile.TemporaryDirectory(prefix="hairdigi-cycles-") as tmp:
        where = Path(folder) if folder is not None else Path(tmp)
        script, rig_file, result = where / "hair.py", where / "rig.json", where / "out.json"
        script.write_text(blender_script_text(look))
        rig_file.write_text(json.dumps(rig))
        run_script(script, ["--scene", str(rig_file), "--render", str(result), "--spp", str(int(spp)),
                            "--seed", str(int(seed)), "--threads", str(int(threads)), "--pixels"])
        out = json.loads(result.read_text())
        Path(out["exr"]).unlink(missing_ok=True)
    image, nonfinite = finite_image(np.asarray(out["pixels"], np.float32))
    # Blender's own mean when every value is finite (as before); else the mean of the image with them at 0
    mean = out["mean_linear"] if nonfinite == 0 else image.reshape(-1, 3).mean(0, dtype=np.float64)
    return CyclesRender(tuple(float(v) for v in mean), float(out["seconds"]), int(out["spp"]), int(seed), nonfinite,
                        image if pixels else None, str(out.get("blender", "")))


def write_blend(look: HairLook, out: str | Path, size: int = 256) -> Path:
    """A ``.blend`` with the look on a small groom of the swatch (``layered_swatch``), in the rig, ready to render."""
    out = Path(out).resolve()
    with tempfile.TemporaryDirectory(prefix="hairdigi-blend-") as tmp:
        script, rig = Path(tmp) / "hair.py", Path(tmp) / "rig.json"
        script.write_text(blender_script_text(look))
        rig.write_text(json.dumps(rig_for_blender(layered_swatch(), size=size)))
        blend = Path(tmp) / out.name
        run_script(script, ["--scene", str(rig), "--blend", str(blend)])
        with atomic_path(out) as target:
            shutil.copyfile(blend, target)
    return out


@dataclass
class CyclesCheck:
    """One colour rendered by Cycles from the export and by Mitsuba as hairdigi's twin."""

    sigma_a: tuple[float, float, float]
    cycles_linear: tuple[float, float, float]
    mitsuba_linear: tuple[float, float, float]
    delta_e2000: float
    cycles_seconds: float
    mitsuba_seconds: float


def cycles_check(look: HairLook, size: int = 48, spp: int = 64, mitsuba_spp: int = 256,
                 pose: rg.CameraPose = rg.RIG_SWATCH_POSE, threads: int = 0) -> CyclesCheck:
    """Render the exported script in Cycles and hairdigi's Mitsuba twin on the same strands, at the rig's
    pose (hair only in view); the ΔE2000 of their mean colours."""
    from hairdigi.render.metrics import delta_e2000   # deferred: loads colour-science (~1 s)

    strands = layered_swatch()
    cycles = render_cycles(look, rig_for_blender(strands, pose, rg.Framing.CROP, size), spp, seed=0, threads=threads)
    mitsuba, seconds = mitsuba_mean(look, strands, pose, rg.Framing.CROP, size, mitsuba_spp)
    return CyclesCheck(look.sigma_a, cycles.mean_linear, tuple(float(v) for v in mitsuba),
                       float(delta_e2000(np.asarray(cycles.mean_linear), mitsuba)), cycles.seconds, seconds)
