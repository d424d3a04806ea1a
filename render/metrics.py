"""Image-comparison metrics: RMSE, L1 on the 0–255 scale, ΔE2000 (colour-science) and MS-SSIM.

Inputs are linear RGB in the renderer's colour space (linear sRGB primaries, D65) unless a
function says it takes 8-bit sRGB.
"""
from __future__ import annotations

import colour
import numpy as np
from scipy.ndimage import gaussian_filter

_SRGB = colour.RGB_COLOURSPACES["sRGB"]


def linear_rgb_to_lab(rgb: np.ndarray, whitepoint: np.ndarray | None = None) -> np.ndarray:
    """Linear sRGB (white = 1) to CIE L*a*b*, through colour-science: against D65, or against the
    ``whitepoint`` (xy) of the light the scene was lit by (an observer adapted to it)."""
    xyz = colour.RGB_to_XYZ(np.asarray(rgb, dtype=float), _SRGB, apply_cctf_decoding=False)
    return colour.XYZ_to_Lab(xyz, _SRGB.whitepoint if whitepoint is None else np.asarray(whitepoint, float))


def delta_e2000(rgb_a: np.ndarray, rgb_b: np.ndarray, whitepoint: np.ndarray | None = None) -> np.ndarray:
    """ΔE2000 between linear-RGB colours (any shape ending in 3), against D65 or ``whitepoint`` (xy)."""
    return colour.delta_E(linear_rgb_to_lab(rgb_a, whitepoint), linear_rgb_to_lab(rgb_b, whitepoint),
                          method="CIE 2000")


def error_stats(values) -> dict:
    """n, median, p95 and worst of the values that are not None (rounded for the evaluations' tables)."""
    v = np.asarray([x for x in values if x is not None], float)
    if not len(v):
        return {"n": 0}
    return {"n": int(len(v)), "median": round(float(np.median(v)), 3), "p95": round(float(np.quantile(v, 0.95)), 3),
            "worst": round(float(v.max()), 3)}


def delta_e2000_lab(lab_a: np.ndarray, lab_b: np.ndarray) -> np.ndarray:
    """ΔE2000 between CIELAB colours (any shape ending in 3): an instrument's readings."""
    return colour.delta_E(np.asarray(lab_a, float), np.asarray(lab_b, float), method="CIE 2000")


def bland_altman(a: np.ndarray, b: np.ndarray) -> dict:
    """Bland & Altman (1986)'s agreement of two methods measuring the same items: the mean difference
    ``a - b`` (the bias), its standard deviation, and the 95% limits of agreement (bias ± 1.96 SD)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    diff = a - b
    bias = float(diff.mean()) if len(diff) else float("nan")
    sd = float(diff.std(ddof=1)) if len(diff) > 1 else 0.0
    return {"n": int(len(diff)), "bias": round(bias, 3), "sd": round(sd, 3),
            "lower": round(bias - 1.96 * sd, 3), "upper": round(bias + 1.96 * sd, 3)}


def quantiles(values) -> dict:
    """n, median, p68, p95 and worst of the values that are not None (an interval's figures)."""
    v = np.asarray([x for x in values if x is not None], float)
    if not len(v):
        return {"n": 0}
    return {**error_stats(v), "p68": round(float(np.quantile(v, 0.68)), 3)}


def mean_colour_delta_e(image_a: np.ndarray, image_b: np.ndarray) -> float:
    """ΔE2000 between the mean linear colours of two images (what a viewer sees from afar)."""
    return float(delta_e2000(image_a.reshape(-1, 3).mean(0), image_b.reshape(-1, 3).mean(0)))


def pixel_delta_e(image_a: np.ndarray, image_b: np.ndarray) -> float:
    """Mean per-pixel ΔE2000 of two linear-RGB images of one shape (how far a preview is from a reference)."""
    a, b = np.asarray(image_a, dtype=float), np.asarray(image_b, dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"per-pixel ΔE2000 needs images of one shape, got {a.shape} and {b.shape}")
    return float(np.mean(delta_e2000(a, b)))


def delta_e_map(image_a: np.ndarray, image_b: np.ndarray, sigma_px: float = 0.0) -> np.ndarray:
    """(H, W) ΔE2000 of two linear-RGB images, both first smoothed by a Gaussian of ``sigma_px`` pixels.

    Smoothing at the fibre scale leaves colour differences and removes what no colour is: single
    fibres, sensor and render noise.
    """
    a, b = np.asarray(image_a, dtype=float), np.asarray(image_b, dtype=float)
    if a.shape != b.shape or a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"a ΔE2000 map needs two (H, W, 3) images of one shape, got {a.shape} and {b.shape}")
    if sigma_px > 0:
        a = gaussian_filter(a, (sigma_px, sigma_px, 0), mode="nearest")
        b = gaussian_filter(b, (sigma_px, sigma_px, 0), mode="nearest")
    return delta_e2000(a, b)


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.asarray(a, float) - np.asarray(b, float)) ** 2)))


