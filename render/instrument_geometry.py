"""What a lab's colour instrument reads of a swatch: the instrument's geometry as a Mitsuba scene.

A hair-colour lab records a tress as a spectrophotometer or colorimeter reads it (CIE 15:2004, §5):

- **d/8° SCI**: an integrating sphere lights the spot evenly from every direction above it, and the
  instrument looks at it 8° off its normal; the specular component is included (the sphere's wall
  stands where the mirror direction points);
- **d/8° SCE**: the same, with a light trap at the mirror direction (``TRAP_HALF_ANGLE_DEG``), so the
  light a glossy surface mirrors into the view is excluded;
- **45°/0°**: a ring of light at 45° from the normal (annular, "45°a"), viewed along the normal: the
  specular reflection of a flat sample points away from the view.

Each is a scene of the swatch's own fibres on the rig's holder (``render.scenes.swatch_scene``'s
holder, at the centre of the swatch), seen by an orthographic sensor whose film covers the
instrument's aperture, a disc of ``aperture_mm`` on the swatch's centre (1 scene unit = 50 mm,
``render.strands``); only the film's pixels inside the disc count. The sphere is Mitsuba's
``constant`` emitter, of radiance 1: a perfect white diffuser then reads 1, so a pixel's value is the
reflectance factor. The trap is a black disc far along the mirror direction that hides the sphere's
light there, as the trap's hole in a sphere's wall does. The ring is ``RING_LIGHTS`` directional
lights whose irradiance is set so that the white diffuser reads 1 there too.

The swatch's colour per wavelength depends only on that wavelength's absorption (the holder is grey,
the lights white), so an RGB render of three flat ``sigma_a`` levels gives three points of the
geometry's reflectance curve (:func:`reflectance_ladder`); the instrument reading of any hair is that
curve read per wavelength, weighed by an illuminant and an observer (:func:`lab_of_reflectance`).
:func:`spectral_tristimulus` renders the same geometry spectrally (``specfilm`` with the observer's
bands under the illuminant): the virtual instrument the evaluations judge against.
"""
from __future__ import annotations

import functools
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hairdigi.render.domain.absorption import hair_bsdf
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import HOLDER_CENTER, HOLDER_SIZE, look_at_matrix

#: mm per scene unit: the holder's swatch is 1 unit wide, a 50 mm swatch (``render.strands``).
MM_PER_UNIT = 50.0
#: The aperture's diameter, mm: a small-area view (Konica Minolta's CM-700d "MAV", 8 mm); 3-25 mm accepted.
DEFAULT_APERTURE_MM = 8.0
APERTURE_RANGE_MM = (3.0, 25.0)
#: The specular trap's half angle (degrees) about the mirror direction of the view.
TRAP_HALF_ANGLE_DEG = 5.0
#: How far the trap's disc stands from the spot (scene units): the spot's 8-25 mm shift its direction < 0.3°.
TRAP_DISTANCE = 50.0
#: Directional lights that make the 45° ring.
RING_LIGHTS = 36
#: How far apart (scene units: 12.5 mm) the spots of a multi-spot reading lie along the fibres.
SPOT_STEP = 0.25
#: The observers and illuminants a reading may be made in (colour-science's names).
OBSERVERS = {"10": "CIE 1964 10 Degree Standard Observer", "2": "CIE 1931 2 Degree Standard Observer"}
ILLUMINANTS = ("D65", "D50", "A", "F2", "F11")
HOLDER_ALBEDO = 0.18


class InstrumentError(HairdigiError, ValueError):
    """An instrument geometry, aperture, observer or illuminant this module does not know; the message names the fix."""


@dataclass(frozen=True)
class Geometry:
    """An instrument's illuminating and viewing geometry (CIE 15:2004, §5)."""

    name: str
    diffuse: bool                  # an integrating sphere; False: a 45° ring
    view_deg: float                # the view's angle from the sample's normal
    specular_included: bool = True

    @property
    def trap(self) -> bool:
        return self.diffuse and not self.specular_included


#: The geometries, by name: a registry, as colour-science's method registries.
GEOMETRIES: dict[str, Geometry] = {
    "d/8 SCI": Geometry("d/8 SCI", diffuse=True, view_deg=8.0, specular_included=True),
    "d/8 SCE": Geometry("d/8 SCE", diffuse=True, view_deg=8.0, specular_included=False),
    "45/0": Geometry("45/0", diffuse=False, view_deg=0.0),
}


