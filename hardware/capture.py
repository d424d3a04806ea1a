"""Saving captures: the untouched frame (or RAW file) first, then its metadata, both atomically."""
from __future__ import annotations

import io
import json
import os
import shutil
import time
from pathlib import Path

import cv2
import numpy as np

from hairdigi.hardware.bayer import write_dng
from hairdigi.render.domain.files import atomic_path, file_sha256
from hairdigi.render.domain.records import CaptureRecord


def _atomic_bytes(path: Path, data: bytes) -> None:
    """A capture is the operator's work: flushed to the disk before it is published."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())


_last_capture_ms = [0]


def _id_at(ms: int) -> str:
    """The capture id ``YYYYmmdd-HHMMSS-mmm`` of a time in milliseconds."""
    seconds, milli = divmod(ms, 1000)
    return time.strftime("%Y%m%d-%H%M%S", time.localtime(seconds)) + f"-{milli:03d}"


def new_capture_id(now: float | None = None) -> str:
    """``YYYYmmdd-HHMMSS-mmm`` of ``now``; never the same twice in a process (a second capture in the same
    millisecond takes the next one). Across processes, :func:`reserve_capture_id` makes it unique in a folder."""
    t = time.time() if now is None else now
    ms = max(int(t * 1000), _last_capture_ms[0] + 1) if now is None else int(t * 1000)
    _last_capture_ms[0] = max(_last_capture_ms[0], ms)
    return _id_at(ms)


#: How many ids after the clock's a capture tries before it gives up (one a millisecond: a second).
ID_TRIES = 1000


def _reservation(folder: Path, capture_id: str) -> Path:
    """The hidden file whose exclusive creation holds a capture id while its files are written."""
    return folder / f".{capture_id}.taken"


def reserve_capture_id(folder: Path) -> str:
    """A capture id no other capture in ``folder`` has or is taking, in this process or another: the clock's
    id, or the next free millisecond. Held by creating ``.<id>.taken`` exclusively (``O_EXCL``; one process
    wins) and checking that no finished capture has it; :func:`save_capture` removes the file once the
    capture record is written (from then on the record holds the id)."""
    t = time.time()
    ms = max(int(t * 1000), _last_capture_ms[0] + 1)
    for _ in range(ID_TRIES):
        capture_id = _id_at(ms)
        try:
            os.close(os.open(_reservation(folder, capture_id), os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        except FileExistsError:
            ms += 1
            continue
        if any(folder.glob(f"{capture_id}.*")) or any(folder.glob(f"{capture_id}-*")):   # a finished capture's
            _reservation(folder, capture_id).unlink(missing_ok=True)
            ms += 1
            continue
        _last_capture_ms[0] = max(_last_capture_ms[0], ms)
        return capture_id
    raise FileExistsError(f"{folder}: no free capture id in the {ID_TRIES} ms after {_id_at(int(t * 1000))} "
                          "(hidden .<id>.taken files left by a crash?); remove them, or use another session")


def _write_png(path: Path, srgb: np.ndarray) -> None:
    ok, png = cv2.imencode(".png", cv2.cvtColor(srgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise OSError(f"could not encode {path.name} as PNG")
    _atomic_bytes(path, png.tobytes())


def _write_dng(path: Path, mosaic: np.ndarray, bayer: dict) -> None:
    """A raw Bayer frame as it came from the sensor, as a DNG that ``read_raw`` decodes."""
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
    reserved = capture_id is None
    capture_id = capture_id or reserve_capture_id(folder)
    written: list[Path] = []
    try:
        return _save(folder, capture_id, srgb, raw_path, light_frames, mosaic, written, fields)
    except BaseException:
        for path in written:   # a capture half written is no capture: nothing of it is left
            path.unlink(missing_ok=True)
        raise
    finally:
        if reserved:
            _reservation(folder, capture_id).unlink(missing_ok=True)


def _save(folder: Path, capture_id: str, srgb, raw_path, light_frames, mosaic, written: list[Path],
          fields: dict) -> tuple[Path, Path, CaptureRecord]:
    """``save_capture``'s writing, each file listed in ``written`` as it is begun."""
    names = []
    for i, frame in enumerate(light_frames):
        names.append(f"{capture_id}-light{i}.png")
        _write_png(folder / names[-1], frame)
        written.append(folder / names[-1])
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
    written.append(image_path)
    digest = file_sha256(image_path)
    if fields.get("swatch_roi") is not None:
        fields["swatch_roi"] = tuple(int(v) for v in fields["swatch_roi"])
    record = CaptureRecord(id=capture_id, image=image_path.name, image_sha256=digest,
                           captured=time.strftime("%Y-%m-%dT%H:%M:%S%z"), **fields)
    meta_path = folder / f"{capture_id}.json"
    _atomic_bytes(meta_path, (json.dumps(record.to_json(), indent=2, default=str) + "\n").encode())
    return image_path, meta_path, record

