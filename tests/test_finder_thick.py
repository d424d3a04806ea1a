"""The finder on real swatches: thick and thin, dark and light, short, off-centre and slightly rotated.

Each case is a RAW still of the whole rig frame, rendered with Mitsuba through the project's own scene
(``render.scenes.swatch_scene``: the holder, the chart, the rig's three lights and the bench camera),
its swatch the layered one (``render.strands.layered_swatch_strands``) stacked to a thickness that is a
share of its width, written as the simulated still camera's DNG (``hardware.sim_still``) and read back
through rawpy (``hardware.cameras.read_raw``), as ``hairdigi rig --still`` reads a still. A second render
(Mitsuba's ``position`` AOV, 2 x 2 samples a pixel) says which pixels show hair: a pixel whose first hit
lies above the holder. The region a rig still is estimated from (``find_swatch_core``) must hold hair
only, and its mean colour must be that of a crop of the same swatch that is hair only.

``rig_still`` is also what ``packaging/bench/finder-thick/finder_thick.py`` renders its table from.
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

#: Dark hair (sigma_a per fibre radius, RGB), as a thick dark swatch was read 2.4 ΔE2000 off; light hair
#: (the simulated rig's hidden copper-dyed light brown).
DARK = (4.0, 5.5, 8.0)
LIGHT = (0.07, 0.14, 0.31)
#: A test still: a quarter of the simulated rig's 400 x 300 frame, 16 samples a pixel.
SIZE, SPP = (240, 180), 16
#: A pixel is hair where at least this share of it shows a fibre.
HAIR_COVER = 0.5
#: The binding's length along the swatch, in scene units (the swatch is 1 wide).
BINDING = 0.12
#: Layers of the test swatches (the layered swatch's own count); their fibre radius sets the thickness.
LAYERS = 20


@dataclass(frozen=True)
class Swatch:
    """A swatch on the holder: its thickness as a share of its width, its length (the default 1.4 units),
    its centre (x, y) on the holder, its rotation in the holder's plane (degrees), and the albedo of a
    binding (a band of tape ``BINDING`` units long across its root end, over the fibres; None: none)."""

    thickness: float
    length: float = 1.4
    centre: tuple[float, float] = (0.0, 0.0)
    rotation_deg: float = 0.0
    binding: float | None = None
    seed: int = 0

    def strands(self):
        """The layered swatch stacked to ``thickness`` (its fibre radius chosen so that ``LAYERS`` layers
        fill it), cut to ``length``, turned and moved to ``centre``."""
        from hairdigi.render.strands import SWATCH_LENGTH, SWATCH_WIDTH, Strands, layered_swatch_strands

        # the layered swatch's top lies about 2.37 radii a layer, plus 1.2 radii, above the holder
        radius = self.thickness * SWATCH_WIDTH / (LAYERS * 2.37 + 1.2)
        per_layer = int(round(0.8 * SWATCH_WIDTH / (2 * radius)))
        strands = layered_swatch_strands(per_layer * LAYERS, seed=self.seed, radius=radius, layers=LAYERS)
        p = strands.points.astype(float).copy()
        p[:, 1] *= self.length / SWATCH_LENGTH
        a = np.radians(self.rotation_deg)
        x, y = p[:, 0].copy(), p[:, 1].copy()
        p[:, 0] = np.cos(a) * x - np.sin(a) * y + self.centre[0]
        p[:, 1] = np.sin(a) * x + np.cos(a) * y + self.centre[1]
        return Strands(p.astype(np.float32), strands.radii, strands.counts)

    def binding_shape(self, top: float) -> dict:
        """The binding as a Mitsuba rectangle ``top`` above the holder, across the swatch's root end (+y)."""
        from hairdigi.render.strands import SWATCH_WIDTH
        from hairdigi.render.variant import transform

        a = np.radians(self.rotation_deg)
        half = (SWATCH_WIDTH / 2 + 0.01, BINDING / 2)
        along = self.length / 2 - BINDING / 2
        cx, cy = self.centre[0] - np.sin(a) * along, self.centre[1] + np.cos(a) * along
        matrix = [[np.cos(a) * half[0], -np.sin(a) * half[1], 0, cx], [np.sin(a) * half[0], np.cos(a) * half[1], 0, cy],
                  [0, 0, 1, top], [0, 0, 0, 1]]
        return {"type": "rectangle", "to_world": transform(matrix),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(self.binding)] * 3}}}

    def hair_only_box(self, size: tuple[int, int], margin: float = 0.1) -> tuple[int, int, int, int]:
        """A crop of the rig frame that is hair only: the largest box inside the swatch's footprint on the
        holder inset by ``margin`` units, short of the binding (x, y, w, h pixels)."""
        from hairdigi.render.domain import rig_geometry as rg
        from hairdigi.render.strands import SWATCH_WIDTH

        a = np.radians(self.rotation_deg)
        hw, hl = SWATCH_WIDTH / 2 - margin, self.length / 2 - margin
        root = hl - (BINDING if self.binding is not None else 0.0)     # the root end, short of the binding
        local = np.array([(-hw, -hl), (hw, -hl), (hw, root), (-hw, root)])
        corners = local @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) + self.centre
        u, v = rg.rig_pixel(corners[:, 0], corners[:, 1], size)
        xs, ys = np.sort(u), np.sort(v)
        x0, x1, y0, y1 = int(np.ceil(xs[1])), int(np.floor(xs[2])), int(np.ceil(ys[1])), int(np.floor(ys[2]))
        return x0, y0, x1 - x0, y1 - y0


