"""Rig-framed swatches of hairdigi's own world seen from other cameras, estimated and judged.

Each hidden hair is rendered on its holder (``framing="rig"``, no chart) from a camera pose, estimated
as ``hairdigi estimate`` does (with ``--camera`` the pose, or without it: the rig's assumed), and
judged against the truth (``render.judge``: mean-colour ΔE2000 of common-seed renders). A row also says
whether the estimate read the swatch: the share of the encoder's crop that lies on the swatch (its
outline projected from the pose), so that an answer from a wrong region is counted, not hidden.

    python -m hairdigi.app.evaluation.views_evaluation --polars 35,55 --azimuths 0,150,270
"""
from __future__ import annotations

import argparse
import json
import time

import cv2
import numpy as np

from hairdigi.inference.encoder import Encoder
from hairdigi.inference.estimate import estimate_image
from hairdigi.inference.preprocess import MIN_SIDE, ROI_CENTRAL, ImageError, find_swatch
from hairdigi.inference.view_check import outline_tilt, view_warning
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateWarning, WarningKind
from hairdigi.render.domain.rig_geometry import (FRAMING_HALF_WIDTH, RIG_SWATCH_POSE, SWATCH_HALF,
                                                 SWATCH_VISIBLE_HALF_LENGTH, CameraPose, Framing, project)
from hairdigi.render.judge import judge

#: Hidden hairs: the hard cases of ``hairdigi evaluate --rig`` (black, platinum, a saturated red, copper)
#: and a mid brown.
HAIRS = {"black": HairParams((255, 255, 255), 0.0, 1.0, 0.95), "platinum": HairParams((255, 255, 255), 0.0, 0.05, 0.3),
         "brown": HairParams((255, 255, 255), 0.0, 0.5, 0.8), "red": HairParams((230, 20, 20), 0.9, 0.1, 0.3),
         "copper": HairParams((200, 90, 30), 0.6, 0.3, 0.2)}
SIZE, SPP, SEED = 96, 64, 3
WRONG_REGION = 0.9     # a crop less than this share on the swatch reads a wrong region


def swatch_outline(pose: CameraPose, size: int = SIZE) -> np.ndarray:
    """(4, 2) pixel corners of the swatch's visible area in a rig-framed render from ``pose``."""
    hx, hy = SWATCH_HALF[0], SWATCH_VISIBLE_HALF_LENGTH
    corners = np.array([(-hx, hy, 0.0), (hx, hy, 0.0), (hx, -hy, 0.0), (-hx, -hy, 0.0)])
    return project(corners, pose, (0.0, 0.0, 0.0), FRAMING_HALF_WIDTH[Framing.RIG], (size, size))


def share_on_swatch(box: tuple[int, int, int, int], outline: np.ndarray, size: int = SIZE) -> float:
    """Share of the pixels of ``box`` (x, y, w, h) inside the swatch's ``outline``."""
    inside = np.zeros((size, size), np.uint8)
    cv2.fillConvexPoly(inside, np.round(outline).astype(np.int32), 1)
    x, y, w, h = box
    return float(inside[y:y + h, x:x + w].mean()) if w * h else 0.0