def geometry(name: str | Geometry) -> Geometry:
    """The geometry named ``name`` (``GEOMETRIES``; "d/8° SCI", "di:8", "45/0", "45a:0" spelt loosely)."""
    if isinstance(name, Geometry):
        return name
    key = str(name).replace("°", "").replace(":", "/").replace("45a", "45").strip()
    key = {"di/8": "d/8 SCI", "de/8": "d/8 SCE", "d/8": "d/8 SCI", "d/8sci": "d/8 SCI",
           "d/8sce": "d/8 SCE"}.get(key.lower().replace(" ", ""), key)
    for known in GEOMETRIES:
        if known.lower() == key.lower():
            return GEOMETRIES[known]
    raise InstrumentError(f"unknown instrument geometry {name!r}; choose one of {', '.join(GEOMETRIES)}")


def check_aperture(aperture_mm: float) -> float:
    lo, hi = APERTURE_RANGE_MM
    value = float(aperture_mm)
    if not np.isfinite(value) or not lo <= value <= hi:
        raise InstrumentError(f"aperture {aperture_mm!r} mm: give a spot between {lo:g} and {hi:g} mm "
                              f"(the swatch is {MM_PER_UNIT:g} mm wide)")
    return value


def check_observer(observer: str) -> str:
    key = str(observer).replace("°", "").strip()
    if key not in OBSERVERS:
        raise InstrumentError(f"unknown observer {observer!r}; choose 10 (CIE 1964) or 2 (CIE 1931)")
    return key


def check_illuminant(illuminant: str) -> str:
    if illuminant not in ILLUMINANTS:
        raise InstrumentError(f"unknown illuminant {illuminant!r}; choose one of {', '.join(ILLUMINANTS)}")
    return illuminant


# -- the scene ------------------------------------------------------------------------------------
def view_direction(geom: Geometry) -> np.ndarray:
    """Unit vector from the spot toward the instrument's view (tilted across the fibres, toward +x)."""
    t = np.radians(geom.view_deg)
    return np.array([np.sin(t), 0.0, np.cos(t)])


def _sensor(geom: Geometry, aperture_mm: float, size: int, spp: int, centre: tuple[float, float] = (0.0, 0.0)) -> dict:
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.variant import transform

    radius = aperture_mm / 2.0 / MM_PER_UNIT
    spot = np.array([centre[0], centre[1], 0.0])
    to_world = transform(look_at_matrix(spot + 2.0 * view_direction(geom), spot) @ np.diag([radius, radius, 1.0, 1.0]))
    return {"type": "orthographic", "to_world": to_world,
            "film": {"type": "hdrfilm", "width": size, "height": size, "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": int(spp)}}


def _lights(geom: Geometry, flat) -> dict:
    """The sphere (with its trap) or the ring; ``flat(v)`` makes a flat spectrum of value ``v``."""
    if geom.diffuse:
        out = {"sphere": {"type": "constant", "radiance": flat(1.0)}}
        if geom.trap:
            # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
            from hairdigi.render.variant import transform

            mirror = view_direction(geom) * np.array([-1.0, 1.0, 1.0])
            centre = TRAP_DISTANCE * mirror
            r = TRAP_DISTANCE * np.tan(np.radians(TRAP_HALF_ANGLE_DEG))
            matrix = look_at_matrix(centre, np.zeros(3)) @ np.diag([r, r, 1.0, 1.0])
            out["trap"] = {"type": "disk", "to_world": transform(matrix),
                           "bsdf": {"type": "diffuse", "reflectance": flat(0.0)}}
        return out
    # 45°a: the ring's plane irradiance sums to pi, so a white diffuser's radiance is 1
    each = np.pi / (RING_LIGHTS * np.cos(np.radians(45.0)))
    out = {}
    for k in range(RING_LIGHTS):
        phi = 2 * np.pi * (k + 0.5) / RING_LIGHTS
        toward = np.array([np.sin(np.radians(45.0)) * np.cos(phi), np.sin(np.radians(45.0)) * np.sin(phi),
                           np.cos(np.radians(45.0))])
        out[f"ring{k:02d}"] = {"type": "directional", "direction": (-toward).tolist(), "irradiance": flat(each)}
    return out