@dataclass
class Still:
    """A RAW still of the rig read back: 8-bit sRGB and linear camera RGB, and each pixel's hair cover."""

    srgb: np.ndarray
    linear: np.ndarray
    cover: np.ndarray
    path: Path | None = None     # the DNG, where it was kept

    def mean(self, box: tuple[int, int, int, int]) -> np.ndarray:
        x, y, w, h = box
        return self.linear[y:y + h, x:x + w].reshape(-1, 3).mean(0)

    def not_hair(self, box: tuple[int, int, int, int]) -> float:
        """The share of ``box``'s pixels that show no hair (holder, shadow, the chart)."""
        x, y, w, h = box
        return float((self.cover[y:y + h, x:x + w] < HAIR_COVER).mean())


def rig_still(swatch: Swatch, sigma_a, size: tuple[int, int] = SIZE, spp: int = SPP, seed: int = 1,
              upscale: int = 1, keep: Path | None = None) -> Still:
    """``swatch`` of ``sigma_a`` on the rig's holder beside the chart, lit by the rig's three lights and seen by
    the bench camera in a frame of ``size``, its glints spread as a sensor's (``spread_glints``), at the
    nominal exposure less 0.2 stops' headroom as ``hairdigi evaluate --rig`` takes its stills, ``upscale`` x
    the frame's pixels (a still camera of finer pixels), through the simulated still camera's DNG (kept at
    ``keep`` when given) and rawpy."""
    import cv2

    from hairdigi.hardware.cameras import read_raw
    from hairdigi.hardware.sim_still import write_raw_still
    from hairdigi.render import scenes
    from hairdigi.render.camera_model import NOMINAL_EXPOSURE, spread_glints
    from hairdigi.render.chart import colorchecker_reflectances
    from hairdigi.render.domain import rig_geometry as rg
    from hairdigi.render.renderer import render_scene, trace
    from hairdigi.render.variant import load_scene, mi

    bsdf = {"type": "hair", "sigma_a": {"type": "rgb", "value": [float(v) for v in sigma_a]},
            "longitudinal_roughness": 0.3, "azimuthal_roughness": 0.3}
    strands = swatch.strands()
    top = float((strands.points[:, 2] + strands.radii).max()) + 0.002     # the binding lies over the fibres
    with tempfile.TemporaryDirectory(prefix="hairdigi-finder-thick-") as tmp:
        curves = Path(tmp) / "swatch.txt"
        curves.write_text(strands.with_dummy().to_curve_text())

        def scene(film: tuple[int, int], chart) -> dict:
            built = scenes.swatch_scene(str(curves), bsdf, rg.CameraPose(), film, rg.Framing.RIG, 32, chart=chart,
                                        target=rg.RIG_TARGET, half_width=rg.RIG_HALF_WIDTH)
            if swatch.binding is not None:
                built["binding"] = swatch.binding_shape(top)
            return built

        linear, _ = render_scene(scene(size, colorchecker_reflectances()), size, spp, seed)
        fine = (2 * size[0], 2 * size[1])
        where, _ = trace(load_scene(scene(fine, None)), fine, 1, seed, mi.load_dict({"type": "aov", "aovs": "p:position"}))
        fibre = (where[..., 2] > 1e-4) & (where[..., 2] < top - 0.001)      # above the holder, below the binding
        cover = cv2.resize(fibre.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        radiance = spread_glints(linear) * NOMINAL_EXPOSURE * 0.8
        if upscale > 1:
            radiance = radiance.repeat(upscale, 0).repeat(upscale, 1)
            cover = cover.repeat(upscale, 0).repeat(upscale, 1)
        path = write_raw_still(keep or Path(tmp) / "IMG_0001.dng", radiance)
        frame = read_raw(path)
    return Still(frame.srgb, frame.linear, cover, keep)


# --- the tests ---------------------------------------------------------------------------------
#: A region holding more than this share of pixels without hair holds shadow, holder or binding.
MOST_NOT_HAIR = 0.001
#: The region's mean colour lies within this ΔE2000 of a hair-only crop of the same swatch (light hair's colour
#: varies this much between boxes of hair alone under the rig's lights; the shadow's pixels cost 3-4).
MOST_DE = 1.0


def check_hair_only(swatch: Swatch, sigma_a) -> tuple[int, int, int, int]:
    """Render ``swatch`` of ``sigma_a`` in a RAW still and check the region a still is estimated from: hair
    only, of a hair-only crop's colour, and most of the swatch (at least 80% of that crop's area)."""
    from hairdigi.inference.preprocess import find_swatch_core
    from hairdigi.render.metrics import delta_e2000

    still = rig_still(swatch, sigma_a)
    roi = find_swatch_core(still.srgb)[0]
    region = (roi.x, roi.y, roi.w, roi.h)
    crop = swatch.hair_only_box((still.srgb.shape[1], still.srgb.shape[0]))
    assert still.not_hair(crop) == 0.0, crop                                   # the reference is hair
    assert still.not_hair(region) <= MOST_NOT_HAIR, (region, still.not_hair(region))
    assert float(delta_e2000(still.mean(region), still.mean(crop))) <= MOST_DE, region
    assert roi.w * roi.h >= 0.8 * crop[2] * crop[3], (region, crop)
    return region


@pytest.mark.parametrize("swatch", [Swatch(0.20), Swatch(0.18, rotation_deg=4.0)], ids=["20%", "18%, turned 4°"])
def test_a_thick_dark_swatch_is_estimated_from_its_hair_alone(swatch):
    """A dark swatch (sigma_a 4-8) a fifth as thick as it is wide casts a shadow on the holder under the rig's
    lights, as dark to the finder's blurred score as the hair beside it. The found box held the shadow and
    a halo of holder, and its core (``CORE_INSET``) reached into them: 0.8% of it shadow, which in so dark a
    swatch is most of its light. The region now holds hair alone."""
    check_hair_only(swatch, DARK)


@pytest.mark.parametrize("swatch, sigma_a", [
    (Swatch(0.15, length=0.8, centre=(-0.05, 0.2), binding=0.8), DARK),
    (Swatch(0.15, length=0.8, centre=(-0.05, -0.25)), LIGHT),
], ids=["dark, bound", "light"])
def test_a_short_off_centre_swatch_is_estimated_from_its_hair_alone(swatch, sigma_a):
    """A short swatch (0.8 of the default's length) off the frame's centre, thick (15%): its shadow is a large
    share of its found box, so a fixed inset of that box left 6-13% of the region shadow and holder (dark:
    3.7 ΔE2000 from its hair, the estimate sigma_a 0.54 for 4-8); the dark one's white binding across its
    root end is not hair either."""
    check_hair_only(swatch, sigma_a)


@pytest.mark.parametrize("swatch", [Swatch(0.05), Swatch(0.10, rotation_deg=3.0, binding=0.05)],
                         ids=["5%", "10%, turned 3°, bound"])
def test_a_thin_light_swatch_is_still_estimated_from_its_hair(swatch):
    """A thin (5%) light swatch, whose texture the shadow of a thick one lacks but whose colour spread is wide,
    and a light one turned and bound with black tape: hair only, and most of it."""
    check_hair_only(swatch, LIGHT)


def test_the_largest_box_of_hair():
    """``largest_box``: the largest axis-aligned box inside a mask (a turned square's inner box, not its rows)."""
    import cv2

    from hairdigi.inference.preprocess import largest_box

    mask = np.zeros((60, 80), np.uint8)
    cv2.fillConvexPoly(mask, np.array([[20, 5], [70, 10], [65, 55], [15, 50]], np.int32), 1)
    x, y, w, h = largest_box(mask > 0)
    assert mask[y:y + h, x:x + w].all() and w * h >= 0.7 * mask.sum()
    assert largest_box(np.zeros((5, 5), bool)) == (0, 0, 0, 0)
