"""The fibre spread and the grey share, read from the swatch's texture at the fibre scale.

At the bench camera a fibre is about one pixel wide, so fibres that differ in pigment make the
swatch area's pixels differ from their neighbours: a spread of ln sigma_a makes neighbouring fibres
lighter and darker, and more and less saturated, about the median; grey fibres add a one-sided
population of light, neutral pixels. The mean colour (what the refinement fits) and the lighting's
slow fall-off across the swatch carry none of it, so ``texture_features`` works on what is left once
a blurred copy is taken away, in logarithms (a global gain or a colour cast is an offset there, and
the offset is removed with the blur):

- ``log_luminance``: ln of the luminance, high-passed (a Gaussian of ``HIGHPASS_SIGMA_PX`` taken away);
- ``chroma``: ln(R/G) and ln(B/G), high-passed the same way; its magnitude, and its component towards
  neutral (against the area's mean chroma: how much "greyer" than its surroundings a pixel is);
- both also after a short blur along the fibres (``ALONG_FIBRE_PX``), which keeps what differs from
  fibre to fibre and averages away the sensor's noise and the glints, which do not follow a fibre.

From these, robust spreads (quantile differences), tails (the share of pixels far lighter or greyer
than their surroundings) and correlations (lighter pixels are greyer where greys are present).

``read_variation`` feeds them, with ln sigma_a and the shine, to a ridge regression fitted by
``inference.training.fit_texture`` and stored in ``resources/models/texture_model.json``; its
intervals are residual quantiles on held-out renders, scaled by how light the hair is (greys among
platinum hair are nearly invisible: the interval there is wide).
"""
from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from hairdigi.resources import MODELS

#: The Gaussian (pixels) whose blur is taken away: far wider than a fibre, far narrower than the
#: lights' fall-off across the swatch.
HIGHPASS_SIGMA_PX = 4.0
#: The Gaussians (pixels) of the blurs along the fibres: a fibre keeps its colour along its length,
#: the path tracer's and the sensor's noise and the glints do not.
ALONG_FIBRE_PX = (3.0, 10.0)
#: Lags (pixels, along the fibres) of the noise-free covariances: past the glints' spread (2 px).
FIBRE_LAGS_PX = (4, 8, 16)
#: A pixel counts "far lighter" / "far greyer" beyond these high-passed values (ln units).
LIGHTER_THRESHOLDS = (0.4, 0.8)
GREYER_THRESHOLDS = (0.1, 0.25)
_EPS = 1e-4
#: Mean chroma (ln R/G, ln B/G magnitude) from which "towards grey" has its full length.
CHROMA_FULL = 0.15
#: Rec. 709 luminance weights.
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)

MODEL_FILE = "texture_model.json"
TARGETS = ("fibre_spread", "grey_fraction")
LEVELS = ("p68", "p95")
#: Where the targets are clipped: the ranges the model was fitted on, to the appearance's limits.
TARGET_LIMITS = {"fibre_spread": (0.0, 1.0), "grey_fraction": (0.0, 1.0)}


def _highpass(channel: np.ndarray, sigma: float = HIGHPASS_SIGMA_PX) -> np.ndarray:
    return channel - cv2.GaussianBlur(channel, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)


def _along(channel: np.ndarray, axis: int, sigma: float) -> np.ndarray:
    """A 1-D Gaussian blur along ``axis`` (0: down the columns)."""
    size = int(2 * round(3 * sigma) + 1)
    kernel = cv2.getGaussianKernel(size, sigma).astype(np.float32)
    kx, ky = (np.ones((1, 1), np.float32), kernel) if axis == 0 else (kernel, np.ones((1, 1), np.float32))
    return cv2.sepFilter2D(channel, -1, kx, ky, borderType=cv2.BORDER_REFLECT)


def _robust_sd(values: np.ndarray) -> float:
    q = np.quantile(values, (0.1587, 0.8413))
    return float(q[1] - q[0]) / 2.0


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    den = float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
    return float(np.sum(a * b) / den) if den > 0 else 0.0