def instrument_scene(geom: Geometry, aperture_mm: float, size: int, spp: int, max_depth: int = 32,
                     curve_file: str | None = None, bsdf: dict | None = None, tile: str | None = None,
                     spectral: bool = False, centre: tuple[float, float] = (0.0, 0.0)) -> dict:
    """The instrument's scene: the hair of ``curve_file`` (its ``bsdf``) on the rig's holder, or a
    calibration ``tile`` ("white": a perfect diffuser; "black glass": a smooth dielectric of index 1.5
    over black) filling the port. ``spectral``: flat spectra written for a spectral variant. ``centre``: the
    spot's centre on the holder (x, y scene units; the swatch's centre is 0, 0; its fibres run along y)."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.scenes import hair_shape, integrator, placed

    if spectral:
        # deferred: the CLI parser imports this module; the spectra only for a spectral render
        from hairdigi.render.spectra import WAVELENGTHS, mitsuba_spectrum

        def flat(v: float) -> dict:
            return mitsuba_spectrum(np.full(len(WAVELENGTHS), float(v)))
    else:
        def flat(v: float) -> dict:
            return {"type": "rgb", "value": [float(v)] * 3}
    scene = {"type": "scene", "integrator": integrator(max_depth),
             "sensor": _sensor(geom, check_aperture(aperture_mm), size, spp, centre), **_lights(geom, flat)}
    if tile is None:
        scene["holder"] = {"type": "rectangle", "to_world": placed(HOLDER_CENTER, (HOLDER_SIZE[0] / 2, HOLDER_SIZE[1] / 2)),
                           "bsdf": {"type": "diffuse", "reflectance": flat(HOLDER_ALBEDO)}}
        scene["hair"] = hair_shape(curve_file, bsdf)
        return scene
    tiles = {"white": {"type": "diffuse", "reflectance": flat(1.0)},
             "black glass": {"type": "plastic", "diffuse_reflectance": flat(0.0), "int_ior": 1.5, "nonlinear": False}}
    if tile not in tiles:
        raise InstrumentError(f"unknown tile {tile!r}; choose one of {', '.join(tiles)}")
    scene["tile"] = {"type": "rectangle", "to_world": placed((0.0, 0.0), (2.0, 2.0)), "bsdf": tiles[tile]}
    return scene


@functools.lru_cache(maxsize=None)
def aperture_mask(size: int) -> np.ndarray:
    """(size, size) bool: the film's pixels whose centres lie inside the aperture's disc."""
    c = (np.arange(size) + 0.5) / size * 2 - 1
    return (c[None, :] ** 2 + c[:, None] ** 2) <= 1.0


def aperture_mean(image: np.ndarray) -> np.ndarray:
    """Per channel mean of ``image`` (H, W, C) inside the aperture."""
    image = np.asarray(image, float)
    return image[aperture_mask(image.shape[0])].mean(0)


def _render(scene_dict: dict, size: int, spp: int, seed: int) -> np.ndarray:
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import RENDER_LOCK, trace
    from hairdigi.render.variant import load_scene

    with RENDER_LOCK:
        image, _ = trace(load_scene(scene_dict), size, spp, seed)
    return image


def tile_reflectance(tile: str, geom: Geometry | str, size: int = 32, spp: int = 64, seed: int = 1) -> np.ndarray:
    """A calibration tile's reflectance factor (RGB) in ``geom``: the white diffuser reads 1."""
    geom = geometry(geom)
    return aperture_mean(_render(instrument_scene(geom, DEFAULT_APERTURE_MM, size, spp, 8, tile=tile), size, spp, seed))


def reflectance_ladder(strands, geom: Geometry | str, levels: np.ndarray, aperture_mm: float = DEFAULT_APERTURE_MM,
                       size: int = 48, spp: int = 64, seed: int = 7, max_depth: int = 32) -> np.ndarray:
    """The swatch's reflectance factor in ``geom`` at each flat ``sigma_a`` of ``levels`` (a multiple of
    three: three levels a render, one per channel), over the aperture on the swatch's centre."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    import mitsuba as mi

    from hairdigi.render.renderer import RENDER_LOCK, trace
    from hairdigi.render.variant import load_scene, select_variant

    select_variant()
    geom = geometry(geom)
    levels = np.asarray(levels, float)
    if len(levels) % 3:
        raise ValueError(f"a reflectance ladder takes a multiple of 3 levels, got {len(levels)}")
    order = levels.reshape(3, -1).T
    out = np.empty(len(levels))
    with tempfile.TemporaryDirectory(prefix="hairdigi-instrument-") as tmp:
        curve_file = Path(tmp) / "curves.txt"
        curve_file.write_text(strands.with_dummy().to_curve_text())
        with RENDER_LOCK:
            scene = load_scene(instrument_scene(geom, aperture_mm, size, spp, max_depth, str(curve_file),
                                                hair_bsdf(HairParams())))
            params = mi.traverse(scene)
            for t, triple in enumerate(order):
                params["hair.bsdf.sigma_a.value"] = mi.Color3f(*[float(v) for v in triple])
                params.update()
                image, _ = trace(scene, size, spp, seed + t)
                out[[t, t + len(order), t + 2 * len(order)]] = aperture_mean(image)
    return out


# -- colour from a reflectance spectrum ------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def _weights(illuminant: str, observer: str) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) the observer's x̄ȳz̄ times the illuminant on ``render.spectra.WAVELENGTHS``, and its white XYZ."""
    # deferred: colour-science takes ~1 s; the CLI parser imports this module (render.spectra)
    import colour

    from hairdigi.render.spectra import WAVELENGTHS

    shape = colour.SpectralShape(float(WAVELENGTHS[0]), float(WAVELENGTHS[-1]), 5.0)
    cmfs = colour.MSDS_CMFS[OBSERVERS[check_observer(observer)]].copy().align(shape).values
    spd = colour.SDS_ILLUMINANTS[check_illuminant(illuminant)].copy().align(shape).values
    weights = np.clip(cmfs * spd[:, None], 0.0, None)   # CIE 1964's x̄ dips below 0 by 1e-5: read as 0
    weights = weights / weights[:, 1].sum()          # a perfect white reads Y = 1
    return weights, weights.sum(0)


