"""Is this a hair swatch like those the encoder was trained on? Checks that flag inputs outside the domain.

Each check reads the encoder's own input (the swatch crop resized to 48² in linear light, as
``preprocess.encode`` makes it), so the thresholds do not depend on the source's resolution. They
were set from 300 clean held-out swatch renders (5th percentile and maximum of each statistic) and
from inputs that are not hair (noise, flat colours, a white card, a checkerboard, stripes, a
portrait): see ``THRESHOLDS`` and ``tests/test_domain.py``. A warning never blocks an estimate; it
says why the numbers should not be trusted.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hairdigi.inference.preprocess import encode, to_srgb8


@dataclass(frozen=True)
class Thresholds:
    """Limits on the 48² input (8-bit units). Held-out renders: std 5.0–21, coherence 0.07–0.46,
    gradient energy 25–116, view spread 0.005–0.13 (the first 100 of the clean held-out set).

    The layered (physical) swatch has no streaks of its own. Its fibres lie side by side,
    far finer than a pixel, so a crop seen from above is as isotropic as noise: 24 renders of the
    training distribution at 64², 16 spp gave coherence 0.014–0.30 (median 0.039) against 0.035 for
    uniform RGB noise. Coherence now flags only what has none at all (a checkerboard); colour noise
    is caught by its channels (``min_channel_corr``).
    """

    min_std: float = 2.0            # below: a flat colour, no strands
    min_coherence: float = 0.005    # below: no common strand direction (a checkerboard, a flat texture)
    max_std: float = 45.0           # above: far more contrast than hair (a scene, a picture of something)
    max_energy: float = 220.0
    max_view_spread: float = 0.2    # the encoder's eight flips/turns disagree (normalised units)
    clipped_share: float = 0.15     # share of pixels at 0 or 255 in some channel (held-out: up to 0.09,
                                    # the glints of pale hair)
    # from 160 renders of the held-out distribution (80 as rendered, 80 through the camera
    # model): gradient energy 27–140, peak share 0.02–0.44, channel correlation 0.24–1.0. The
    # peak share is taken on the texture less its smooth shading; dark or dyed swatches with fibre
    # spread 0.3 and 0–40% grey fibres read 0.06–0.26 (0.54–0.70 with the shading), stripes 0.93, a
    # checkerboard 0.78–0.99, a smooth gradient 1
    min_energy: float = 12.0        # below: no strand texture (a smooth gradient, a blurred picture) ...
    # ... unless its texture is fine fibres'. A real camera's view of fibres about a photosite
    # wide, through its lens (Gaussian blur 1-2 px on renders of 128-384 px, then the camera model),
    # keeps 0.57-0.76 of its texture's power above half the 48² input's Nyquist frequency, its three
    # channels moving together there (correlation 0.55-0.80), though black hair's texture is weak
    # (energy 8.2-11.4). Defocused by 6-16 px, the fine texture left is the sensor's noise: a share
    # 0.12-0.69, but its channels apart (0.13-0.41) or under half the share (blurred pictures: 0.02-0.13)
    min_fine_share: float = 0.5
    min_fine_corr: float = 0.48
    max_peak_share: float = 0.6     # above: a few frequencies hold the texture (stripes, a checkerboard)
    min_channel_corr: float = 0.12  # below: R, G and B vary independently (colour noise); hair's shading
                                    # moves all three together


THRESHOLDS = Thresholds()
SAMPLE_PIXELS = 1 << 22   # greyscale and clipped shares are judged on at most this many pixels
INPUT_SIZE = 48


@dataclass(frozen=True)
class DomainStats:
    std: float            # luminance standard deviation
    coherence: float      # strand-direction coherence of the structure tensor, 0 (none) to 1
    energy: float         # RMS gradient magnitude
    greyscale: bool       # R = G = B everywhere
    clipped: float        # share of clipped pixels
    peak_share: float = 0.0    # share of the texture's power in its 4 strongest spatial frequencies
    channel_corr: float = 1.0  # the smallest correlation between two colour channels of the input
    clipped_on: str = "8-bit"  # what ``clipped`` was judged on: the 8-bit values, or the "sensor"'s counts
    fine_share: float = 1.0    # share of the texture's power above half the input's Nyquist frequency
    fine_corr: float = 1.0     # the smallest correlation between two colour channels there

    def to_dict(self) -> dict:
        return {"std": round(self.std, 3), "coherence": round(self.coherence, 4), "energy": round(self.energy, 2),
                "greyscale": self.greyscale, "clipped_share": round(self.clipped, 4), "clipped_on": self.clipped_on,
                "peak_share": round(self.peak_share, 4), "channel_corr": round(self.channel_corr, 4),
                "fine_share": round(self.fine_share, 4), "fine_corr": round(self.fine_corr, 4)}


def domain_stats(crop: np.ndarray, sensor_clipped: np.ndarray | None = None) -> DomainStats:
    """Texture statistics of a swatch crop (8-bit sRGB or linear float), on the encoder's 48² input.

    ``sensor_clipped``: the crop's saturated photosites (a RAW still's, ``hardware.exposure.sensor_clipped``);
    clipping is then the sensor's, not the 8-bit encode's 0 or 255 (a dark swatch's zeros are not clipping)."""
    x = encode(crop, INPUT_SIZE)
    step = max(1, int(np.ceil(np.sqrt(crop.shape[0] * crop.shape[1] / SAMPLE_PIXELS))))
    crop = to_srgb8(crop[::step, ::step])   # the pixel statistics below, on a bounded sample
    luminance = (x + 0.5).mean(0) * 255.0
    gx = cv2.Sobel(luminance, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(luminance, cv2.CV_32F, 0, 1)
    jxx, jyy, jxy = float((gx * gx).mean()), float((gy * gy).mean()), float((gx * gy).mean())
    coherence = np.sqrt((jxx - jyy) ** 2 + 4 * jxy**2) / (jxx + jyy + 1e-6)
    greyscale = bool(np.array_equal(crop[..., 0], crop[..., 1]) and np.array_equal(crop[..., 1], crop[..., 2]))
    if sensor_clipped is None:
        clipped = float(((crop == 0) | (crop == 255)).any(axis=2).mean())
    else:
        clipped = float(np.asarray(sensor_clipped).reshape(*sensor_clipped.shape[:2], -1).any(axis=2).mean())
    return DomainStats(float(luminance.std()), float(coherence), float(np.sqrt(jxx + jyy)), greyscale, clipped,
                       _peak_share(luminance), _channel_corr(x), "8-bit" if sensor_clipped is None else "sensor",
                       _fine_share(luminance), _channel_corr(_fine(x)))


#: Below this share of the luminance's variance left once its smooth shading is removed, the input is
#: one smooth gradient: all of its texture is in the shading (``_peak_share`` then gives 1).
MIN_TEXTURE_SHARE = 0.01


def _shading(n: int, m: int) -> np.ndarray:
    """The basis of a quadratic surface over an n x m image (1, x, y, x², xy, y²), (n*m, 6)."""
    yy, xx = np.mgrid[:n, :m].astype(np.float64)
    xx, yy = xx / max(1, m - 1) - 0.5, yy / max(1, n - 1) - 0.5
    return np.stack([np.ones_like(xx), xx, yy, xx * xx, xx * yy, yy * yy], -1).reshape(-1, 6)


def _texture(luminance: np.ndarray) -> np.ndarray | None:
    """The luminance less its smooth shading (a quadratic surface, fitted); None when that leaves
    under ``MIN_TEXTURE_SHARE`` of its variance (the input is one smooth gradient) or it is flat."""
    lum = np.asarray(luminance, np.float64)
    total = float(((lum - lum.mean()) ** 2).sum())
    if total <= 0:
        return None
    basis = _shading(*lum.shape)
    coef, *_ = np.linalg.lstsq(basis, lum.ravel(), rcond=None)
    texture = lum - (basis @ coef).reshape(lum.shape)
    return None if float((texture**2).sum()) < MIN_TEXTURE_SHARE * total else texture - texture.mean()


def _peak_share(luminance: np.ndarray, k: int = 4) -> float:
    """Share of the luminance's texture power in its ``k`` strongest spatial frequencies: near 1 for
    stripes, a smooth gradient or a checkerboard; hair spreads its power over many.

    The texture is the luminance less its smooth shading (``_texture``): a swatch's brightness falls
    off along its fibres, and on dark hair with few grey fibres that shading held most of the power,
    so that uniform hair read as "a few frequencies". All shading, a gradient: 1 (a flat
    input: 0).
    """
    texture = _texture(luminance)
    if texture is None:
        return 0.0 if float(np.ptp(luminance)) == 0 else 1.0
    power = np.abs(np.fft.rfft2(texture)) ** 2
    power[0, 0] = 0.0
    return float(np.sort(power.ravel())[-k:].sum() / power.sum())


def _fine_share(luminance: np.ndarray) -> float:
    """Share of the texture's power above half the Nyquist frequency (0.25 cycles a pixel): fibres'
    glints and a camera's noise spread their power to the finest scales; a blurred picture has none
    there. 0 when there is no texture (a flat input, a smooth gradient)."""
    texture = _texture(luminance)
    if texture is None:
        return 0.0
    power = np.abs(np.fft.fft2(texture)) ** 2
    fy, fx = np.meshgrid(np.fft.fftfreq(texture.shape[0]), np.fft.fftfreq(texture.shape[1]), indexing="ij")
    total = float(power.sum())
    return float(power[np.hypot(fy, fx) > 0.25].sum() / total) if total > 0 else 0.0


def _fine(x: np.ndarray) -> np.ndarray:
    """The part of each channel of ``x`` (channels first) above half the Nyquist frequency."""
    fy, fx = np.meshgrid(np.fft.fftfreq(x.shape[1]), np.fft.fftfreq(x.shape[2]), indexing="ij")
    spectrum = np.fft.fft2(np.asarray(x, np.float64), axes=(1, 2)) * (np.hypot(fy, fx) > 0.25)
    return np.real(np.fft.ifft2(spectrum, axes=(1, 2)))


def _channel_corr(x: np.ndarray) -> float:
    """The smallest correlation between two of the input's colour channels (1 when one is flat)."""
    flat = x.reshape(3, -1).astype(np.float64)
    spread = flat.std(axis=1)
    if (spread < 1e-6).any():
        return 1.0
    c = np.corrcoef(flat)
    return float(min(c[0, 1], c[0, 2], c[1, 2]))


def fine_fibres(stats: DomainStats, limits: Thresholds = THRESHOLDS) -> bool:
    """Whether a weak texture is fine fibres' (a real camera's view of them): most of its power at the
    finest scales, the three channels moving together there (not the sensor's noise)."""
    return stats.fine_share >= limits.min_fine_share and stats.fine_corr >= limits.min_fine_corr


def domain_warnings(stats: DomainStats, view_spread: float | None = None,
                    limits: Thresholds = THRESHOLDS) -> list[str]:
    """Human-readable reasons why the crop is not a hair swatch the encoder knows; empty when it is."""
    out = []
    if stats.std < limits.min_std:
        out.append(f"out of domain: the swatch area is a flat colour (contrast {stats.std:.1f} < {limits.min_std}), "
                   "not hair; check the swatch area (--roi), the lens and the lights")
    elif stats.coherence < limits.min_coherence:
        out.append(f"out of domain: no strand direction in the swatch area (coherence {stats.coherence:.3f} < "
                   f"{limits.min_coherence}): noise or a pattern, not a combed swatch")
    elif stats.energy < limits.min_energy and not fine_fibres(stats, limits):
        out.append(f"out of domain: no strand texture in the swatch area (texture {stats.energy:.1f} < "
                   f"{limits.min_energy}, and not fine fibres': {100 * stats.fine_share:.0f}% of it fine, "
                   f"channels correlated {stats.fine_corr:.2f} there): a smooth gradient or a blurred picture, "
                   f"not hair")
    elif stats.peak_share > limits.max_peak_share:
        out.append(f"out of domain: a few spatial frequencies hold {100 * stats.peak_share:.0f}% of the texture "
                   f"(over {100 * limits.max_peak_share:.0f}%): stripes, a gradient or a printed pattern, not hair")
    if not stats.greyscale and stats.std >= limits.min_std and stats.channel_corr < limits.min_channel_corr:
        out.append(f"out of domain: the colour channels vary independently (correlation {stats.channel_corr:.2f} "
                   f"< {limits.min_channel_corr}): colour noise, not hair")
    if stats.std > limits.max_std or stats.energy > limits.max_energy:
        out.append(f"out of domain: far more contrast than a hair swatch (contrast {stats.std:.0f}, texture "
                   f"{stats.energy:.0f}); is the swatch area on the swatch?")
    if stats.greyscale:
        out.append("out of domain: the image has no colour (R = G = B everywhere), perhaps a greyscale image "
                   "saved as RGB; capture in colour")
    if stats.clipped > limits.clipped_share and stats.clipped_on == "sensor":
        out.append(f"clipped: {100 * stats.clipped:.1f}% of the swatch area is at the sensor's white level; lower "
                   "the exposure and capture again")
    elif stats.clipped > limits.clipped_share:
        out.append(f"clipped: {100 * stats.clipped:.1f}% of the swatch area is at 0 or 255; lower or raise "
                   "the exposure and capture again")
    if view_spread is not None and view_spread > limits.max_view_spread:
        out.append(f"out of domain: the encoder's eight views of the swatch disagree (spread {view_spread:.2f} "
                   f"> {limits.max_view_spread})")
    return out
