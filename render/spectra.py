"""Hair absorption as a spectrum, and the lights and cameras of a spectral world.

Table 1 stays; each parameter maps to an absorption spectrum ``sigma_a(λ)`` per fibre radius, on
``WAVELENGTHS`` (Mitsuba's spectral range, 360–830 nm, every 5 nm):

1. **Melanins.** Donner & Jensen 2006 ("A spectral BSSRDF for shading human skin") give eumelanin's
   absorption as ∝ λ^-3.33 and pheomelanin's as ∝ λ^-4.75; d'Eon et al. 2011 ("An energy-conserving
   hair reflectance model") use them for hair, and their RGB coefficients are the ones
   ``render.domain.absorption`` renders with. Each power law is scaled here so that its projection on
   linear sRGB under D65 (:func:`rgb_projection`: the channel's colour matching function times D65,
   normalised, so that a flat spectrum projects to itself) fits those coefficients in the
   least-squares sense of their logarithms. Measured (``tests/test_spectra.py``): eumelanin
   (0.392, 0.716, 1.429) against (0.419, 0.697, 1.37), pheomelanin (0.172, 0.411, 1.113) against
   (0.187, 0.4, 1.05): within 6.5% and 8.2% per channel. The melanin quantity ``q`` and the ratio
   split them exactly as in RGB (``render.domain.absorption.melanin_quantity``).
2. **The dye.** Its colour ``c = dye_rgb / 255`` (a linear albedo, as in RGB) is read as a smooth
   spectral albedo by Jakob & Hanika 2019 ("A low-dimensional function space for efficient spectral
   upsampling"): it reproduces the colour under D65 and stays in (0, 1). The coefficients come from
   the table Mitsuba's spectral variants upsample RGB albedos with (``srgb_model_fetch``, 0.2 µs), so
   a dye renders spectrally as Mitsuba would render its RGB albedo; colour-science's solve of the same
   model (``XYZ_to_sd``, method "Jakob 2019", 40 ms) is the reference it is tested against (within
   0.0023 in albedo from saturated to grey dyes, ``tests/test_spectra.py``). The solve's cost (0.5 s
   a dyed swatch's colour under another light) and its solver noise (which a refit's finite
   differences took for a slope) are gone. Chiang 2016's eq. 9 then turns each wavelength's albedo
   into an absorption, times the concentration. A dye
   whose real absorption is a narrow band cannot be told from Table 1's RGB: :func:`band_dye` makes
   one, for the evaluations' hidden hairs.

Lights are colour-science's CIE SPDs (``ILLUMINANTS``: daylight, tungsten, fluorescent and the CIE
LED series), or a two-column CSV. Cameras are colour-science's measured sensitivities (``CAMERAS``),
or a four-column CSV. Both are read on ``WAVELENGTHS``, zero (cameras) or held constant (lights)
outside their own range. A spectrum enters Mitsuba as a ``regular`` spectrum (:func:`mitsuba_spectrum`).
"""
from __future__ import annotations

import csv
import functools
import io
import re
from pathlib import Path

import numpy as np

from hairdigi.render.domain.absorption import (AZIMUTHAL_ROUGHNESS, EUMELANIN_SIGMA_A, MIN_DYE_ALBEDO,
                                               PHEOMELANIN_SIGMA_A, albedo_from_sigma_a, melanin_quantity,
                                               sigma_a_from_albedo)
from hairdigi.render.domain.bounds import CAMERAS, ILLUMINANTS  # noqa: F401  (named cameras and lights)
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import read_bytes
from hairdigi.render.domain.params import HairParams

#: nm: Mitsuba's spectral range (``MI_CIE_MIN``..``MI_CIE_MAX``) every 5 nm.
WAVELENGTHS = np.arange(360.0, 830.0 + 1e-9, 5.0)
STEP_NM = 5.0
#: Power-law exponents of the melanins' absorption (Donner & Jensen 2006).
EUMELANIN_EXPONENT = 3.33
PHEOMELANIN_EXPONENT = 4.75
#: The reference wavelength of the power laws, nm.
REFERENCE_NM = 600.0

#: A spectrum read from a file must cover at least this much of 400–700 nm, and have this many rows.
MIN_COVERAGE_NM = (400.0, 700.0)
MIN_ROWS = 4
MAX_CSV_BYTES = 1 << 20