def _channels(pixels_linear: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ln luminance, ln R/G, ln B/G, and the unit chroma direction pointing from the area's mean
    chroma towards neutral grey."""
    img = np.asarray(pixels_linear, np.float32)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"pixels must be (H, W, 3) linear RGB, got shape {img.shape}")
    if min(img.shape[:2]) < 16:
        raise ValueError(f"the swatch area {img.shape[1]}x{img.shape[0]} px is too small to read its texture "
                         "(at least 16x16)")
    level = float(np.median(img.reshape(-1, 3), axis=0).mean())
    floor = max(level * 0.02, _EPS)          # a floor under dark pixels, proportional to the area's level
    rgb = np.maximum(img, 0.0) + floor
    log_rgb = np.log(rgb)
    lum = np.log(rgb @ _LUMA)
    c1 = log_rgb[..., 0] - log_rgb[..., 1]
    c2 = log_rgb[..., 2] - log_rgb[..., 1]
    mean = np.array([np.median(c1), np.median(c2)])
    # the unit direction to neutral, shortened for nearly neutral hair (continuously: a small cast
    # must not flip the feature between two definitions)
    towards_grey = -mean / max(float(np.hypot(*mean)), CHROMA_FULL)
    return lum, c1, c2, towards_grey


FEATURE_NAMES: tuple[str, ...] = ()   # filled below from a probe call


def _features(pixels_linear: np.ndarray, axis: int = 0) -> dict[str, float]:
    if axis not in (0, 1):
        raise ValueError(f"fibre_axis must be 0 (fibres run down the image) or 1 (across it), got {axis!r}")
    lum, c1, c2, towards_grey = _channels(pixels_linear)
    feats: dict[str, float] = {}
    for tag, smooth in (("px", 0.0),) + tuple((f"fb{int(a)}", a) for a in ALONG_FIBRE_PX):
        planes = [(_along(p, axis, smooth) if smooth else p) for p in (lum, c1, c2)]
        hl, h1, h2 = (_highpass(p) for p in planes)
        grey = h1 * towards_grey[0] + h2 * towards_grey[1]        # towards neutral (0 for neutral hair)
        # the edges hold the reflected border's artefacts: leave out the blur's width
        m = int(np.ceil(2 * HIGHPASS_SIGMA_PX))
        hl, grey, chroma = (a[m:-m, m:-m].ravel() for a in (hl, grey, np.hypot(h1, h2)))
        q = np.quantile(hl, (0.02, 0.1, 0.25, 0.5, 0.75, 0.9, 0.98))
        feats[f"{tag}_lum_sd"] = _robust_sd(hl)
        feats[f"{tag}_lum_iqr"] = float(q[4] - q[2])
        feats[f"{tag}_lum_upper"] = float(q[6] - q[3])
        feats[f"{tag}_lum_lower"] = float(q[3] - q[0])
        feats[f"{tag}_lum_skew"] = float((q[5] - q[3]) - (q[3] - q[1])) / max(float(q[5] - q[1]), 1e-6)
        for t in LIGHTER_THRESHOLDS:
            feats[f"{tag}_lighter_{t}"] = float(np.mean(hl > t))
        g = np.quantile(grey, (0.1, 0.5, 0.9, 0.98))
        g_low = np.quantile(grey, (0.02, 0.25))
        feats[f"{tag}_grey_sd"] = _robust_sd(grey)
        feats[f"{tag}_grey_upper"] = float(g[3] - g[1])
        # more saturated than the surroundings: fibres of more pigment, never greys (spread alone)
        feats[f"{tag}_grey_lower"] = float(g[1] - g_low[0])
        feats[f"{tag}_grey_lower_iq"] = float(g[1] - g_low[1])
        feats[f"{tag}_grey_skew"] = float((g[2] - g[1]) - (g[1] - g[0])) / max(float(g[2] - g[0]), 1e-6)
        for t in GREYER_THRESHOLDS:
            feats[f"{tag}_greyer_{t}"] = float(np.mean(grey > t))
        feats[f"{tag}_chroma_p50"] = float(np.quantile(chroma, 0.5))
        feats[f"{tag}_chroma_p95"] = float(np.quantile(chroma, 0.95))
        feats[f"{tag}_corr_lum_grey"] = _corr(hl, grey)
        feats[f"{tag}_lighter_and_greyer"] = float(np.mean((hl > LIGHTER_THRESHOLDS[0]) & (grey > GREYER_THRESHOLDS[0])))
    for a in ALONG_FIBRE_PX:
        feats[f"fb{int(a)}_over_px_lum"] = feats[f"fb{int(a)}_lum_sd"] / max(feats["px_lum_sd"], 1e-6)
        feats[f"fb{int(a)}_over_px_grey"] = feats[f"fb{int(a)}_grey_sd"] / max(feats["px_grey_sd"], 1e-6)
    # whole fibre runs: the mean of each column (row, for horizontal fibres), high-passed across
    cols = [np.mean(p, axis=axis) for p in (lum, c1, c2)]
    cl, k1, k2 = (c - cv2.GaussianBlur(c.reshape(1, -1), (0, 0), HIGHPASS_SIGMA_PX,
                                       borderType=cv2.BORDER_REFLECT).ravel() for c in cols)
    m = int(np.ceil(2 * HIGHPASS_SIGMA_PX))
    cl, cg = cl[m:-m], (k1 * towards_grey[0] + k2 * towards_grey[1])[m:-m]
    feats["col_lum_sd"] = float(np.std(cl))
    feats["col_grey_sd"] = float(np.std(cg))
    feats["col_lum_skew"] = float(np.mean((cl - cl.mean()) ** 3) / max(np.std(cl) ** 3, 1e-9))
    feats["col_corr_lum_grey"] = _corr(cl, cg)
    feats["col_over_px_lum"] = feats["col_lum_sd"] / max(feats["px_lum_sd"], 1e-6)
    # the fibres' own variation, free of the noise: covariance along the fibres at a lag (the noise of
    # two pixels apart is independent, a fibre's colour is the same), as a signed standard deviation
    hl, h1, h2 = (_highpass(p) for p in (lum, c1, c2))
    hg = h1 * towards_grey[0] + h2 * towards_grey[1]
    if axis == 1:
        hl, h1, h2, hg = hl.T, h1.T, h2.T, hg.T
    hl, h1, h2, hg = (a[:, m:-m] for a in (hl, h1, h2, hg))
    for lag in FIBRE_LAGS_PX:
        def acov(a: np.ndarray, b: np.ndarray) -> float:
            a0, b0 = a[:-lag] - a.mean(), b[lag:] - b.mean()
            return float(np.mean(a0 * b0))
        for name, a, b in (("lum", hl, hl), ("grey", hg, hg), ("lum_grey", hl, hg)):
            v = acov(a, b) if name != "lum_grey" else 0.5 * (acov(a, b) + acov(b, a))
            feats[f"lag{lag}_{name}"] = float(np.sign(v) * np.sqrt(abs(v)))
        v = acov(h1, h1) + acov(h2, h2)
        feats[f"lag{lag}_chroma"] = float(np.sign(v) * np.sqrt(abs(v)))
    feats["saturation"] = float(np.hypot(np.median(c1), np.median(c2)))
    return feats


def texture_features(pixels_linear: np.ndarray, fibre_axis: int = 0) -> np.ndarray:
    """Statistics of the swatch area's texture at the fibre scale, ``FEATURE_NAMES`` order.

    ``pixels_linear`` is the colour-corrected linear float (H, W, 3) swatch area of the all-lights
    frame, at the capture's full resolution (a fibre about a pixel wide); ``fibre_axis`` the image
    axis the fibres run along (0, down the image, at the bench camera: the rig holds the strands
    along its y axis, the image's vertical; noise this strong makes a guess from the image unsafe).
    The statistics respond to the fibres' spread and grey share and hardly to a global gain or a
    colour cast (they are taken on logarithms after the local mean is taken away; only
    ``saturation``, the area's mean chroma, follows a cast)."""
    return np.array(list(_features(pixels_linear, fibre_axis).values()), float)


FEATURE_NAMES = tuple(_features(np.random.default_rng(0).uniform(0.1, 1.0, (32, 32, 3)).astype(np.float32)))


# --- the model ---------------------------------------------------------------------------------
def covariates(sigma_a, shine: float) -> np.ndarray:
    """What conditions the reading besides the texture: mean ln sigma_a (how dark), the red-blue
    contrast of ln sigma_a (how coloured) and the shine."""
    log_sigma = np.log(np.maximum(np.asarray(sigma_a, float).ravel(), 0.0) + 0.01)
    if log_sigma.shape != (3,):
        raise ValueError(f"sigma_a must hold 3 values, got {sigma_a!r}")
    return np.array([log_sigma.mean(), log_sigma[2] - log_sigma[0], float(shine)])


def lightness(sigma_a) -> float:
    """How light the hair is, for the intervals: -mean ln(sigma_a + 0.01) (platinum about 4.3,
    mid brown about 1, black about -1)."""
    return float(-covariates(sigma_a, 0.3)[0])


#: Lightness bins the evidence reports (edges in ``lightness``): dark, medium, light.
LIGHTNESS_BINS = {"dark": (-np.inf, 0.0), "medium": (0.0, 2.0), "light": (2.0, np.inf)}


#: The regression designs ``fit_texture`` chooses from, per target, by cross-validation.
DESIGNS = ("linear", "products")


def design(features: np.ndarray, cov: np.ndarray, kind: str = "products") -> np.ndarray:
    """The regression's inputs: the features and the covariates (``"linear"``), and (``"products"``)
    also ln sigma_a's square and each feature times mean ln sigma_a, its square and the shine (the
    texture a given spread makes depends on how dark and how glossy the hair is: in platinum and in
    black hair a spread of pigment hardly shows)."""
    features = np.atleast_2d(features)
    cov = np.atleast_2d(cov)
    if kind == "linear":
        return np.hstack([features, cov])
    if kind != "products":
        raise ValueError(f"unknown design {kind!r}; choose one of {', '.join(DESIGNS)}")
    mods = np.column_stack([cov[:, 0], cov[:, 0] ** 2, cov[:, 2]])
    products = (features[:, :, None] * mods[:, None, :]).reshape(len(features), -1)
    return np.hstack([features, cov, mods[:, 1:2], products])


@dataclass(frozen=True)
class TextureModel:
    """A ridge regression per target on standardised ``design`` inputs (``kinds``), with interval scales."""

    kinds: dict[str, str]
    mean: dict[str, np.ndarray]
    scale: dict[str, np.ndarray]
    coef: dict[str, np.ndarray]
    intercept: dict[str, float]
    #: per target: the residual's scale per lightness bin (``"scale"``: the mean |out-of-fold error| of
    #: the training renders in the bin) and, per level (``"k"``), the quantile of |error| / scale on
    #: the held-out renders: an interval is the reading +- k * scale.
    interval: dict[str, dict]
    feature_names: tuple[str, ...] = FEATURE_NAMES
    meta: dict = field(default_factory=dict)

    def predict(self, features: np.ndarray, cov: np.ndarray) -> dict[str, np.ndarray]:
        out = {}
        for t in TARGETS:
            x = (design(features, cov, self.kinds[t]) - self.mean[t]) / self.scale[t]
            out[t] = x @ self.coef[t] + self.intercept[t]
        return out

    def residual_scale(self, target: str, light: np.ndarray | float) -> np.ndarray:
        """The typical |error| of ``target`` for hair of ``lightness`` ``light`` (per ``LIGHTNESS_BINS``)."""
        scales = self.interval[target]["scale"]
        light = np.asarray(light, float)
        out = np.zeros(light.shape)
        for name, (lo, hi) in LIGHTNESS_BINS.items():
            out = np.where((light >= lo) & (light < hi), scales[name], out)
        return out

    def to_dict(self) -> dict:
        return {"kind": "ridge", "feature_names": list(self.feature_names), "designs": self.kinds,
                "mean": {t: v.tolist() for t, v in self.mean.items()},
                "scale": {t: v.tolist() for t, v in self.scale.items()}, "coef": {t: v.tolist() for t, v in self.coef.items()},
                "intercept": self.intercept, "interval": self.interval, "meta": self.meta}

    @classmethod
    def from_dict(cls, data: dict) -> "TextureModel":
        names = tuple(data["feature_names"])
        if names != FEATURE_NAMES:
            raise ValueError("texture_model.json was fitted on other features than inference.texture computes; "
                             "fit it again (python -m hairdigi.inference.training.fit_texture fit)")
        arrays = {key: {t: np.array(v) for t, v in data[key].items()} for key in ("mean", "scale", "coef")}
        return cls(dict(data["designs"]), arrays["mean"], arrays["scale"], arrays["coef"],
                   {t: float(v) for t, v in data["intercept"].items()}, data["interval"], names, data.get("meta", {}))


def model_path() -> Path:
    return MODELS / MODEL_FILE


@functools.lru_cache(maxsize=4)
def _load(path: str, mtime_ns: int) -> TextureModel:
    return TextureModel.from_dict(json.loads(Path(path).read_text()))


def load_model(path: str | Path | None = None) -> TextureModel:
    """The fitted model (default: the packaged ``texture_model.json``), cached while the file is unchanged."""
    path = Path(path) if path is not None else model_path()
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no texture model; fit one with python -m hairdigi.inference.training.fit_texture")
    return _load(str(path), path.stat().st_mtime_ns)


@dataclass(frozen=True)
class VariationReading:
    """The fibre spread and grey share read from a swatch area, each with its 68% and 95% intervals
    (``{"fibre_spread": {"p68": [lo, hi], "p95": [lo, hi]}, "grey_fraction": {...}}``)."""

    fibre_spread: float
    grey_fraction: float
    intervals: dict[str, dict[str, list[float]]]

    def to_dict(self) -> dict:
        return {"fibre_spread": self.fibre_spread, "grey_fraction": self.grey_fraction, "intervals": self.intervals}


def reading_from(model: TextureModel, features: np.ndarray, sigma_a, shine: float) -> VariationReading:
    """The reading for features already computed (``texture_features``)."""
    pred = model.predict(features, covariates(sigma_a, shine))
    light = lightness(sigma_a)
    values, intervals = {}, {}
    for target in TARGETS:
        lo_lim, hi_lim = TARGET_LIMITS[target]
        value = float(np.clip(pred[target][0], lo_lim, hi_lim))
        s = float(model.residual_scale(target, light))
        intervals[target] = {level: [float(np.clip(value - k * s, lo_lim, hi_lim)), float(np.clip(value + k * s, lo_lim, hi_lim))]
                             for level, k in model.interval[target]["k"].items()}
        values[target] = value
    return VariationReading(values["fibre_spread"], values["grey_fraction"], intervals)


def read_variation(pixels_linear: np.ndarray, sigma_a, shine: float, model: TextureModel | None = None) -> VariationReading:
    """The fibre spread (std of ln sigma_a across pigmented fibres) and the grey share of a swatch.

    ``pixels_linear``: the colour-corrected linear (H, W, 3) swatch area of the all-lights frame at the
    capture's resolution; ``sigma_a``: the median fibre's refined RGB sigma_a; ``shine``: the
    longitudinal roughness read from the three lights. The intervals are calibrated on held-out renders
    (wider for light hair, where greys hardly show)."""
    model = model or load_model()
    return reading_from(model, texture_features(pixels_linear), sigma_a, shine)


#: Lags (pixels along the fibres, at the bench camera's 400-pixel-wide frame) of the streak statistic.
STREAK_LAGS_PX = (4, 8, 16)
#: A floor under the luminance before its logarithm (linear units): dark hair's noise does not dominate.
STREAK_FLOOR = 1e-3


@dataclass(frozen=True)
class Streaks:
    """What the swatch area's texture says of how its fibres lie (``streaks``)."""

    along: float       # autocorrelation of the high-passed ln luminance along the fibres (lags STREAK_LAGS_PX)
    order: float       # 0-1: how far the local texture's orientations agree (1: every streak one way)


def streaks(pixels_linear: np.ndarray, fibre_axis: int = 0) -> Streaks:
    """Streaks along the fibres in the swatch area (linear (H, W, 3), a fibre about a pixel wide).

    Fibres side by side in full layers (hairdigi's layered swatch, tilted layers) show a top of even
    fibres: the texture is the noise's, with no direction and no correlation along the fibres. Fibres
    dropped one by one, spread or wavy leave voids and shadows that run along them: dark streaks, long
    along the fibres and oriented. ``along`` is the high-passed ln luminance's autocovariance at
    ``STREAK_LAGS_PX`` along ``fibre_axis`` over its variance; ``order`` the resultant length of the
    doubled local orientation angles (a structure tensor, Gaussian 4 px) over the more coherent half of
    the pixels, so a view that turns the fibres in the image reads the same."""
    if fibre_axis not in (0, 1):
        raise ValueError(f"fibre_axis must be 0 (fibres run down the image) or 1 (across it), got {fibre_axis!r}")
    img = np.asarray(pixels_linear, np.float32)
    if img.ndim != 3 or img.shape[2] != 3 or min(img.shape[:2]) < 2 * max(STREAK_LAGS_PX):
        raise ValueError(f"pixels must be a linear (H, W, 3) swatch area at least {2 * max(STREAK_LAGS_PX)} px "
                         f"a side, got shape {img.shape}")
    lum = np.log(np.maximum(img, 0.0) @ _LUMA + STREAK_FLOOR).astype(np.float32)
    high = _highpass(lum, HIGHPASS_SIGMA_PX)
    if fibre_axis == 1:
        high = high.T
    m = int(np.ceil(2 * HIGHPASS_SIGMA_PX))
    h = high[:, m:-m] - high[:, m:-m].mean()
    along = float(np.mean([np.mean(h[:-lag] * h[lag:]) for lag in STREAK_LAGS_PX]) / max(float(np.var(h)), 1e-12))
    smooth = cv2.GaussianBlur(lum, (0, 0), 1.0)
    gx, gy = cv2.Sobel(smooth, cv2.CV_32F, 1, 0), cv2.Sobel(smooth, cv2.CV_32F, 0, 1)
    jxx, jyy, jxy = (cv2.GaussianBlur(v, (0, 0), HIGHPASS_SIGMA_PX) for v in (gx * gx, gy * gy, gx * gy))
    coherence = np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2) / (jxx + jyy + 1e-9)
    doubled = np.arctan2(2 * jxy, jxx - jyy)[coherence > np.median(coherence)]
    order = float(abs(np.mean(np.exp(1j * doubled)))) if doubled.size else 0.0
    return Streaks(round(along, 5), round(order, 5))
