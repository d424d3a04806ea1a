"""Is the image seen from the camera the estimate assumes? The swatch's outline says.

The swatch is a 1 x 1.4 rectangle on the holder (``rig_geometry.SWATCH_HALF``), its fibres along its
long side. Seen by a camera tilted ``polar`` degrees from the holder's normal, towards ``azimuth``,
its sides shorten and its corners open (nearly an orthographic projection: the rig's views are
narrow), so its outline gives the tilt back (from about 22°: below, the sides change less than the
swatch's blurred edge moves them), and the azimuth up to its sign and a half turn: not enough to
render from. Without ``--camera`` the estimate assumes the rig's pose. A rig frame (the chart in
view) whose outline reads another tilt, and any swatch on its holder without the chart (neither the
bench camera's frame nor an all-hair crop), are warned of, and the colour interval widened to what
unknown cameras measured.
"""
from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np

from hairdigi.render.domain.estimate_parts import Uncertainty
from hairdigi.render.domain.rig_geometry import SWATCH_HALF, SWATCH_VISIBLE_HALF_LENGTH


def outline_shape(corners: np.ndarray) -> tuple[float, float]:
    """(the side along the fibres over the side across them, the |cosine| of the angle between them)
    of a quadrilateral's outline, opposite sides averaged; the fibres run along the side nearer the
    image's vertical (the rig's camera sees them so)."""
    c = np.asarray(corners, float)
    sides = [c[(i + 1) % 4] - c[i] for i in range(4)]
    first = (sides[0] - sides[2]) / 2.0       # the mean of each pair of opposite sides, one direction
    second = (sides[1] - sides[3]) / 2.0
    a, b = float(np.linalg.norm(first)), float(np.linalg.norm(second))
    cosine = abs(float(np.dot(first, second) / max(a * b, 1e-9)))
    along, across = (a, b) if abs(first[1]) / max(a, 1e-9) >= abs(second[1]) / max(b, 1e-9) else (b, a)
    return along / max(across, 1e-9), cosine


@functools.lru_cache(maxsize=1)
def _shape_table() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Outline shapes (along over across the fibres, |cosine|) over tilts (0-80°, 0.5° steps) and
    azimuths (0-179°, 1° steps)."""
    polar, azimuth = np.meshgrid(np.arange(0.0, 80.5, 0.5), np.arange(0.0, 180.0, 1.0), indexing="ij")
    sx = np.sin(np.radians(polar)) * np.cos(np.radians(azimuth))   # the view direction along the short side
    sy = np.sin(np.radians(polar)) * np.sin(np.radians(azimuth))   # ... and along the fibres
    lx, ly = np.sqrt(1 - sx**2) * SWATCH_HALF[0], np.sqrt(1 - sy**2) * SWATCH_VISIBLE_HALF_LENGTH
    aspect = ly / lx
    cosine = np.abs(sx * sy) / np.sqrt((1 - sx**2) * (1 - sy**2))
    return polar, azimuth, aspect, cosine


def outline_tilt(corners: np.ndarray) -> tuple[float, float]:
    """The camera's (tilt from the holder's normal, azimuth modulo 180°) that best gives this outline."""
    aspect, cosine = outline_shape(corners)
    polar, azimuth, table_aspect, table_cosine = _shape_table()
    misfit = (np.log(table_aspect / aspect) / 0.03) ** 2 + ((table_cosine - cosine) / 0.03) ** 2
    k = np.unravel_index(int(np.argmin(misfit)), misfit.shape)
    return float(polar[k]), float(azimuth[k])


#: A tilt read this far from the assumed camera's is not the assumed camera (degrees), when it is at
#: least ``MIN_TILT``. The outline's sides change little at small tilts (cos 20° = 0.94), and a swatch's
#: blurred edge moves them as much: rig-framed renders (96²) at 30-55° read within 6° of the truth,
#: at 10° 16-22°, and the bench camera's frames (tilt 0, 200-400 px) 3-16°.
TILT_TOLERANCE = 12.0
MIN_TILT = 22.0
#: Mean-colour ΔE2000 (68%, 95%) of estimates of rig-framed swatches seen from 20° and 30° without
#: ``--camera`` (``python -m hairdigi.app.evaluation.views_evaluation --no-camera --polars 20,30
#: --azimuths 0,90,180,270 --hairs brown,platinum,red,black``).
UNKNOWN_VIEW_DE = (3.38, 5.11)


def view_warning(outline: np.ndarray | None, assumed_tilt: float, rig_view: bool) -> str | None:
    """One line when the camera is not known to be the assumed one; None when it is, or when no swatch
    outline is in view (an all-hair crop: the rig's swatch pose is assumed, as documented).

    A rig frame (the chart in view) is warned of when its swatch's outline reads a tilt of at least
    ``MIN_TILT``, ``TILT_TOLERANCE`` from the bench camera's ``assumed_tilt``. A swatch on its holder
    without the chart is neither the bench camera's frame nor an all-hair crop: its pose is unknown,
    and it is always warned of, with the tilt its outline reads where it can be read."""
    if outline is None:
        return None
    tilt, azimuth = outline_tilt(outline)
    readable = tilt >= MIN_TILT
    if rig_view and (not readable or abs(tilt - assumed_tilt) <= TILT_TOLERANCE):
        return None
    seen = (f"its outline says the camera is tilted about {tilt:.0f}° from the holder's normal, azimuth "
            f"{azimuth:.0f}° up to its sign and a half turn" if readable else
            f"its outline reads no tilt over {MIN_TILT:.0f}°")
    what = ("this rig frame is not the bench camera's view" if rig_view else
            "a swatch on its holder without the chart: its camera is unknown")
    return (f"camera: {what} ({seen}), and the estimate assumes {assumed_tilt:.1f}°; its colour interval is "
            f"widened to an unknown camera's: pass --camera POLAR,AZIMUTH")


def widened(uncertainty: Uncertainty, de: tuple[float, float] | None = None) -> Uncertainty:
    """The record's colour interval widened to an unknown camera's (``UNKNOWN_VIEW_DE``)."""
    p68, p95 = de or UNKNOWN_VIEW_DE
    return replace(uncertainty,
                   mean_colour_de2000_p68=round(max(uncertainty.mean_colour_de2000_p68 or 0.0, p68), 3),
                   mean_colour_de2000_p95=round(max(uncertainty.mean_colour_de2000_p95 or 0.0, p95), 3),
                   mean_colour_source=f"{uncertainty.mean_colour_source or ''}; widened: the camera is not known to "
                                      f"be the assumed one (rig-framed swatches from 20-30° estimated without "
                                      f"--camera, evaluate_views --no-camera)")