class SpectrumError(HairdigiError, ValueError):
    """A light or camera is unknown, or its CSV file cannot be used; the message names the fix."""


# -- colour-science's data on this grid -------------------------------------------------------
def _shape():
    import colour   # deferred: colour-science takes ~1 s to import

    return colour.SpectralShape(float(WAVELENGTHS[0]), float(WAVELENGTHS[-1]), 5.0)


@functools.lru_cache(maxsize=None)
def cmfs() -> np.ndarray:
    """(n, 3) CIE 1931 2° colour matching functions on ``WAVELENGTHS``."""
    import colour   # deferred: colour-science takes ~1 s to import

    return colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(_shape()).values


@functools.lru_cache(maxsize=None)
def srgb_weights() -> np.ndarray:
    """(n, 3) each linear-sRGB channel's weight per wavelength under D65 (the CIE 1931 observer through sRGB's
    matrix), each channel summing to 1: a flat spectrum projects to itself."""
    import colour   # deferred: colour-science takes ~1 s to import

    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(_shape()).values
    rgb_bar = cmfs() @ np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB).T
    weights = rgb_bar * d65[:, None]
    return weights / weights.sum(0)


def rgb_projection(spectrum: np.ndarray) -> np.ndarray:
    """A spectrum's linear-sRGB value under D65 (each channel's CMF times D65, normalised): a flat
    spectrum projects to itself. How an absorption spectrum is compared with RGB coefficients."""
    return np.asarray(spectrum, float) @ srgb_weights()


# -- melanins ----------------------------------------------------------------------------------
def _fitted_power_law(exponent: float, rgb: np.ndarray) -> np.ndarray:
    """``a (λ / REFERENCE_NM)^-exponent``, with ``a`` fitting the RGB coefficients (log least squares)."""
    shape = (WAVELENGTHS / REFERENCE_NM) ** -exponent
    a = float(np.exp(np.mean(np.log(np.asarray(rgb) / rgb_projection(shape)))))
    return a * shape


@functools.lru_cache(maxsize=None)
def _melanins() -> tuple[np.ndarray, np.ndarray]:
    return (_fitted_power_law(EUMELANIN_EXPONENT, EUMELANIN_SIGMA_A),
            _fitted_power_law(PHEOMELANIN_EXPONENT, PHEOMELANIN_SIGMA_A))


def eumelanin_spectrum() -> np.ndarray:
    """Eumelanin's absorption per unit quantity per fibre radius on ``WAVELENGTHS``."""
    return _melanins()[0].copy()


def pheomelanin_spectrum() -> np.ndarray:
    """Pheomelanin's absorption per unit quantity per fibre radius on ``WAVELENGTHS``."""
    return _melanins()[1].copy()


def melanin_sigma_a_spectrum(concentration: float, ratio: float) -> np.ndarray:
    """Melanin's absorption spectrum: the RGB mapping's quantity and split, the spectral melanins."""
    q = melanin_quantity(concentration)
    eu, pheo = _melanins()
    return q * ratio * eu + q * (1.0 - ratio) * pheo


# -- dyes ----------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=4096)
def _albedo_spectrum(rgb: tuple[float, float, float]) -> np.ndarray:
    c = np.clip(np.asarray(rgb, float), MIN_DYE_ALBEDO, 1.0)
    if np.all(c >= 0.999):   # white: no absorption (the sigmoid never reaches 1)
        return np.ones_like(WAVELENGTHS)
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from mitsuba import scalar_rgb   # the variant's module itself: no global variant is chosen here

    c0, c1, c2 = scalar_rgb.srgb_model_fetch(scalar_rgb.ScalarColor3f(*c))
    x = c0 * WAVELENGTHS ** 2 + c1 * WAVELENGTHS + c2   # Jakob & Hanika 2019 (as colour's sd_Jakob2019)
    return np.clip(0.5 + x / (2.0 * np.sqrt(1.0 + x * x)), MIN_DYE_ALBEDO, 1.0)