def crop_box(roi, size: int = SIZE) -> tuple[int, int, int, int]:
    """The encoder's crop of ``roi`` (``preprocess.swatch_crop``'s central square), as x, y, w, h."""
    share = 1.0 if (roi.w, roi.h) == (size, size) else ROI_CENTRAL
    side = max(MIN_SIDE // 2, int(round(min(roi.w, roi.h) * share)))
    return roi.x + (roi.w - side) // 2, roi.y + (roi.h - side) // 2, side, side


def view_image(name: str, pose: CameraPose, renderer) -> np.ndarray:
    """The hidden hair ``name`` on its holder seen from ``pose`` (rig framing, no chart), 8-bit sRGB."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec

    return renderer.render(HAIRS[name], SceneSpec("swatch", camera=pose, framing="rig"), SIZE, SPP, seed=SEED).srgb


def view_row(name: str, hair: HairParams, pose: CameraPose, encoder, renderer, camera_given: bool) -> dict:
    """One hidden hair from one pose: the render, the estimate (with or without the pose) and the verdict."""
    image = view_image(name, pose, renderer)
    row = {"hair": name, "polar_deg": pose.polar_deg, "azimuth_deg": pose.azimuth_deg, "camera_given": camera_given}
    try:
        roi, outline = find_swatch(image)
        # without the pose, as hairdigi estimate does: the rig's assumed, checked against the outline
        warned = None if camera_given else view_warning(outline, RIG_SWATCH_POSE.polar_deg, rig_view=False)
        result = estimate_image(image, encoder, roi=roi, view=pose if camera_given else RIG_SWATCH_POSE,
                                renderer=renderer,
                                extra_warnings=[EstimateWarning(WarningKind.OTHER, warned)] if warned else [])
    except ImageError as exc:
        return row | {"refused": str(exc)}
    row["tilt_read"] = None if outline is None else outline_tilt(outline)[0]
    row |= {"roi": [roi.x, roi.y, roi.w, roi.h], "on_swatch": share_on_swatch(crop_box(roi), swatch_outline(pose)),
            "de2000": judge(hair, result.params, renderer=renderer).de2000,
            "residual_de2000": result.refinement.residual_de2000,
            "warnings": [w.message for w in result.warnings if w.kind.value != "appearance"],
            "interval_p68": result.uncertainty.mean_colour_de2000_p68}
    return row


def summarise_views(rows: list[dict], warn_above: float = 2.0) -> dict:
    """Median / p95 / worst ΔE2000 of the estimates, refusals, answers from a wrong region, and the
    estimates off by more than ``warn_above`` that carry no warning."""
    judged = [r for r in rows if "de2000" in r]
    de = np.array([r["de2000"] for r in judged]) if judged else np.array([np.nan])
    return {"n": len(rows), "estimated": len(judged), "refused": len(rows) - len(judged),
            "median": float(np.median(de)), "p95": float(np.quantile(de, 0.95)), "worst": float(de.max()),
            "wrong_region": sum(r["on_swatch"] < WRONG_REGION for r in judged),
            f"unwarned_over_{warn_above:g}": sum(r["de2000"] > warn_above and not r["warnings"] for r in judged)}


def evaluate_views(polars, azimuths, hairs=tuple(HAIRS), camera_given: bool = True, progress: bool = True) -> dict:
    """Every hair in ``hairs`` from every (polar, azimuth): rows and their summary."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import Renderer

    encoder, renderer, rows = Encoder(), Renderer(max_cached=2), []
    start = time.perf_counter()
    for name in hairs:
        for polar in polars:
            for azimuth in azimuths:
                rows.append(view_row(name, HAIRS[name], CameraPose(polar, azimuth), encoder, renderer, camera_given))
                if progress:
                    print(json.dumps({k: (round(v, 3) if isinstance(v, float) else v) for k, v in rows[-1].items()}),
                          flush=True)
    return {"summary": summarise_views(rows) | {"seconds": time.perf_counter() - start}, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    # deferred: loads Mitsuba; this entry point chooses the variant (below), not an import
    from hairdigi.render.variant import select_variant

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--polars", default="35,55")
    p.add_argument("--azimuths", default="0,150,270", help="away from the lights (90, 210, 330 at 45° and over)")
    p.add_argument("--hairs", default=",".join(HAIRS))
    p.add_argument("--no-camera", action="store_true", help="estimate without the pose (the rig's assumed)")
    args = p.parse_args(argv)
    select_variant("auto")
    out = evaluate_views([float(v) for v in args.polars.split(",")], [float(v) for v in args.azimuths.split(",")],
                         args.hairs.split(","), camera_given=not args.no_camera)
    print(json.dumps(out["summary"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