def l1_255(srgb_a: np.ndarray, srgb_b: np.ndarray) -> float:
    """Mean absolute difference of two 8-bit images on the 0–255 scale (the paper's L1)."""
    return float(np.mean(np.abs(srgb_a.astype(float) - srgb_b.astype(float))))


# --- MS-SSIM (Wang, Simoncelli & Bovik 2003) --------------------------------------------------
MS_SSIM_WEIGHTS = np.array([0.0448, 0.2856, 0.3001, 0.2363, 0.1333])
_K1, _K2, _SIGMA = 0.01, 0.03, 1.5


def _ssim_parts(x: np.ndarray, y: np.ndarray, data_range: float) -> tuple[float, float]:
    c1, c2 = (_K1 * data_range) ** 2, (_K2 * data_range) ** 2
    blur = lambda im: gaussian_filter(im, _SIGMA, truncate=3.5, axes=(0, 1))  # noqa: E731  (11-tap window)
    mx, my = blur(x), blur(y)
    sxx = blur(x * x) - mx * mx
    syy = blur(y * y) - my * my
    sxy = blur(x * y) - mx * my
    cs = (2 * sxy + c2) / (sxx + syy + c2)
    lum = (2 * mx * my + c1) / (mx * mx + my * my + c1)
    crop = (slice(5, -5), slice(5, -5))  # valid region of the 11-tap window
    return float(np.mean((lum * cs)[crop])), float(np.mean(cs[crop]))


def ms_ssim(img_a: np.ndarray, img_b: np.ndarray, data_range: float = 255.0, scales: int = 5) -> float:
    """Multi-scale SSIM of two (H, W) or (H, W, C) images, averaged over channels; 1 is identical.

    The 5 scales of Wang et al. need both sides >= 161 px; smaller images raise ``ValueError``.
    ``scales`` < 5 uses the first weights, renormalised (3 scales need 43 px: for 64² swatches).
    """
    if not 1 <= scales <= 5:
        raise ValueError(f"MS-SSIM has 1 to 5 scales, got {scales}")
    weights = MS_SSIM_WEIGHTS[:scales] / MS_SSIM_WEIGHTS[:scales].sum()
    min_size = 11 * 2 ** (scales - 1) - 2 ** (scales - 1) + 1
    a, b = np.asarray(img_a, dtype=float), np.asarray(img_b, dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"MS-SSIM needs images of one shape, got {a.shape} and {b.shape}")
    if min(a.shape[:2]) < min_size:
        raise ValueError(f"MS-SSIM's {scales} scales need images of at least {min_size} px, got {a.shape[:2]}")
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    values = []
    for ch in range(a.shape[2]):
        x, y = a[..., ch], b[..., ch]
        mcs = []
        for scale in range(scales):
            ssim, cs = _ssim_parts(x, y, data_range)
            if scale < scales - 1:
                mcs.append(max(cs, 0.0))
                h, w = (x.shape[0] // 2) * 2, (x.shape[1] // 2) * 2
                x = x[:h, :w].reshape(h // 2, 2, w // 2, 2).mean((1, 3))
                y = y[:h, :w].reshape(h // 2, 2, w // 2, 2).mean((1, 3))
        values.append(np.prod(np.array(mcs) ** weights[:-1]) * max(ssim, 0.0) ** weights[-1])
    return float(np.mean(values))
