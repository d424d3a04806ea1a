"""Denoising of preview renders, for display only: Intel Open Image Denoise (``pyoidn``) on linear RGB.

A denoised image is a picture for the operator. It never goes to the estimator or into a metric:
those take the raw path-traced image, whose mean is unbiased.

OIDN removes fireflies, and with them some of a low-spp pass's energy (the twin's 1-spp pass lost
ΔE2000 2.0 of mean colour). :func:`denoise` therefore adds back what it removed, blurred to a coarse
scale (``keep_mean``, :func:`restore_mean`): the clean picture keeps the raw pass's colour region by
region, and a background the raw pass had right stays untouched (a global gain tinted it).
Without ``pyoidn`` :func:`available` is False and :func:`denoise` raises :class:`DenoiserMissing`
naming the fix; the app then shows the raw passes.
"""
from __future__ import annotations

import sys
import threading

import numpy as np

from hairdigi.render.domain.errors import HairdigiError


class DenoiserMissing(HairdigiError, RuntimeError):
    """``pyoidn`` is not installed (or its OIDN libraries do not load)."""


_LOCK = threading.Lock()
_STATE: dict = {}


def _import_pyoidn():
    """``import pyoidn``, without the torch it imports when torch is installed (for tensor inputs,
    which hairdigi does not use): that took 1.3 s, and the runtime path never loads torch."""
    hide = "torch" not in sys.modules
    if hide:
        sys.modules["torch"] = None          # makes pyoidn's optional ``import torch`` fail, as without torch
    try:
        import pyoidn   # deferred: pyoidn loads the OIDN library; only a denoise needs it
    finally:
        if hide and "torch" in sys.modules and sys.modules["torch"] is None:
            del sys.modules["torch"]
    return pyoidn


def _oidn():
    with _LOCK:
        if "module" not in _STATE:
            try:
                _STATE["module"], _STATE["error"] = _import_pyoidn(), None
            except (ImportError, OSError) as exc:   # OSError: the wheel's OIDN libraries do not load
                _STATE["module"], _STATE["error"] = None, exc
    if _STATE["module"] is None:
        raise DenoiserMissing(f"the denoiser is missing ({_STATE['error']}); install it with "
                              "`pip install pyoidn==2.5.1.0`, or preview the raw passes")
    return _STATE["module"]


def available() -> bool:
    """True when :func:`denoise` can run."""
    try:
        _oidn()
        return True
    except DenoiserMissing:
        return False


def name() -> str:
    """What denoises, for the window's status line and the benchmark's table."""
    try:
        return f"OIDN {getattr(_oidn().version, 'oidn_version', '')}".strip()
    except DenoiserMissing:
        return "none"


#: The scale (pixels) at which :func:`restore_mean` gives back what the denoiser removed: coarser than
#: fibres and clumps, finer than a head. Measured on the twin (1-spp pass, per-pixel ΔE2000 against
#: 1024 spp): 3.77 with nothing given back, 3.49 at 16 px, 3.83 at 8 px, 3.25 with one global gain.
RESTORE_SIGMA_PX = 16.0


def restore_mean(denoised: np.ndarray, raw: np.ndarray, sigma_px: float = RESTORE_SIGMA_PX) -> np.ndarray:
    """``denoised`` plus the part of ``raw - denoised`` coarser than ``sigma_px``: the local mean colour
    of ``raw`` (and its global mean) without its noise."""
    import cv2   # deferred: OpenCV takes ~0.3 s; only this step needs it

    residual = np.ascontiguousarray(raw - denoised, dtype=np.float32)
    coarse = cv2.GaussianBlur(residual, (0, 0), sigmaX=float(sigma_px), borderType=cv2.BORDER_REFLECT)
    return np.clip(denoised + coarse, 0.0, None).astype(np.float32)


def denoise(linear: np.ndarray, albedo: np.ndarray | None = None, normal: np.ndarray | None = None,
            keep_mean: bool = True, quality: str = "high") -> np.ndarray:
    """A denoised copy of an (H, W, 3) linear RGB render (HDR, values >= 0); the input is untouched.

    ``albedo`` ([0, 1]) and ``normal`` ([-1, 1]) are optional guide images of the same shape.
    ``keep_mean`` gives back, at a coarse scale, the energy the denoiser removed (see the module's note).
    """
    image = np.asarray(linear, dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3 or min(image.shape[:2]) < 1:
        raise ValueError(f"denoise takes an (H, W, 3) linear RGB image, got shape {image.shape}")
    nonfinite = int(image.size - np.count_nonzero(np.isfinite(image)))
    if nonfinite:   # the renderer counts and replaces them (RenderResult.nonfinite): never hidden here
        raise ValueError(f"denoise takes a finite image, got {nonfinite} NaN or Inf values; denoise the "
                         f"renderer's linear image, whose non-finite samples are counted and replaced")
    image = np.ascontiguousarray(np.clip(image, 0.0, None))
    guides = [None if g is None else np.ascontiguousarray(g, dtype=np.float32) for g in (albedo, normal)]
    out = _oidn().denoise(image, guides[0], guides[1], hdr=True, quality=quality)
    out = np.clip(out, 0.0, None)
    return restore_mean(out, image) if keep_mean else out
