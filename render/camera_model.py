"""One camera model for the simulated rig and for training: linear radiance in, an 8-bit sRGB frame out.

A frame is ``radiance x 2**exposure_ev x gain x cast``, plus shot noise (variance proportional to
the signal) and read noise, clipped and quantised by a 12-bit ADC, then sRGB-encoded to 8 bits.
The simulated rig (``hardware.sim_rig``) shoots its frames through it; training
(``inference.training.train``) passes every linear render through it with small random errors, so the
encoder sees what ``estimate`` receives from a calibrated camera.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from hairdigi.render.srgb import linear_to_srgb8

ADC_BITS = 12
#: The simulated bench's exposure, set as an operator sets it with the exposure check: the chart's white
#: patch in its band (8-bit level about 195, ``hardware.exposure.WHITE_BAND``), with room for +0.5 EV of
#: error before the chart clips (a platinum swatch's glints may: that capture is then refused).
NOMINAL_EXPOSURE = 2.0 ** -0.25


@dataclass
class CameraModel:
    """A simple sensor: linear radiance x 2**exposure_ev x gain x cast, noise, clip, sRGB, 8 bits."""

    exposure_ev: float = 0.0
    gain: float = 1.0
    cast: tuple[float, float, float] = (1.0, 1.0, 1.0)   # white-balance error, per channel
    shot_noise: float = 0.0015   # variance per unit signal (photon noise)
    read_noise: float = 0.002    # standard deviation, in units of full scale

    def settings(self) -> dict:
        return asdict(self)


_LUT_MAX = 2**ADC_BITS - 1
#: ADC code to 8-bit sRGB (colour-science's sRGB curve), so a frame costs one table lookup.
_SRGB_LUT = linear_to_srgb8(np.arange(_LUT_MAX + 1) / _LUT_MAX)


def sensor_response(linear: np.ndarray, model: CameraModel, rng: np.random.Generator) -> np.ndarray:
    """Apply the camera model to linear radiance; returns the 8-bit sRGB frame (12-bit ADC, then sRGB)."""
    scale = np.float32(2.0 ** model.exposure_ev * model.gain) * np.asarray(model.cast, np.float32)
    signal = np.asarray(linear, dtype=np.float32) * scale
    noise_sd = np.sqrt(np.maximum(signal, 0) * np.float32(model.shot_noise) + np.float32(model.read_noise**2))
    signal = signal + rng.standard_normal(signal.shape, dtype=np.float32) * noise_sd
    codes = np.clip(signal * _LUT_MAX + 0.5, 0, _LUT_MAX).astype(np.uint16)
    return _SRGB_LUT[codes]


@dataclass(frozen=True)
class CaptureErrors:
    """How far a calibrated capture strays from the renderer's linear radiance, for training draws.

    The colour correction (CCM) removes the exposure and the white balance; what is left is small:
    ``hairdigi bench rig`` measured ΔE2000 0.57 on average after the CCM. ``exposure_sd`` (EV) and
    ``cast_sd`` (per channel) are that residual; the noise ranges cover the simulated rig's sensor
    (shot 0.0015, read 0.002) with room on either side.
    """

    exposure_sd: float = 0.015
    cast_sd: float = 0.008
    shot_noise: tuple[float, float] = (0.0, 0.004)
    read_noise: tuple[float, float] = (0.0005, 0.004)


def random_camera(rng: np.random.Generator, errors: CaptureErrors = CaptureErrors()) -> CameraModel:
    """A camera with the residual errors of a calibrated capture, drawn at random."""
    return CameraModel(exposure_ev=float(rng.normal(0.0, errors.exposure_sd)),
                       cast=tuple(float(c) for c in rng.normal(1.0, errors.cast_sd, size=3)),
                       shot_noise=float(rng.uniform(*errors.shot_noise)),
                       read_noise=float(rng.uniform(*errors.read_noise)))


def spread_glints(linear: np.ndarray, ratio: float = 3.0, margin: float = 0.05, sigma_px: float = 2.0) -> np.ndarray:
    """Spread a render's single-pixel glints over their neighbours, keeping their energy.

    A path tracer at a few samples per pixel concentrates a fibre's glint in a few pixels far above
    their surroundings; a camera integrates the converged glint over each pixel's area behind its
    lens. The excess over ``ratio`` x the 3 x 3 median + ``margin`` is blurred with a Gaussian of
    ``sigma_px`` and added back, so the image's sum (the swatch's colour) is unchanged where
    removing the outliers would darken hair by up to 18% in red (``shared/reference/inverse-notes.md``;
    on the simulated rig's hidden swatch that was ΔE2000 3.65).
    """
    import cv2   # deferred: OpenCV takes ~0.3 s; only this step needs it

    img = np.ascontiguousarray(linear, dtype=np.float32)
    threshold = np.float32(ratio) * cv2.medianBlur(img, 3) + np.float32(margin)
    excess = np.maximum(img - threshold, 0)
    return np.minimum(img, threshold) + cv2.GaussianBlur(excess, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT)
