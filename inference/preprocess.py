"""Capture preprocessing shared by training and inference: read, validate, find the swatch, encode.

The encoder sees sRGB 8-bit colour, as a camera (or the renderer's ``srgb`` output) gives it,
resized in linear light and scaled to [-0.5, 0.5], channels first. Training crops random squares of all-hair renders; at
inference the swatch area is found (or given as a ROI) and its central square is used.
"""
from __future__ import annotations

import io
import os
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import read_bytes
from hairdigi.inference.calibration import CalibrationError, detect_chart
from hairdigi.render.srgb import linear_to_srgb, linear_to_srgb8, to_linear

MIN_SIDE = 32          # smaller images hold too few strands to judge a colour
ROI_CENTRAL = 0.7      # share of the swatch area's shorter side kept at inference, away from its edges
#: Largest image decoded: 64 MP (a 61 MP camera's still); 3 bytes a pixel, and a few copies while
#: finding the swatch, keep that under 1 GB. Larger files are refused from their header, undecoded.
MAX_IMAGE_PIXELS = 64_000_000
MAX_IMAGE_BYTES = 512 * 1024 * 1024
SEARCH_SIDE = 800      # frames are searched for the swatch at most this many pixels on their longer side


class ImageError(HairdigiError, ValueError):
    """The image cannot be used; the message names the problem and the fix."""


def _check_complete(data: bytes, path: Path) -> None:
    if data[:8] == b"\x89PNG\r\n\x1a\n" and b"IEND" not in data[-16:]:
        raise ImageError(f"{path}: the PNG is truncated (no IEND chunk); copy the file again")
    if data[:2] == b"\xff\xd8" and not data.rstrip(b"\0").endswith(b"\xff\xd9"):
        raise ImageError(f"{path}: the JPEG is truncated (no end marker); copy the file again")


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """Width and height from a JPEG's start-of-frame segment, or None when none is found."""
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:                       # fill byte
            i += 1
            continue
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        length = struct.unpack(">H", data[i + 2:i + 4])[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[i + 5:i + 9])
            return w, h
        i += 2 + length
    return None


def image_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from an image file's header, without decoding it; None when unknown. An image
    Pillow calls a decompression bomb (over 179 MP) raises ImageError."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR":
        return struct.unpack(">II", data[16:24])
    if data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    try:   # other formats (TIFF, BMP, WebP, ...): Pillow reads only the header here
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(io.BytesIO(data)) as im:
                return im.size
    except Exception as exc:   # not an image Pillow knows, or one it calls a decompression bomb
        if type(exc).__name__ == "DecompressionBombError":
            raise ImageError(f"the image is larger than {2 * Image.MAX_IMAGE_PIXELS / 1e6:.0f} MP, more than "
                             f"hairdigi decodes ({MAX_IMAGE_PIXELS / 1e6:.0f} MP); scale it down or crop it "
                             f"around the swatch and chart") from None
        return None


#: Images over this many pixels (a 6000x4000 frame is 24 MP) are decoded reduced, by 2, 4 or 8 a side
#: (``cv2.IMREAD_REDUCED_COLOR_*``; a JPEG is scaled while it is decoded): every later step, the
#: chart search included, then works on at most this many pixels, whatever the file holds. The
#: estimate's ROI and record are in the decoded image's pixels.
MAX_FULL_PIXELS = 24_000_000
_REDUCED = {2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4, 8: cv2.IMREAD_REDUCED_COLOR_8}


def _decode_flags(data: bytes, size: tuple[int, int] | None) -> int:
    """``cv2.imdecode``'s flags: unchanged, or reduced for an 8-bit colour image over ``MAX_FULL_PIXELS``
    (other kinds are decoded as they are, so that their own checks name them)."""
    if size is None or size[0] * size[1] <= MAX_FULL_PIXELS:
        return cv2.IMREAD_UNCHANGED
    eight_bit_colour = (data[:2] == b"\xff\xd8" or (data[:8] == b"\x89PNG\r\n\x1a\n" and data[24] == 8
                                                    and data[25] in (2, 6)))
    if not eight_bit_colour:
        return cv2.IMREAD_UNCHANGED
    factor = next((f for f in (2, 4, 8) if size[0] * size[1] / (f * f) <= MAX_FULL_PIXELS), 8)
    return _REDUCED[factor]


