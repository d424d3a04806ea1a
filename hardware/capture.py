"""Saving captures: the untouched frame (or RAW file) first, then its metadata, both atomically."""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
from pathlib import Path

import cv2
import numpy as np

from hairdigi.render.domain.files import atomic_path
from hairdigi.render.domain.records import CaptureRecord


def _atomic_bytes(path: Path, data: bytes) -> None:
    """A capture is the operator's work: flushed to the disk before it is published."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())


_last_capture_ms = [0]


def new_capture_id(now: float | None = None) -> str:
    """``YYYYmmdd-HHMMSS-mmm`` of ``now``; never the same twice in a process (a second capture in the same
    millisecond takes the next one), so a capture never replaces another."""
    t = time.time() if now is None else now
    ms = max(int(t * 1000), _last_capture_ms[0] + 1) if now is None else int(t * 1000)
    _last_capture_ms[0] = max(_last_capture_ms[0], ms)
    seconds, milli = divmod(ms, 1000)
    return time.strftime("%Y%m%d-%H%M%S", time.localtime(seconds)) + f"-{milli:03d}"


def _write_png(path: Path, srgb: np.ndarray) -> None:
    ok, png = cv2.imencode(".png", cv2.cvtColor(srgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise OSError(f"could not encode {path.name} as PNG")
    _atomic_bytes(path, png.tobytes())


def _write_dng(path: Path, mosaic: np.ndarray, bayer: dict) -> None:
    """A raw Bayer frame as it came from the sensor, as a DNG that ``read_raw`` decodes."""
    import io

    from hairdigi.hardware.bayer import write_dng

    data = io.BytesIO()
    write_dng(data, mosaic, bayer["layout"], bayer["black"], bayer["white"], bayer.get("model", "hairdigi GenICam camera"))
    _atomic_bytes(path, data.getvalue())


def save_capture(folder: str | os.PathLike, srgb: np.ndarray | None = None, raw_path: str | os.PathLike | None = None,
                 capture_id: str | None = None, light_frames: tuple | list = (),
                 mosaic: tuple[np.ndarray, dict] | None = None, **fields) -> tuple[Path, Path, CaptureRecord]:
    """Write ``<id>.png`` (lossless, as captured), a copy of the RAW file, or ``<id>.dng`` of a raw Bayer
    frame (``mosaic``: its counts and ``{layout, black, white}``), each light's own frame
    ``<id>-light<i>.png`` (``light_frames``, light order), then the capture record ``<id>.json``
    (``fields`` are ``CaptureRecord``'s). Nothing is processed before all are on disk.

    Returns (image path, record path, record).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    capture_id = capture_id or new_capture_id()
    names = []
    for i, frame in enumerate(light_frames):
        names.append(f"{capture_id}-light{i}.png")
        _write_png(folder / names[-1], frame)
    if names:
        fields["light_images"] = tuple(names)
    if raw_path is not None:
        raw_path = Path(raw_path)
        image_path = folder / f"{capture_id}{raw_path.suffix.lower()}"
        with atomic_path(image_path) as tmp:
            shutil.copyfile(raw_path, tmp)
    elif mosaic is not None:
        image_path = folder / f"{capture_id}.dng"
        _write_dng(image_path, *mosaic)
    elif srgb is not None:
        image_path = folder / f"{capture_id}.png"
        _write_png(image_path, srgb)
    else:
        raise ValueError("a capture needs a frame or a RAW file")
    digest = hashlib.sha256(image_path.read_bytes()).hexdigest()
    if fields.get("swatch_roi") is not None:
        fields["swatch_roi"] = tuple(int(v) for v in fields["swatch_roi"])
    record = CaptureRecord(id=capture_id, image=image_path.name, image_sha256=digest,
                           captured=time.strftime("%Y-%m-%dT%H:%M:%S%z"), **fields)
    meta_path = folder / f"{capture_id}.json"
    _atomic_bytes(meta_path, (json.dumps(record.to_json(), indent=2, default=str) + "\n").encode())
    return image_path, meta_path, record
