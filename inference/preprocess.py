"""Capture preprocessing shared by training and inference: read, validate, find the swatch, encode.

The encoder sees sRGB 8-bit colour, as a camera (or the renderer's ``srgb`` output) gives it,
scaled to [-0.5, 0.5], channels first. Training crops random squares of all-hair renders; at
inference the swatch area is found (or given as a ROI) and its central square is used.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

MIN_SIDE = 32          # smaller images hold too few strands to judge a colour
ROI_CENTRAL = 0.7      # share of the swatch area's shorter side kept at inference, away from its edges


class ImageError(ValueError):
    """The image cannot be used; the message names the problem and the fix."""


def _check_complete(data: bytes, path: Path) -> None:
    if data[:8] == b"\x89PNG\r\n\x1a\n" and b"IEND" not in data[-16:]:
        raise ImageError(f"{path}: the PNG is truncated (no IEND chunk); copy the file again")
    if data[:2] == b"\xff\xd8" and not data.rstrip(b"\0").endswith(b"\xff\xd9"):
        raise ImageError(f"{path}: the JPEG is truncated (no end marker); copy the file again")


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an 8-bit RGB image; clear errors for missing, non-image, truncated and 16-bit files."""
    path = Path(path)
    if not path.exists():
        raise ImageError(f"{path}: no such file")
    data = path.read_bytes()
    if not data:
        raise ImageError(f"{path}: the file is empty")
    _check_complete(data, path)
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ImageError(f"{path}: not an image OpenCV can read (PNG, JPEG, TIFF, ...); "
                         f"for RAW files use the capture command")
    if img.dtype != np.uint8:
        raise ImageError(f"{path}: {img.dtype} ({8 * img.dtype.itemsize}-bit) image; the encoder takes "
                         f"8-bit sRGB: export 8-bit, or capture RAW through the rig, which converts it")
    if img.ndim == 2:
        raise ImageError(f"{path}: a greyscale image has no hair colour; use a colour image")
    if img.shape[2] == 4:
        img = img[..., :3]
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def validate_image(img: np.ndarray, name: str = "image") -> np.ndarray:
    """Check an in-memory RGB image: 8-bit, 3 channels, big enough, and not flat."""
    if img.dtype != np.uint8:
        raise ImageError(f"{name}: {img.dtype} data; the encoder takes 8-bit sRGB (uint8)")
    if img.ndim != 3 or img.shape[2] != 3:
        raise ImageError(f"{name}: shape {img.shape}; expected height x width x 3 (RGB)")
    if min(img.shape[:2]) < MIN_SIDE:
        raise ImageError(f"{name}: {img.shape[1]}x{img.shape[0]} px is too small; the swatch needs at "
                         f"least {MIN_SIDE}x{MIN_SIDE} px")
    if float(img.std()) < 1.0:
        raise ImageError(f"{name}: the image is flat (one grey level): no swatch in view? Check the "
                         f"lens cap, the lights and the exposure")
    return img


@dataclass(frozen=True)
class Roi:
    x: int
    y: int
    w: int
    h: int

    @classmethod
    def parse(cls, text: str) -> "Roi":
        try:
            x, y, w, h = (int(v) for v in text.split(","))
        except ValueError:
            raise ImageError(f"ROI {text!r} must be x,y,w,h in pixels, e.g. 40,30,200,180") from None
        return cls(x, y, w, h)

    def clip(self, img: np.ndarray) -> np.ndarray:
        h, w = img.shape[:2]
        if self.w < MIN_SIDE or self.h < MIN_SIDE or self.x < 0 or self.y < 0 \
                or self.x + self.w > w or self.y + self.h > h:
            raise ImageError(f"ROI {self} does not fit a {w}x{h} image with sides >= {MIN_SIDE} px")
        return img[self.y:self.y + self.h, self.x:self.x + self.w]


def _border(values: np.ndarray, share: float = 0.06) -> np.ndarray:
    h, w = values.shape[:2]
    bh, bw = max(1, int(h * share)), max(1, int(w * share))
    return np.concatenate([values[:bh].reshape(-1, *values.shape[2:]), values[-bh:].reshape(-1, *values.shape[2:]),
                           values[:, :bw].reshape(-1, *values.shape[2:]), values[:, -bw:].reshape(-1, *values.shape[2:])])


def swatch_score(img: np.ndarray) -> np.ndarray:
    """How unlike the holder each pixel's neighbourhood is; the holder is what the frame's border shows.

    Hair differs from the holder in colour, in texture energy, or both (platinum hair on a grey
    holder differs in texture; a smooth dark swatch in colour). Values above 1 count as swatch.
    """
    sigma = max(1.5, min(img.shape[:2]) / 50.0)
    f = img.astype(np.float32)
    local = cv2.GaussianBlur(f, (0, 0), sigma)
    background = np.median(_border(local), axis=0)
    colour_distance = np.linalg.norm(local - background, axis=2)
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    detail = gray - cv2.GaussianBlur(gray, (0, 0), 1.0)
    energy = np.sqrt(cv2.GaussianBlur(detail * detail, (0, 0), sigma))
    background_energy = float(np.median(_border(energy)))
    return np.maximum(colour_distance / 12.0, energy / (1.8 * background_energy + 1.5))


def find_swatch_roi(img: np.ndarray) -> Roi:
    """The bounding box of the largest region unlike the frame's border; the whole image when no
    such region stands out (an image that is all hair)."""
    h, w = img.shape[:2]
    mask = (swatch_score(img) > 1.0).astype(np.uint8)
    k = max(3, min(h, w) // 40) | 1
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((k, k), np.uint8))
    n, _, stats, _ = cv2.connectedComponentsWithStats(mask)
    if n <= 1:
        return Roi(0, 0, w, h)
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x, y, bw, bh, area = (int(v) for v in stats[best])
    # a swatch on its holder is a large, filled rectangle; streaks inside an all-hair image are not
    if area < 0.10 * h * w or area < 0.6 * bw * bh or bw * bh > 0.85 * h * w:
        return Roi(0, 0, w, h)
    if min(bw, bh) < MIN_SIDE:
        raise ImageError(f"the swatch area found is only {bw}x{bh} px (at least {MIN_SIDE} px a side is "
                         f"needed): move the camera closer, or pass its area with --roi x,y,w,h")
    return Roi(x, y, bw, bh)


def central_square(img: np.ndarray, share: float = ROI_CENTRAL) -> np.ndarray:
    """The central square whose side is ``share`` of the shorter side."""
    h, w = img.shape[:2]
    side = max(MIN_SIDE // 2, int(round(min(h, w) * share)))
    y0, x0 = (h - side) // 2, (w - side) // 2
    return img[y0:y0 + side, x0:x0 + side]


def swatch_crop(img: np.ndarray, roi: Roi | None = None) -> tuple[np.ndarray, Roi]:
    """The hair the encoder should see: the ROI (found when not given), then its central square.

    An all-hair image keeps its whole central square; a rig frame keeps the middle of the swatch.
    """
    validate_image(img)
    roi = roi or find_swatch_roi(img)
    region = roi.clip(img)
    full = roi.w == img.shape[1] and roi.h == img.shape[0]
    return central_square(region, 1.0 if full else ROI_CENTRAL), roi


def encode(img: np.ndarray, size: int) -> np.ndarray:
    """Resize (area filter) to ``size``² and encode as float32 (3, size, size) in [-0.5, 0.5]."""
    if img.shape[0] != size or img.shape[1] != size:
        img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
    return (img.astype(np.float32) / 255.0 - 0.5).transpose(2, 0, 1).copy()
