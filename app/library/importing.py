"""Session folders and record files into the library: one transaction per session (all or nothing)."""
from __future__ import annotations

import hashlib
import json
import os
import stat
from pathlib import Path

import numpy as np

from hairdigi.app.library.store import Library, LibraryError, SwatchRecord, SwatchRow
from hairdigi.app.library.swatch_colour import INSTRUMENT, swatch_labs
from hairdigi.render.domain.files import stream_sha256
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import EstimateRecord, read_record, read_session_capture, record_sha256
from hairdigi.render.domain.session_folder import SessionFolder, capture_id_of

FIRST_RUN_KEY = "first_run_import"


def _short(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _sigma(record: EstimateRecord | None) -> tuple[float, float, float] | None:
    return None if record is None else record.sigma_a


def _spectral_hair(row: SwatchRow) -> HairParams | None:
    """The Table 1 hair whose spectrum gives a row's studio colour: a declared rig's camera answer
    (``record.spectral``) where the record has one, else its parameters."""
    estimate = row.record.estimate
    return estimate.spectral.hair if estimate is not None and estimate.spectral is not None else row.hair


def _instrument_labs(row: SwatchRow) -> dict[str, tuple[float, float, float]]:
    """A row's instrument readings in D65/10° (the record's ``instrument`` block), by geometry."""
    readings = () if row.record.estimate is None else row.record.estimate.instrument
    return {r.geometry: tuple(float(v) for v in r.lab) for r in readings
            if r.geometry in INSTRUMENT and r.illuminant == "D65" and r.observer == "10"}


def _with_colours(rows: list[SwatchRow]) -> list[SwatchRow]:
    """Fill every row's CIELAB under each light from its ``sigma_a`` (the studio light's change from its
    Table 1 hair's spectrum, where it has one), all at once; and its instrument readings, where its record has them."""
    coloured = [r for r in rows if r.sigma_a is not None]
    if coloured:
        labs = swatch_labs(np.array([r.sigma_a for r in coloured]), [_spectral_hair(r) for r in coloured])
        for i, r in enumerate(coloured):
            r.labs = {ill: tuple(float(v) for v in lab[i]) for ill, lab in labs.items()}
    for r in rows:
        r.labs.update(_instrument_labs(r))
    return rows


#: The largest capture image hashed at import (a RAW still is tens of MB; a file this large is no capture).
MAX_IMAGE_BYTES = 1 << 30


def checked_image(session: SessionFolder, name: str, claimed: str, record: Path) -> tuple[Path, str]:
    """A capture's image and its sha256, recomputed: the image must lie inside its session folder, be a
    regular file, and hash to what its record claims (when it claims one). A record that lies (an image
    elsewhere, missing, or another's hash: it would take over that capture's swatch) raises
    :class:`LibraryError` naming the record, before anything is written."""
    root, path = session.root.resolve(), session.image(name)
    shown = repr(str(name)[:120])
    try:
        real = path.resolve()
    except (OSError, RuntimeError):
        real = None
    if real is None or Path(name).is_absolute() or (real != root and root not in real.parents):
        raise LibraryError(f"{record}: its image {shown} lies outside the session folder {root}; the record is not "
                           f"the one the rig wrote: fix or remove that capture's records, then import again")
    if not real.exists():
        raise LibraryError(f"{record}: no image {shown} in {session.captures} (moved or deleted?); put the image "
                           f"back or remove that capture's records, then import again")
    digest = _sha256_of(real, record, shown)
    if claimed and digest != str(claimed).lower():
        raise LibraryError(f"{record}: its image_sha256 does not match its image {shown} (the image or the record "
                           f"was changed after the capture); restore them or remove that capture's records, "
                           f"then import again")
    return path, digest


def _sha256_of(path: Path, record: Path, shown: str) -> str:
    """The sha256 of a regular file of at most ``MAX_IMAGE_BYTES``, read in chunks (a device, a FIFO or a
    folder is refused before a byte is read)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        raise LibraryError(f"{record}: its image {shown} cannot be read ({exc.strerror or exc}); make it "
                           f"readable, then import again") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise LibraryError(f"{record}: its image {shown} is not a regular file (a folder, device or pipe); "
                               f"put the capture's image back, then import again")
        if info.st_size > MAX_IMAGE_BYTES:
            raise LibraryError(f"{record}: its image {shown} is {info.st_size / 1e9:.1f} GB, larger than any "
                               f"capture ({MAX_IMAGE_BYTES / 1e9:.1f} GB); remove that capture, then import again")
        with os.fdopen(fd, "rb", closefd=False) as f:
            return stream_sha256(f)
    except OSError as exc:
        raise LibraryError(f"{record}: its image {shown} cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)


def capture_rows(folder: str | Path) -> list[SwatchRow]:
    """One row per capture of a session folder (``captures/<id>.json`` and its ``.result.json``), each
    capture's image checked (:func:`checked_image`); its swatch's id is its image's recomputed hash."""
    folder = Path(folder).resolve()
    session = SessionFolder(folder)
    if not session.is_session():
        raise LibraryError(f"{folder}: not a session folder (no captures/ in it)")
    rows = []
    for meta_path in session.capture_records():
        capture_id = capture_id_of(meta_path)
        read = read_session_capture(session, capture_id)
        if read.problems:
            raise LibraryError(read.problems[0])
        capture, estimate, result_path = read.capture, read.result, session.result_record(capture_id)
        image, identity = checked_image(session, capture.image, capture.image_sha256, meta_path)
        rows.append(SwatchRow(
            id="c" + _short(identity)[:15], kind="capture", session=str(folder), capture_id=capture_id,
            captured=capture.captured or None, image_path=str(image),
            record_path=str(result_path if estimate is not None else meta_path),
            record_sha256=record_sha256(result_path) if estimate is not None else None,
            reliable=bool(estimate and estimate.reliable),
            hair=None if estimate is None else estimate.hair, sigma_a=_sigma(estimate),
            record=SwatchRecord(capture=capture, estimate=estimate)))
    return _with_colours(rows)


def record_row(path: str | Path) -> SwatchRow:
    """A lone estimate record (``hairdigi estimate --out``) or a dye prediction."""
    path = Path(path).resolve()
    try:
        record = read_record(path, EstimateRecord)
    except RecordError as exc:
        raise LibraryError(str(exc)) from None
    kind = "dye" if record.provenance.prediction else "estimate"   # hairdigi dye apply --out
    sha = record_sha256(path)
    when = record.provenance.time
    row = SwatchRow(id=("d" if kind == "dye" else "e") + sha[:15], kind=kind, captured=str(when) if when else None,
                    record_path=str(path), record_sha256=sha, reliable=record.reliable,
                    hair=record.hair, sigma_a=_sigma(record), record=SwatchRecord(estimate=record))
    return _with_colours([row])[0]


def import_paths(library: Library, paths: list[str | Path], progress=print) -> int:
    """Import session folders (one transaction each) and record files; the swatches written. Every path is
    read and checked before the first is written: one that cannot be imported leaves the library as it was."""
    batches = []
    for path in paths:
        path = Path(path)
        if path.is_dir():
            batches.append((capture_rows(path), str(path.resolve())))
        elif path.is_file():
            batches.append(([record_row(path)], None))
        else:
            raise LibraryError(f"{path}: no such session folder or record file")
    total = 0
    for rows, session in batches:
        if session is not None:
            progress(f"writing {len(rows)} captures of {session}")
        total += library.add(rows, session=session)
    return total


def first_run_sessions() -> list[Path]:
    """Session folders written before the library: ``HAIRDIGI_SESSIONS`` (folders, ``os.pathsep``-separated;
    each a session or a folder of sessions), else the app's default ``~/hairdigi-sessions``."""
    roots = os.environ.get("HAIRDIGI_SESSIONS")
    candidates = [Path(p) for p in roots.split(os.pathsep) if p] if roots is not None \
        else [Path.home() / "hairdigi-sessions"]
    found = []
    for root in candidates:
        if SessionFolder(root).is_session():
            found.append(root)
        elif root.is_dir():
            found += sorted(p for p in root.iterdir() if SessionFolder(p).is_session())
    return found


def first_run(library: Library, progress=print) -> int:
    """On a library's first open: import the sessions written before it; once (remembered in the library).

    A session that cannot be imported (a corrupt capture) is skipped with one line naming it and the
    fix; the others are imported, and the first run is not tried again, so one damaged old session
    never locks every command out."""
    if library.setting(FIRST_RUN_KEY) is not None:
        return 0
    total, done, skipped = 0, [], []
    for session in first_run_sessions():
        try:
            total += import_paths(library, [session], progress)
            done.append(str(session))
        except (LibraryError, RecordError, OSError, ValueError) as exc:
            reason = " ".join(str(exc).split())[:300]
            skipped.append({"session": str(session), "reason": reason})
            progress(f"skipped the old session {session} in the first import: {reason}; fix or move that capture, "
                     f"then hairdigi library import {session}")
    library.set_setting(FIRST_RUN_KEY, json.dumps({"sessions": done, "skipped": skipped, "swatches": total}))
    return total