def albedo_spectrum(rgb: np.ndarray) -> np.ndarray:
    """A linear-sRGB albedo (each in [0, 1]) read as a smooth spectral albedo (Jakob & Hanika 2019), from
    the coefficient table Mitsuba's spectral variants upsample RGB albedos with (``srgb_model_fetch``)."""
    return _albedo_spectrum(tuple(round(float(v), 4) for v in np.ravel(rgb)[:3])).copy()


def dye_sigma_a_spectrum(dye_rgb: tuple[float, float, float], concentration: float,
                         azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """The dye's absorption spectrum: its colour as a spectral albedo, Chiang 2016 eq. 9 per wavelength."""
    if float(concentration) == 0.0:
        return np.zeros_like(WAVELENGTHS)
    albedo = albedo_spectrum(np.asarray(dye_rgb, float) / 255.0)
    return float(concentration) * sigma_a_from_albedo(albedo, azimuthal_roughness)


def rgb_sigma_spectrum(sigma_rgb: np.ndarray, azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """An RGB absorption (a dye's deposit, a prediction) as a spectrum, the way a dye's colour becomes one:
    its fibre albedo (Chiang 2016 eq. 9 inverted) read as a smooth spectral albedo (Jakob & Hanika 2019),
    then eq. 9 per wavelength. A flat absorption stays flat."""
    sigma_rgb = np.asarray(sigma_rgb, float)
    if np.ptp(sigma_rgb) < 1e-9:
        return np.full_like(WAVELENGTHS, float(sigma_rgb[0]))
    albedo = albedo_spectrum(albedo_from_sigma_a(sigma_rgb, azimuthal_roughness))
    return sigma_a_from_albedo(albedo, azimuthal_roughness)


def band_dye(centre_nm: float, width_nm: float, peak: float) -> np.ndarray:
    """A dye absorbing in one Gaussian band (sd ``width_nm``), ``peak`` per fibre radius at its centre."""
    return float(peak) * np.exp(-0.5 * ((WAVELENGTHS - float(centre_nm)) / float(width_nm)) ** 2)


def hair_sigma_a_spectrum(params: HairParams, azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """Total absorption spectrum (per fibre radius) of melanin plus dye; finite and non-negative."""
    return (melanin_sigma_a_spectrum(params.melanin_concentration, params.melanin_ratio)
            + dye_sigma_a_spectrum(params.dye_rgb, params.dye_concentration, azimuthal_roughness))


# -- lights and cameras ------------------------------------------------------------------------
def _read_table(path: Path, columns: int, what: str, form: str) -> np.ndarray:
    """The numeric rows of a CSV (a header line is allowed), checked; ``SpectrumError`` names the fix."""
    fix = f"give a CSV of {form}, one row per wavelength in nm, rising"
    data = read_bytes(path, SpectrumError, "a CSV file", MAX_CSV_BYTES, f"a spectrum needs far less; {fix}")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SpectrumError(f"{what} {path}: not a text CSV file; {fix}") from None
    rows = []
    for n, row in enumerate(csv.reader(io.StringIO(text)), 1):
        cells = [c.strip() for c in row if c.strip()]
        if not cells or cells[0].startswith("#"):
            continue
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows and n == 1 and not any(_is_number(c) for c in cells):   # a header: words only
                continue
            raise SpectrumError(f"{what} {path}, line {n}: {','.join(cells)[:60]!r} is not {columns} numbers; "
                                f"{fix}") from None
        if len(values) != columns:
            raise SpectrumError(f"{what} {path}, line {n}: {len(values)} columns, expected {columns}; {fix}")
        rows.append(values)
    table = np.asarray(rows, float).reshape(-1, columns)
    if len(table) < MIN_ROWS:
        raise SpectrumError(f"{what} {path}: {len(table)} rows of numbers, need at least {MIN_ROWS}; {fix}")
    if not np.all(np.isfinite(table)):
        raise SpectrumError(f"{what} {path}: holds NaN or infinite values; {fix}")
    wl = table[:, 0]
    if np.any(np.diff(wl) <= 0):
        raise SpectrumError(f"{what} {path}: the wavelengths do not rise; {fix}")
    if wl[0] > MIN_COVERAGE_NM[0] or wl[-1] < MIN_COVERAGE_NM[1]:
        hint = " (wavelengths in µm? give nm)" if wl[-1] < 10 else ""
        raise SpectrumError(f"{what} {path}: covers {wl[0]:g}–{wl[-1]:g} nm, not all of "
                            f"{MIN_COVERAGE_NM[0]:g}–{MIN_COVERAGE_NM[1]:g} nm{hint}; {fix}")
    if np.any(table[:, 1:] < 0):
        raise SpectrumError(f"{what} {path}: holds negative values; a spectrum is >= 0; {fix}")
    if not np.any(table[:, 1:] > 0, axis=0).all():
        raise SpectrumError(f"{what} {path}: a column is all zero; {fix}")
    return table


def _is_number(cell: str) -> bool:
    """Whether a CSV cell reads as a number (a first row holding one is data, never a header)."""
    try:
        float(cell)
    except ValueError:
        return False
    return True


#: Where light is colour (nm): a light's power and a camera channel's response must lie mostly inside it.
VISIBLE_NM = (380.0, 780.0)
#: The least share of a light's power, or of a camera channel's response, inside ``VISIBLE_NM`` (on ``WAVELENGTHS``,
#: 360-830 nm: CIE A, the reddest named light, has 0.80; every named camera 1.00).
MIN_VISIBLE_SHARE = 0.5
#: A white LED's spread: the least share of its 400-700 nm power in each third (blue 400-490, green 490-580, red
#: 580-700 nm); the named lights have at least 0.066 (LED-RGB1's blue), a single-wavelength LED 0 in two.
WHITE_BANDS_NM = ((400.0, 490.0), (490.0, 580.0), (580.0, 700.0))
MIN_WHITE_BAND_SHARE = 0.03
#: Two camera channels whose sensitivities point this nearly the same way (cosine) cannot be told apart; the Sigma
#: SD Merrill's (a Foveon, the most overlapping camera measured) reach 0.92.
MAX_CHANNEL_COSINE = 0.98


def _visible_share(values: np.ndarray) -> np.ndarray:
    """The share of a spectrum's (or each column's) sum on ``WAVELENGTHS`` that lies inside ``VISIBLE_NM``."""
    inside = (WAVELENGTHS >= VISIBLE_NM[0]) & (WAVELENGTHS <= VISIBLE_NM[1])
    total = np.asarray(values, float).sum(0)
    return np.where(total > 0, np.asarray(values, float)[inside].sum(0) / np.where(total > 0, total, 1.0), 0.0)


def white_light_problem(name: str) -> str | None:
    """Why a light cannot be a rig's white LEDs (too little power in one of ``WHITE_BANDS_NM``), or None."""
    spd = illuminant_spd(name)
    window = (WAVELENGTHS >= WHITE_BANDS_NM[0][0]) & (WAVELENGTHS <= WHITE_BANDS_NM[-1][1])
    total = float(spd[window].sum())
    shares = [float(spd[(WAVELENGTHS >= lo) & (WAVELENGTHS < hi)].sum()) / total for lo, hi in WHITE_BANDS_NM]
    low = [f"{lo:g}-{hi:g} nm {share:.0%}" for (lo, hi), share in zip(WHITE_BANDS_NM, shares)
           if share < MIN_WHITE_BAND_SHARE]
    if not low:
        return None
    return (f"illuminant {name}: not a white light (of its 400-700 nm power: {', '.join(low)}; a white LED has at "
            f"least {MIN_WHITE_BAND_SHARE:.0%} in each of blue, green and red); give the rig's white LEDs' SPD")


def _camera_problem(name: str, bands: np.ndarray) -> str | None:
    """Why a camera's sensitivities (n, 3) cannot read colour: a channel with no response inside ``VISIBLE_NM``, two
    channels alike, or channels out of r, g, b order; None when they can."""
    share = _visible_share(bands)
    weak = [c for c, v in zip("rgb", share) if v < MIN_VISIBLE_SHARE]
    if weak:
        return (f"camera {name}: channel {', '.join(weak)} responds mostly outside {VISIBLE_NM[0]:g}-{VISIBLE_NM[1]:g} "
                f"nm (" + ", ".join(f"{c} {v:.0%}" for c, v in zip("rgb", share)) + " inside); a camera's three "
                "channels respond to visible light: check the file's columns and units")
    unit = bands / np.linalg.norm(bands, axis=0)
    cosine = unit.T @ unit
    alike = [f"{a} and {b} ({cosine[i, j]:.3f})" for i, j, a, b in ((0, 1, "r", "g"), (1, 2, "g", "b"), (0, 2, "r", "b"))
             if cosine[i, j] > MAX_CHANNEL_COSINE]
    if alike:
        return (f"camera {name}: channels {', '.join(alike)} respond alike, so colour cannot be read; give three "
                "distinct channels, r, g, b")
    centre = (WAVELENGTHS[:, None] * bands).sum(0) / bands.sum(0)
    if not centre[0] > centre[1] > centre[2]:
        return (f"camera {name}: its channels' centres (r {centre[0]:.0f}, g {centre[1]:.0f}, b {centre[2]:.0f} nm) "
                "are not red above green above blue; give the columns as wavelength, r, g, b")
    return None


#: A Planckian radiator named by its temperature: "3200K" (1000-25000 K).
_BLACKBODY = re.compile(r"(\d{4,5}) ?[Kk]")


def illuminant_spd(name: str) -> np.ndarray:
    """A light's relative SPD on ``WAVELENGTHS``, normalised to luminance Y = 1 (as an RGB white of 1
    is in Mitsuba's spectral variants): a name of ``ILLUMINANTS``, a Planckian radiator's temperature
    ("3200K", 1000-25000 K), or a CSV of wavelength, power."""
    import colour   # deferred: colour-science takes ~1 s to import

    key = ILLUMINANTS.get(name) or ILLUMINANTS.get(str(name).upper())
    kelvin = _BLACKBODY.fullmatch(str(name).strip())
    if key is not None:
        sd = colour.SDS_ILLUMINANTS[key]
        values = np.interp(WAVELENGTHS, sd.wavelengths, sd.values)
    elif kelvin is not None and 1000 <= int(kelvin.group(1)) <= 25000:   # a Planckian radiator, e.g. studio tungsten
        sd = colour.sd_blackbody(float(kelvin.group(1)), colour.SpectralShape(360.0, 830.0, 5.0))
        values = np.interp(WAVELENGTHS, sd.wavelengths, sd.values)
    elif Path(name).suffix.lower() in (".csv", ".txt"):
        table = _read_table(Path(name), 2, "illuminant", "wavelength, power")
        values = np.interp(WAVELENGTHS, table[:, 0], table[:, 1])
    else:
        raise SpectrumError(f"unknown illuminant {name!r}; choose one of {', '.join(ILLUMINANTS)}, a "
                            f"temperature from 1000K to 25000K, or a CSV file of wavelength (nm), power")
    y = float(spectrum_to_xyz(values)[1])
    share = float(_visible_share(values))
    if y <= 0 or share < MIN_VISIBLE_SHARE:
        raise SpectrumError(f"illuminant {name}: {share:.0%} of its power lies where the eye sees "
                            f"({VISIBLE_NM[0]:g}-{VISIBLE_NM[1]:g} nm), too little to light a colour (infrared or "
                            "ultraviolet only?); give a visible light's SPD, wavelength (nm), power")
    return values / y


def camera_sensitivities(name: str) -> np.ndarray:
    """(n, 3) a camera's R, G, B sensitivities on ``WAVELENGTHS`` (0 outside their range), each channel
    scaled to a peak of 1: a name of ``CAMERAS`` or a CSV of wavelength, r, g, b."""
    import colour   # deferred: colour-science takes ~1 s to import

    key = CAMERAS.get(name) or (name if name in colour.MSDS_CAMERA_SENSITIVITIES else None)
    if key is not None:
        msd = colour.MSDS_CAMERA_SENSITIVITIES[key]
        wl, values = msd.wavelengths, msd.values
    elif Path(name).suffix.lower() in (".csv", ".txt"):
        table = _read_table(Path(name), 4, "camera sensitivities", "wavelength, r, g, b")
        wl, values = table[:, 0], table[:, 1:]
    else:
        raise SpectrumError(f"unknown camera {name!r}; choose one of {', '.join(CAMERAS)} "
                            f"or give a CSV file of wavelength (nm), r, g, b")
    out = np.stack([np.interp(WAVELENGTHS, wl, values[:, k], left=0.0, right=0.0) for k in range(3)], axis=1)
    problem = _camera_problem(name, out)
    if problem is not None:
        raise SpectrumError(problem)
    return out / out.max(0)


def illuminant_whitepoint(name: str) -> np.ndarray:
    """The xy chromaticity of a light (``illuminant_spd``): the white an observer adapted to it sees."""
    x, y, z = spectrum_to_xyz(illuminant_spd(name))
    return np.array([x, y]) / (x + y + z)


def light_rgb(name: str) -> np.ndarray:
    """A light as an RGB renderer sees it: its colour in linear sRGB at luminance 1. An RGB render under
    it is the white-light render times this, per channel (every path's weight is a per-channel product)."""
    import colour   # deferred: colour-science takes ~1 s to import

    xyz = spectrum_to_xyz(illuminant_spd(name))
    return colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)


def balanced(linear: np.ndarray, name: str) -> np.ndarray:
    """Linear sRGB rendered under a light, as an eye adapted to that light sees it: a von Kries
    adaptation (Bradford) from the light's white to D65's, so that a white under the light is white."""
    import colour   # deferred: colour-science takes ~1 s to import

    srgb = colour.RGB_COLOURSPACES["sRGB"]
    xyz = colour.RGB_to_XYZ(np.asarray(linear, float), srgb, apply_cctf_decoding=False)
    white = spectrum_to_xyz(illuminant_spd(name))
    d65 = colour.xy_to_XYZ(srgb.whitepoint)
    adapted = colour.adaptation.chromatic_adaptation_VonKries(xyz, white, d65, transform="Bradford")
    return colour.XYZ_to_RGB(adapted, srgb, apply_cctf_encoding=False).astype(np.float32)


def swatch_colour(reflectance: np.ndarray, light: str, sensitivities: str | None = None) -> np.ndarray:
    """The mean colour of a swatch that reflects ``reflectance`` (any shape ending in n: its mean
    radiance per unit light, wavelength by wavelength) lit by ``light``: linear sRGB as the CIE observer
    sees it (D65 white), or a camera's raw RGB through its ``sensitivities`` (bands of unit area, as
    ``render.scenes.camera_film``). With a rig's response curve read per wavelength as ``reflectance``,
    this is a spectral render's mean colour without the render (``inference.spectral_reading``)."""
    import colour   # deferred: colour-science takes ~1 s to import

    radiance = np.asarray(reflectance, float) * illuminant_spd(light)
    if sensitivities is not None:
        return radiance @ camera_bands(sensitivities) * STEP_NM   # the film's integral, sample by sample
    return colour.XYZ_to_RGB(spectrum_to_xyz(radiance), colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)


def camera_bands(name: str) -> np.ndarray:
    """A camera's sensitivities (:func:`camera_sensitivities`) as its film weighs radiance: each band of
    unit area over wavelength (per nm), so that an equal-energy radiance of 1 reads 1 in every channel."""
    bands = camera_sensitivities(name)
    return bands / (bands.sum(0) * STEP_NM)


def spectrum_to_xyz(radiance: np.ndarray) -> np.ndarray:
    """CIE XYZ of spectra (any shape ending in ``len(WAVELENGTHS)``) as Mitsuba's film weighs them: an
    equal-energy spectrum of 1 has Y = 1."""
    return np.asarray(radiance, float) @ cmfs() / cmfs()[:, 1].sum()


def mitsuba_spectrum(values: np.ndarray) -> dict:
    """A Mitsuba ``regular`` spectrum on ``WAVELENGTHS`` (``uniform`` where it is flat: Mitsuba refuses a
    ``regular`` spectrum of zeros)."""
    values = np.asarray(values, float)
    if values.shape != WAVELENGTHS.shape or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(f"a spectrum must be {len(WAVELENGTHS)} finite values >= 0 on WAVELENGTHS")
    if np.ptp(values) == 0:
        return {"type": "uniform", "value": float(values[0])}
    return {"type": "regular", "wavelength_min": float(WAVELENGTHS[0]), "wavelength_max": float(WAVELENGTHS[-1]),
            "values": ", ".join(f"{v:.6g}" for v in values)}