def lab_of_reflectance(reflectance: np.ndarray, illuminant: str = "D65", observer: str = "10") -> np.ndarray:
    """CIELAB of a reflectance factor spectrum (..., n) on ``render.spectra.WAVELENGTHS``, under
    ``illuminant`` for ``observer``, its white the perfect diffuser under the same light."""
    import colour   # deferred: colour-science takes ~1 s to import

    weights, white = _weights(illuminant, str(observer))
    xyz = np.asarray(reflectance, float) @ weights
    return colour.XYZ_to_Lab(xyz, colour.XYZ_to_xy(white))


def lab_of_tristimulus(relative: np.ndarray, illuminant: str = "D65", observer: str = "10") -> np.ndarray:
    """CIELAB of tristimulus values relative to the white's (X/Xn, Y/Yn, Z/Zn)."""
    import colour   # deferred: colour-science takes ~1 s to import

    _, white = _weights(illuminant, str(observer))
    return colour.XYZ_to_Lab(np.asarray(relative, float) * white, colour.XYZ_to_xy(white))


def spectral_tristimulus(strands, sigma_spectrum: np.ndarray | None, geom: Geometry | str,
                         aperture_mm: float = DEFAULT_APERTURE_MM, illuminant: str = "D65", observer: str = "10",
                         size: int = 48, spp: int = 256, seed: int = 11, max_depth: int = 32,
                         tile: str | None = None, spots: int = 1) -> np.ndarray:
    """The virtual instrument: ``geom`` rendered spectrally (Mitsuba's spectral twin of the variant),
    the hair of ``strands`` absorbing ``sigma_spectrum`` (on ``render.spectra.WAVELENGTHS``), seen through
    ``specfilm`` bands of ``observer`` under ``illuminant``. Returns (X/Xn, Y/Yn, Z/Zn) over the aperture:
    :func:`lab_of_tristimulus` turns it into CIELAB. ``tile`` renders a calibration tile instead. ``spots``:
    the mean of that many readings along the fibres (``SPOT_STEP`` apart, centred on the swatch), as a lab
    reads a tress at three places and averages."""
    # deferred: loads Mitsuba (the entry point chooses the variant); the CLI parser imports this module
    import mitsuba as mi

    from hairdigi.render.spectra import mitsuba_spectrum
    from hairdigi.render.variant import spectral_variant

    geom = geometry(geom)
    weights, _ = _weights(illuminant, str(observer))
    bands = weights / weights.sum(0)                 # each band of unit sum: a flat reflectance 1 reads 1
    with mi.variant_context(spectral_variant()), tempfile.TemporaryDirectory(prefix="hairdigi-instrument-") as tmp:
        curve_file = None
        bsdf = None
        if tile is None:
            curve_file = Path(tmp) / "curves.txt"
            curve_file.write_text(strands.with_dummy().to_curve_text())
            bsdf = hair_bsdf(HairParams())
            bsdf["sigma_a"] = mitsuba_spectrum(np.asarray(sigma_spectrum, float))
        readings = []
        for k in range(spots):
            centre = (0.0, (k - (spots - 1) / 2) * SPOT_STEP)
            scene = instrument_scene(geom, aperture_mm, size, spp, max_depth,
                                     None if curve_file is None else str(curve_file), bsdf, tile=tile, spectral=True,
                                     centre=centre)
            film = scene["sensor"]["film"]
            film.update(type="specfilm", component_format="float32")
            film.pop("pixel_format", None)
            for c, band in enumerate(("band1_x", "band2_y", "band3_z")):   # specfilm orders channels by name
                film[band] = mitsuba_spectrum(bands[:, c] / 5.0)           # flat 1 then reads 1 (measured: tiles)
            readings.append(aperture_mean(_render(scene, size, spp, seed + k)))
        return np.mean(readings, axis=0)