def _read_bytes(path: Path) -> bytes:
    """The file's bytes, with an ImageError naming the path and the fix for every way reading fails."""
    return read_bytes(path, ImageError, "a swatch image", MAX_IMAGE_BYTES, "export a smaller JPEG or PNG")


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an 8-bit RGB image; clear errors for missing, unreadable, non-image, truncated, 16-bit and
    oversized files (the size is read from the header, before anything is decoded)."""
    path = Path(path)
    data = _read_bytes(path)
    if not data:
        raise ImageError(f"{path}: the file is empty")
    _check_complete(data, path)
    try:
        size = image_size(data)
    except ImageError as exc:
        raise ImageError(f"{path}: {exc}") from None
    if size is not None and size[0] * size[1] > MAX_IMAGE_PIXELS:
        raise ImageError(f"{path}: {size[0]}x{size[1]} px is more than hairdigi decodes "
                         f"({MAX_IMAGE_PIXELS / 1e6:.0f} MP); scale it down or crop it around the swatch "
                         f"and chart, e.g. to 6000x4000")
    img = cv2.imdecode(np.frombuffer(data, np.uint8), _decode_flags(data, size))
    if img is not None and img.shape[0] * img.shape[1] > MAX_IMAGE_PIXELS:
        raise ImageError(f"{path}: {img.shape[1]}x{img.shape[0]} px is more than hairdigi takes "
                         f"({MAX_IMAGE_PIXELS / 1e6:.0f} MP); scale it down or crop it around the swatch")
    if img is None:
        raise ImageError(f"{path}: not an image OpenCV can read (PNG, JPEG, TIFF, ...); "
                         f"for a RAW still of the rig use hairdigi rig --still FILE")
    if img.dtype != np.uint8:
        raise ImageError(f"{path}: {img.dtype} ({8 * img.dtype.itemsize}-bit) image; the encoder takes "
                         f"8-bit sRGB: export 8-bit, or import a RAW still with hairdigi rig --still FILE")
    if img.ndim == 2:
        raise ImageError(f"{path}: a greyscale image has no hair colour; use a colour image")
    if img.shape[2] == 4:
        img = img[..., :3]
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def to_srgb8(img: np.ndarray) -> np.ndarray:
    """8-bit sRGB of an image: 8-bit sRGB as it is, linear float RGB (a corrected capture) encoded."""
    return img if img.dtype == np.uint8 else linear_to_srgb8(img)


def validate_image(img: np.ndarray, name: str = "image") -> np.ndarray:
    """Check an in-memory RGB image: 8-bit sRGB or linear float, 3 channels, big enough, and not flat."""
    if img.dtype != np.uint8 and img.dtype not in (np.float32, np.float64):
        raise ImageError(f"{name}: {img.dtype} data; the encoder takes 8-bit sRGB (uint8) or linear float RGB")
    if img.ndim != 3 or img.shape[2] != 3:
        raise ImageError(f"{name}: shape {img.shape}; expected height x width x 3 (RGB)")
    if min(img.shape[:2]) < MIN_SIDE:
        raise ImageError(f"{name}: {img.shape[1]}x{img.shape[0]} px is too small; the swatch needs at "
                         f"least {MIN_SIDE}x{MIN_SIDE} px")
    step = max(1, int(np.sqrt(img.shape[0] * img.shape[1] / 1e6)))   # about a million pixels decide it
    if float(to_srgb8(img[::step, ::step]).reshape(-1, 3).std(axis=0).max()) < 1.0:   # per channel: one colour is flat
        raise ImageError(f"{name}: the image is flat (one colour): no swatch in view? Check the "
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


def _detail_energy(img: np.ndarray) -> np.ndarray:
    """Each pixel's detail: its grey level's distance from a 1-px blur (texture, and the sensor's noise)."""
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    return np.abs(gray - cv2.GaussianBlur(gray, (0, 0), 1.0))


#: What the frame's border shows besides the holder: at a grazing view the camera sees past the holder
#: (the world beyond it: black in a render, a bench in a lab), a band along one side of the frame. A
#: group of border colours far from the holder's (``BACKGROUND_APART``) and holding at least
#: ``BACKGROUND_SHARE`` of the border is a background of its own, and a region like any background is
#: not the swatch (at 55° the band beyond the holder was unlike the holder, merged with the
#: swatch, and the whole frame, holder included, was taken as hair). The holder's own shading (the
#: simulated rig's border spans about 40 codes) stays one background: a dark swatch is unlike it.
BACKGROUND_SHARE = 0.15
BACKGROUND_GAP = 30.0      # 8-bit codes (RGB norm): border colours this close to a group's centre join it
BACKGROUND_APART = 90.0    # a further group's colours are this far from every earlier group's centre
MAX_BACKGROUNDS = 3
_SEED_SAMPLES = 1500       # border pixels tried as a group's centre


def _densest(colours: np.ndarray) -> np.ndarray:
    """The colour (one of a sample of ``colours``) with the most others within ``BACKGROUND_GAP``."""
    seeds = colours[:: max(1, len(colours) // _SEED_SAMPLES)]
    stride = max(1, len(colours) * len(seeds) // 4_000_000)
    others = colours[::stride]
    near = (np.linalg.norm(others[None, :, :] - seeds[:, None, :], axis=2) < BACKGROUND_GAP).sum(1)
    return seeds[int(np.argmax(near))]


def border_backgrounds(local: np.ndarray, energy: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """The groups of the frame's border colours (each its colour and median detail energy), largest
    first: the holder, and what lies beyond it when the view sees past it."""
    colours, energies = _border(local).reshape(-1, 3), _border(energy).ravel()
    groups: list[tuple[np.ndarray, float]] = []
    pool = np.ones(len(colours), bool)
    while len(groups) < MAX_BACKGROUNDS:
        if groups:
            centres = np.array([c for c, _ in groups])
            far = np.linalg.norm(colours[:, None, :] - centres[None, :, :], axis=2).min(1) >= BACKGROUND_APART
            pool &= far
            if pool.sum() < BACKGROUND_SHARE * len(colours):
                break
        centre = _densest(colours[pool])
        member = pool & (np.linalg.norm(colours - centre, axis=1) < BACKGROUND_GAP)
        groups.append((np.median(colours[member], axis=0), float(np.median(energies[member]))))
    return groups


def swatch_score(img: np.ndarray) -> np.ndarray:
    """How unlike the background each pixel's neighbourhood is; the background is what the frame's
    border shows: the holder, and what lies beyond it at a grazing view (``border_backgrounds``).

    Hair differs from the holder in colour, in texture energy, or both (platinum hair on a grey
    holder differs in texture; a smooth dark swatch in colour). A pixel's score is its least
    unlikeness to any background group; values above 1 count as swatch.
    """
    return _unlike_background(img, max(1.5, min(img.shape[:2]) / 50.0))[0]


def _unlike_background(img: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``swatch_score`` at the blur ``sigma``, and the local colour and detail energy it was judged on."""
    local = cv2.GaussianBlur(img.astype(np.float32), (0, 0), sigma)
    detail = _detail_energy(img)
    energy = np.sqrt(cv2.GaussianBlur(detail * detail, (0, 0), sigma))
    score = None
    for colour, background_energy in border_backgrounds(local, energy):
        colour_distance = np.linalg.norm(local - colour.astype(np.float32), axis=2)
        unlike = np.maximum(colour_distance / 12.0, energy / (1.8 * background_energy + 1.5))
        score = unlike if score is None else np.minimum(score, unlike)
    return score, local, energy


#: Strand coherence (0 to 1) above which the frame's border counts as hair: the border of an all-hair
#: image (uniform, dyed or with grey fibres) reads 0.45–0.8, a holder 0.1–0.2 and the simulated
#: rig's holder 0.12–0.18 (without it, grey fibres in an all-hair crop were taken for a swatch on a
#: holder, and the "swatch" was a streak of greys).
HAIR_BORDER_COHERENCE = 0.35


def strand_coherence(img: np.ndarray) -> np.ndarray:
    """Each pixel's strand coherence: how much its neighbourhood's gradients share one direction
    (the structure tensor's coherence, 0 for none to 1 for parallel strands), at the finder's scale
    and at least 3 px so that noise reads low (a window of a few hundred pixels)."""
    sigma = max(3.0, min(img.shape[:2]) / 50.0)
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1)
    jxx, jyy, jxy = (cv2.GaussianBlur(a, (0, 0), sigma) for a in (gx * gx, gy * gy, gx * gy))
    return np.sqrt((jxx - jyy) ** 2 + 4 * jxy * jxy) / (jxx + jyy + 1e-3)


def border_is_hair(img: np.ndarray) -> bool:
    """True when the frame's border shows strands (median coherence over ``HAIR_BORDER_COHERENCE``):
    the image is all hair, not a swatch on a holder, so no part of it is to be found."""
    return float(np.median(_border(strand_coherence(img)))) > HAIR_BORDER_COHERENCE


def chart_mask(img: np.ndarray, margin: float) -> np.ndarray | None:
    """A mask (uint8, 1 inside) over the ColorChecker in view, grown by ``margin`` pixels and by a
    tenth of its size to take in its board; None when no chart is found (detection as in calibration)."""
    try:
        box = detect_chart(img).box
    except (CalibrationError, cv2.error):
        return None
    centre = box.mean(axis=0)
    grown = centre + (box - centre) * 1.1
    grown += np.sign(grown - centre) * margin
    h, w = img.shape[:2]
    if cv2.contourArea(grown.astype(np.float32)) > 0.5 * h * w:
        return None   # a "chart" covering half the frame is a misdetection, not the chart beside a swatch
    mask = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(mask, np.round(grown).astype(np.int32), 1)
    return mask


def _search_image(img: np.ndarray) -> tuple[np.ndarray, float]:
    """The frame scaled down (area filter) to at most ``SEARCH_SIDE`` on its longer side, and the scale."""
    scale = min(1.0, SEARCH_SIDE / max(img.shape[:2]))
    if scale == 1.0:
        return img, 1.0
    size = (max(1, round(img.shape[1] * scale)), max(1, round(img.shape[0] * scale)))
    return cv2.resize(img, size, interpolation=cv2.INTER_AREA), scale


#: A swatch on a holder differs from the holder around it in texture or in colour (``swatch_score``'s
#: two cues): the simulated rig's ring of holder has 0.3-0.5 of a brown swatch's detail energy, and a
#: black swatch, as smooth as the holder (0.5-0.8 of its energy), differs from it by 90-110 codes of
#: colour. In an all-hair image (the layered swatch at 48-150 px, or Cycles' swatches, whose strands
#: read as noise to the coherence test) the "ring" around a blob of glints is the same hair: 1.0 of
#: its energy, 15 codes of colour.
HOLDER_RING_ENERGY = 0.6
HOLDER_RING_COLOUR = 30.0     # 8-bit codes (the norm of the medians' RGB difference)


def holder_around(img: np.ndarray, box: tuple[int, int, int, int]) -> bool:
    """Whether the region ``box`` (x, y, w, h) stands on a holder: a ring around it smoother than the
    region (median detail energy under ``HOLDER_RING_ENERGY`` of its own) or of another colour (medians
    ``HOLDER_RING_COLOUR`` codes apart)."""
    x, y, bw, bh = box
    h, w = img.shape[:2]
    pad = max(2, int(round(0.15 * min(bw, bh))))
    ring = np.zeros((h, w), bool)
    ring[max(0, y - pad):y + bh + pad, max(0, x - pad):x + bw + pad] = True
    ring[y:y + bh, x:x + bw] = False
    if not ring.any():
        return True
    energy = _detail_energy(img)
    inside = float(np.median(energy[y:y + bh, x:x + bw]))
    if float(np.median(energy[ring])) < HOLDER_RING_ENERGY * max(inside, 1e-6):
        return True
    pixels = img.reshape(-1, 3).astype(np.float32)
    inner = np.zeros((h, w), bool)
    inner[y:y + bh, x:x + bw] = True
    colour_gap = np.median(pixels[ring.ravel()], axis=0) - np.median(pixels[inner.ravel()], axis=0)
    return float(np.linalg.norm(colour_gap)) > HOLDER_RING_COLOUR


def _regions(mask: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Connected regions of the swatch mask (count, labels and ``cv2`` stats), after a small opening. A region
    touching the frame's edge is opened again with a disk of the score's blur width: the band where
    the holder meets what lies beyond it is that thin, and so is its bridge to a swatch beside it."""
    sh, sw = mask.shape
    kernel = np.ones((max(3, min(sh, sw) // 40) | 1,) * 2, np.uint8)
    opened = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(opened)
    edge = set(np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))) - {0}
    if not edge:
        return n, labels, stats
    radius = int(np.ceil(3.5 * max(1.5, min(sh, sw) / 50.0)))
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1,) * 2)
    touching = np.isin(labels, list(edge)).astype(np.uint8)
    opened[touching > 0] = cv2.morphologyEx(touching, cv2.MORPH_OPEN, disk)[touching > 0]
    n, labels, stats, _ = cv2.connectedComponentsWithStats(opened)
    return n, labels, stats


#: A region filling less of its bounding box than this (a swatch seen obliquely is a parallelogram or a
#: trapezium) is taken by the box inside it that it fills to ``INNER_FILL``: its bounding box holds holder.
TRIM_BELOW_FILL, INNER_FILL = 0.9, 0.97


def inner_box(region: np.ndarray, box: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """``box`` (x, y, w, h) around the boolean ``region``, its emptiest edge row or column cut away in
    turn until the region (its holes filled: a swatch's grey fibres read as holder) fills it to
    ``INNER_FILL``; unchanged when the region fills it to ``TRIM_BELOW_FILL`` already."""
    x, y, w, h = box
    contours, _ = cv2.findContours(region[y:y + h, x:x + w].astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_SIMPLE)
    inside = cv2.drawContours(np.zeros((h, w), np.uint8), contours, -1, 1, cv2.FILLED).astype(bool)
    if inside.mean() >= TRIM_BELOW_FILL:
        return box
    top, bottom, left, right = 0, h, 0, w
    while bottom - top > 2 and right - left > 2:
        part = inside[top:bottom, left:right]
        if part.mean() >= INNER_FILL:
            break
        edges = (part[0].mean(), part[-1].mean(), part[:, 0].mean(), part[:, -1].mean())
        k = int(np.argmin(edges))
        top, bottom, left, right = (top + (k == 0), bottom - (k == 1), left + (k == 2), right - (k == 3))
    return x + left, y + top, right - left, bottom - top


def find_swatch_roi(img: np.ndarray) -> Roi:
    """The bounding box of the largest filled region unlike the frame's border, the colour chart
    masked out; the whole image when no such region stands out, or when the border itself is hair
    (an image that is all hair: its grey fibres or lighter streaks are not a swatch on a holder).

    Large frames are searched scaled down to ``SEARCH_SIDE``; the ROI is in the frame's pixels.
    """
    return find_swatch(img)[0]


def region_outline(region: np.ndarray) -> np.ndarray | None:
    """The four corners (4, 2; x, y in pixels, in order around it) of a boolean region's outline, or
    None when its convex hull is not near a quadrilateral."""
    contours, _ = cv2.findContours(region.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    hull = cv2.convexHull(max(contours, key=cv2.contourArea))
    perimeter = cv2.arcLength(hull, True)
    for tolerance in np.linspace(0.01, 0.1, 19):
        corners = cv2.approxPolyDP(hull, tolerance * perimeter, True)
        if len(corners) <= 4:
            return corners.reshape(-1, 2).astype(float) if len(corners) == 4 else None
    return None


#: A region filling this share of its convex hull is a filled shape: a swatch seen obliquely is a
#: parallelogram filling half its bounding box (at 60° a rhombus), but all of its hull.
SOLIDITY = 0.9


def _hull_area(region: np.ndarray) -> float:
    """The area of a boolean region's convex hull, in pixels."""
    points = cv2.findNonZero(region.astype(np.uint8))
    return float(cv2.contourArea(cv2.convexHull(points))) + 1.0 if points is not None else 1.0


def find_swatch(img: np.ndarray) -> tuple[Roi, np.ndarray | None]:
    """:func:`find_swatch_roi`'s ROI, and the outline of the swatch found (its four corners in the
    frame's pixels: ``region_outline``), or None when the image is taken whole or has no such outline."""
    roi, outline, _ = _find(img)
    return roi, outline


@dataclass(frozen=True)
class _Found:
    """What :func:`_find` saw of a swatch found on its holder: the searched image (``_search_image``), its
    scale, the swatch's region there (boolean) and its box (x, y, w, h in the searched image's pixels)."""

    small: np.ndarray
    scale: float
    region: np.ndarray
    box: tuple[int, int, int, int]


def _find(img: np.ndarray) -> tuple[Roi, np.ndarray | None, _Found | None]:
    """:func:`find_swatch`'s ROI and outline, and what the search saw of the swatch (None: taken whole)."""
    h, w = img.shape[:2]
    small, scale = _search_image(img)
    sh, sw = small.shape[:2]
    whole = Roi(0, 0, w, h), None, None
    if border_is_hair(small):
        return whole
    score = swatch_score(small)
    mask = (score > 1.0).astype(np.uint8)
    n, labels, stats = _regions(mask)
    # masking only shrinks regions: when none is large enough to be a swatch, the chart does not matter
    chart = (chart_mask(small, margin=2 * max(1.5, min(sh, sw) / 50.0))
             if n > 1 and stats[1:, cv2.CC_STAT_AREA].max() >= 0.10 * sh * sw else None)
    if chart is not None:
        mask[chart > 0] = 0
        n, labels, stats = _regions(mask)
    # a swatch on its holder is a large, filled rectangle with holder on every side; streaks inside an
    # all-hair image are not, nor is a band across the whole frame (the lighter half of all-hair shading)
    def across(s) -> bool:
        return (s[0] <= 1 and s[0] + s[2] >= sw - 1) or (s[1] <= 1 and s[1] + s[3] >= sh - 1)

    def filled(i: int, s) -> bool:   # a filled rectangle, or a filled quadrilateral seen obliquely
        return s[4] >= 0.6 * s[2] * s[3] or s[4] >= SOLIDITY * _hull_area(labels == i)

    candidates = [(int(s[4]), i) for i, s in enumerate(stats) if i > 0 and s[4] >= 0.10 * sh * sw
                  and s[2] * s[3] <= 0.85 * sh * sw and not across(s) and filled(i, s)]
    if not candidates:
        return whole
    best = max(candidates)[1]
    x, y, bw, bh = inner_box(labels == best, tuple(int(v) for v in stats[best, :4]))
    if not holder_around(small, (x, y, bw, bh)):
        return whole   # like its surroundings in texture and colour: a patch of an all-hair image
    x0, y0 = int(np.floor(x / scale)), int(np.floor(y / scale))
    x1, y1 = min(w, int(np.ceil((x + bw) / scale))), min(h, int(np.ceil((y + bh) / scale)))
    if min(x1 - x0, y1 - y0) < MIN_SIDE:
        raise ImageError(f"the swatch area found is only {x1 - x0}x{y1 - y0} px (at least {MIN_SIDE} px a "
                         f"side is needed): move the camera closer, or pass its area with --roi x,y,w,h")
    # the outline at half the region's typical score: the blurred score's halo around a swatch of high
    # contrast (platinum's glints) would round it out
    region = labels == best
    outline = region_outline(region & (score > 0.5 * float(np.median(score[region]))))
    return (Roi(x0, y0, x1 - x0, y1 - y0), None if outline is None else (outline + 0.5) / scale - 0.5,
            _Found(small, scale, region, (x, y, bw, bh)))


#: The share of a found swatch's box cut from each side (x, y) before a rig region is estimated from it, where
#: its hair is not told apart (``find_swatch_core``; ``hair_core`` finds the hair's own box otherwise):
#: the box carries the score's blur halo (holder) and the swatch's edges, where fibres thin out (a spread,
#: loose or coarse swatch's sides, the binding). On RAW stills of the family's seven structures (copper, the
#: bench camera at twice the feed's resolution) the whole box's mean colour lay 1.5-3.4 ΔE2000 from the rig's
#: own region (inset 0.05 units from the swatch's edges), its core at most 0.25; at (0.10, 0.05), 0.62.
CORE_INSET = (0.15, 0.08)


def swatch_core(roi: Roi, size: tuple[int, int]) -> Roi:
    """The core of a swatch ``roi`` found on its holder in a frame of ``size`` (width, height): ``CORE_INSET``
    cut from each side. A ``roi`` that is the whole frame (an all-hair image) is all hair and kept whole."""
    if (roi.x, roi.y, roi.w, roi.h) == (0, 0, *size):
        return roi
    dx, dy = int(round(CORE_INSET[0] * roi.w)), int(round(CORE_INSET[1] * roi.h))
    if min(roi.w - 2 * dx, roi.h - 2 * dy) < MIN_SIDE:
        return roi
    return Roi(roi.x + dx, roi.y + dy, roi.w - 2 * dx, roi.h - 2 * dy)


def find_swatch_core(img: np.ndarray) -> tuple[Roi, np.ndarray | None]:
    """The area a rig region is estimated from, and the swatch's outline as :func:`find_swatch` found it.

    The area is the swatch's hair alone (:func:`hair_core`): the largest box of pixels like the swatch's
    interior, inside its edges. Where no such box is found, :func:`swatch_core` of :func:`find_swatch`'s box."""
    roi, outline, found = _find(img)
    core = hair_core(found) if found is not None else None
    return core if core is not None else swatch_core(roi, (img.shape[1], img.shape[0])), outline


#: The hair's own edge is judged at a blur of the searched frame's shorter side over ``HAIR_EDGE_BLUR`` (the
#: score's blur is its 50th part, whose halo of holder is what the found box holds beyond the hair).
HAIR_EDGE_BLUR = 150.0
#: A pixel is like the swatch's interior when its colour (at that blur) lies within ``HAIR_LIKE`` times the
#: interior's own 90th-percentile distance from the interior's median colour, and at least ``HAIR_LIKE_FLOOR``
#: 8-bit codes (RGB norm). The shadow a thick swatch casts on the holder is unlike both the holder (in the
#: found region) and the hair (here).
HAIR_LIKE, HAIR_LIKE_FLOOR = 2.0, 10.0
#: ... and not smoother than ``HAIR_ENERGY`` of the interior's median detail energy (a light swatch's shadow
#: is within its colour spread of it, but as smooth as the holder it falls on).
HAIR_ENERGY = 0.5
#: The share of the hair's box cut from each side (x, y): the swatch's edge fibres, lit and seen unlike its
#: interior (a spread swatch's thin sides, a thick swatch's side wall). At (0.12, 0.06) light swatches 5-20%
#: thick were estimated from their RAW stills 0.81-0.93 ΔE2000 off, at (0.06, 0.04) 0.65-0.80
#: (packaging/bench/finder-thick).
HAIR_MARGIN = (0.06, 0.04)
#: A hair box under this share of the found box's area is not trusted (the interior too varied to judge).
HAIR_LEAST_SHARE = 0.25


def hair_mask(found: _Found) -> np.ndarray:
    """Over ``found.box`` of the searched frame: the pixels of hair like the swatch's interior (boolean), its
    holes filled (grey fibres, glints), specks removed. The interior is the found region's deepest half
    (distance from its edge); a pixel is hair when it is unlike the holder (``swatch_score`` at the finer
    blur ``HAIR_EDGE_BLUR``), like the interior in colour (``HAIR_LIKE``) and not smoother (``HAIR_ENERGY``).
    What the found region holds besides hair is unlike it: the holder in its halo, a thick swatch's shadow
    on the holder, a binding across its end."""
    small, (x, y, w, h) = found.small, found.box
    sigma = max(1.0, min(small.shape[:2]) / HAIR_EDGE_BLUR)
    score, local, energy = (a[y:y + h, x:x + w] for a in _unlike_background(small, sigma))
    # depth: the distance from the region's edge, or the box's (the region may fill its box)
    depth = cv2.distanceTransform(np.pad(found.region[y:y + h, x:x + w], 1).astype(np.uint8), cv2.DIST_L2, 5)
    interior = depth[1:-1, 1:-1] >= 0.5 * depth.max()
    distance = np.linalg.norm(local - np.median(local[interior], axis=0), axis=2)
    tolerance = max(HAIR_LIKE * float(np.percentile(distance[interior], 90)), HAIR_LIKE_FLOOR)
    smooth = energy < HAIR_ENERGY * float(np.median(energy[interior]))
    hair = (distance <= tolerance) & ~smooth & (score > 1.0)
    hair = _filled(hair)
    side = int(2 * np.ceil(sigma) + 1)
    hair = cv2.morphologyEx(hair.astype(np.uint8), cv2.MORPH_OPEN, np.ones((side, side), np.uint8)) > 0
    return hair


def _filled(mask: np.ndarray) -> np.ndarray:
    """A boolean mask with its holes (what it encloses) filled."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return cv2.drawContours(np.zeros(mask.shape, np.uint8), contours, -1, 1, cv2.FILLED) > 0


def largest_box(mask: np.ndarray) -> tuple[int, int, int, int]:
    """The largest axis-aligned box (x, y, w, h) all inside the boolean ``mask``; (0, 0, 0, 0) when it is empty."""
    rows, cols = mask.shape
    heights = np.zeros(cols + 1, np.int64)     # a sentinel column of height 0 closes every run
    best, found = 0, (0, 0, 0, 0)
    for r in range(rows):
        heights[:cols] = np.where(mask[r], heights[:cols] + 1, 0)
        stack: list[int] = []
        for c in range(cols + 1):
            while stack and heights[stack[-1]] >= heights[c]:
                top = stack.pop()
                left = stack[-1] + 1 if stack else 0
                area = int(heights[top]) * (c - left)
                if area > best:
                    best, found = area, (left, r - int(heights[top]) + 1, c - left, int(heights[top]))
            stack.append(c)
    return found


def hair_core(found: _Found) -> Roi | None:
    """The region a rig still is estimated from: the largest box of hair (``hair_mask``, judged on a grid of
    at most 200 cells a side, a cell hair when all of it is) less ``HAIR_MARGIN``, in the frame's pixels; None
    when it is under ``HAIR_LEAST_SHARE`` of the found box or ``MIN_SIDE`` a side."""
    hair = hair_mask(found)
    h, w = hair.shape
    cell = max(1, int(np.ceil(max(h, w) / 200)))
    grid = hair[:h // cell * cell, :w // cell * cell].reshape(h // cell, cell, w // cell, cell).all(axis=(1, 3))
    gx, gy, gw, gh = (v * cell for v in largest_box(grid))
    if gw * gh < HAIR_LEAST_SHARE * h * w:
        return None
    dx, dy = HAIR_MARGIN[0] * gw, HAIR_MARGIN[1] * gh
    x0, y0 = (found.box[0] + gx + dx) / found.scale, (found.box[1] + gy + dy) / found.scale
    x1, y1 = (found.box[0] + gx + gw - dx) / found.scale, (found.box[1] + gy + gh - dy) / found.scale
    x0, y0, x1, y1 = int(np.ceil(x0)), int(np.ceil(y0)), int(np.floor(x1)), int(np.floor(y1))
    if min(x1 - x0, y1 - y0) < MIN_SIDE:
        return None
    return Roi(x0, y0, x1 - x0, y1 - y0)


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
    return crop_of(img, roi), roi


def crop_of(values: np.ndarray, roi: Roi) -> np.ndarray:
    """What :func:`swatch_crop` keeps of ``values`` (an image, or a per-pixel mask of its size) in ``roi``."""
    full = roi.w == values.shape[1] and roi.h == values.shape[0]
    return central_square(roi.clip(values), 1.0 if full else ROI_CENTRAL)


def encode(img: np.ndarray, size: int) -> np.ndarray:
    """Resize an image (8-bit sRGB or linear float) to ``size``² in linear light and encode it for the net.

    The area filter averages linear radiance, as a camera with fewer pixels would: the input's
    mean colour is then the same whatever the source's resolution (averaging sRGB codes would
    darken textured hair more the larger the source). Returns float32 (3, size, size): sRGB
    values (unquantised) in [-0.5, 0.5].
    """
    linear = reduced_linear(img)
    if linear.shape[0] != size or linear.shape[1] != size:
        linear = cv2.resize(linear, (size, size), interpolation=cv2.INTER_AREA)
    return (linear_to_srgb(linear) - np.float32(0.5)).transpose(2, 0, 1).copy()


#: Pixels an image is reduced to, in linear light, before anything else works on it whole (encode,
#: domain checks): 4 MP of float32 RGB is 48 MB, whatever the source's size.
MAX_WORK_PIXELS = 1 << 22
_BAND_PIXELS = 1 << 20   # source pixels converted to float at once


def reduced_linear(img: np.ndarray, max_pixels: int = MAX_WORK_PIXELS) -> np.ndarray:
    """Linear float32 RGB of ``img``; above ``max_pixels``, block means (k x k, in linear light, band by
    band) so that memory stays bounded whatever the image's size (the area filter then finishes)."""
    h, w = img.shape[:2]
    k = int(np.ceil(np.sqrt(h * w / max_pixels)))
    if k <= 1:
        return to_linear(img)
    rows, cols = h // k, w // k
    out = np.empty((rows, cols, 3), np.float32)
    band = max(1, _BAND_PIXELS // (k * k * cols))
    for r in range(0, rows, band):
        r1 = min(rows, r + band)
        block = to_linear(img[r * k:r1 * k, :cols * k]).reshape(r1 - r, k, cols, k, 3)
        out[r:r1] = block.mean(axis=(1, 3), dtype=np.float32)
    return out
