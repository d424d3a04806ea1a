"""Files, written atomically: every writer goes through :func:`atomic_path`, which hands out a
temporary path beside the target and renames it over the target only when the write succeeded, so
no reader ever sees half a file and a failed write leaves the old file in place."""
from __future__ import annotations

import csv
import errno
import hashlib
import importlib.util
import json
import os
import re
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.session_folder import SessionFolder


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def publish(tmp: str | os.PathLike, path: str | os.PathLike) -> Path:
    """Give ``tmp`` the permissions a normally created file would have, then rename it to ``path``.

    ``tempfile.mkstemp`` creates files readable by their owner only; captures, exports and models
    must stay readable by the rest of the lab.
    """
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, path)
    return Path(path)


def _temp_suffix(path: Path, suffix: str | None) -> str:
    """The temporary file's suffix: the target's extension (writers choose the format by it), kept short."""
    ext = suffix or path.suffix or ".tmp"
    return ext if len(ext) <= 16 else ".tmp"


def _refuse_read_only(path: Path) -> None:
    """An existing target with no write permission bit was made read-only on purpose: never replace it."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return
    if path.is_file() and not mode & 0o222:
        raise PermissionError(errno.EACCES, "the file is read-only (no write permission); make it writable "
                              "(chmod u+w) or choose another name", str(path))


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; published as ``path`` when the block succeeds.

    ``suffix`` (default: ``path``'s) matters to writers that choose the format by extension
    (``cv2.imwrite``, ``np.savez``). The temporary name is short (``.hd-XXXXXXXX.ext``), so any
    name the file system takes can be written; a read-only target is refused before the work."""
    with atomic_paths(path, suffixes=(suffix,)) as (tmp,):
        yield tmp


@contextmanager
def atomic_paths(*paths: str | os.PathLike | None, suffixes: tuple = ()) -> Iterator[tuple]:
    """Temporary paths beside each of ``paths`` (None stays None); all are published together when the
    block succeeds, none when it fails (a disk filling on the second file leaves the first untouched)."""
    targets = [None if p is None else Path(p) for p in paths]
    temps: list[Path | None] = []
    try:
        for i, path in enumerate(targets):
            if path is None:
                temps.append(None)
                continue
            _refuse_read_only(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            suffix = suffixes[i] if i < len(suffixes) else None
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".hd-", suffix=_temp_suffix(path, suffix))
            os.close(fd)
            temps.append(Path(tmp))
        try:
            yield tuple(temps)
            for tmp, path in zip(temps, targets):
                if tmp is not None:
                    publish(tmp, path)
        except Exception as exc:
            _name_targets(exc, temps, targets)
            raise
    finally:
        for tmp in temps:
            if tmp is not None:
                tmp.unlink(missing_ok=True)


def _name_targets(exc: Exception, temps: list, targets: list) -> None:
    """An error while writing names the file asked for, never the temporary one it was written to."""
    pairs = [(str(t), str(p)) for t, p in zip(temps, targets) if t is not None]

    def fix(value):
        if isinstance(value, (str, os.PathLike)):
            text = os.fspath(value)
            for tmp, path in pairs:
                text = text.replace(tmp, path).replace(Path(tmp).name, Path(path).name)
            return text
        return value

    if isinstance(exc, OSError):
        for attr in ("filename", "filename2"):
            if getattr(exc, attr, None) is not None:
                setattr(exc, attr, fix(getattr(exc, attr)))
    try:
        exc.args = tuple(fix(a) for a in exc.args)
    except (AttributeError, TypeError):
        pass


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_json_atomic(path: str | os.PathLike, data: Any) -> Path:
    """JSON, indented, with a final newline."""
    return write_text_atomic(path, json.dumps(data, indent=2) + "\n")


def write_csv_atomic(path: str | os.PathLike, rows: list[dict]) -> Path:
    """Rows as CSV: the header is every key in the order first met (a row without one leaves it empty:
    a failed case's row holds its error, not the figures)."""
    fields = list(dict.fromkeys(key for row in rows for key in row))
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    return Path(path)


#: A parameter file, calibration profile or manifest is a few kB; anything this large is the wrong file.
MAX_JSON_BYTES = 16 * 1024 * 1024


def read_bytes(path: str | os.PathLike, error: type[Exception], what: str, max_bytes: int,
               too_large: str, missing: str = "no such file") -> bytes:
    """A regular file's bytes, at most ``max_bytes``; every way reading fails raises ``error`` naming the
    path and the fix.

    ``what`` names the expected file ("a JSON file"); ``too_large`` is the fix for a file over
    ``max_bytes``, which is refused before it is read. A device (``/dev/zero``), a FIFO or a socket is
    refused before a byte is read: it is opened without blocking and checked on the open descriptor, and
    never more than ``max_bytes`` + 1 bytes are read (a file that grows while read is refused too)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise error(f"{path}: {missing}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, not {what}; give the file's path") from None
    except PermissionError:
        raise error(f"{path}: permission denied; make it readable (chmod +r) or use a copy") from None
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or exc})") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise error(f"{path}: is a folder, not {what}; give the file's path")
        if not stat.S_ISREG(info.st_mode):
            raise error(f"{path}: is not a regular file (a device, pipe or socket), not {what}; give a file")
        if info.st_size > max_bytes:
            raise error(f"{path}: {info.st_size / 1e6:.0f} MB is too large for {what} (at most "
                        f"{max_bytes / 1e6:.0f} MB); {too_large}")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(max_bytes + 1)
        if len(data) > max_bytes:
            raise error(f"{path}: grew past {max_bytes / 1e6:.0f} MB while read, too large for {what}; "
                        f"{too_large}")
        return data
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)


def sha256_file(path: str | os.PathLike, error: type[Exception] = ValueError, max_bytes: int = 16 * 1024 * 1024) -> str:
    """The sha256 of a regular file of at most ``max_bytes`` (read as :func:`read_bytes` reads)."""
    return hashlib.sha256(read_bytes(path, error, "a file", max_bytes, "check the file name")).hexdigest()


def read_json(path: str | os.PathLike, error: type[Exception], missing: str, invalid: str):
    """Parse a JSON file; a missing or malformed file raises ``error`` with ``path: missing`` or
    ``path: invalid`` (``{exc}`` in ``invalid`` is replaced by the parser's message)."""
    data = read_bytes(path, error, "a JSON file", MAX_JSON_BYTES, "check the file name", missing)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise error(f"{path}: {invalid.format(exc='not UTF-8 text')}") from None
    try:
        return json.loads(text, object_pairs_hook=_unique_keys)
    except _DuplicateKey as exc:
        raise error(f"{path}: {invalid.format(exc=f'the key {exc.args[0]!r} appears twice')}") from None
    except json.JSONDecodeError as exc:
        raise error(f"{path}: {invalid.format(exc=exc)}") from None
    except RecursionError:
        raise error(f"{path}: {invalid.format(exc='nested too deeply')}") from None
    except ValueError as exc:   # a number with more digits than Python converts (over 4300)
        raise error(f"{path}: {invalid.format(exc=' '.join(str(exc).split())[:120])}") from None


class _DuplicateKey(ValueError):
    """A JSON object names one key twice: which value was meant is unknown."""


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """``json.loads``'s object hook: an object, refusing a key given twice (JSON would keep the last)."""
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


# --- files hairdigi itself reads: never overwritten by a command's output ---------------------
#: The package's folders (as installed: a checkout's source folders in an editable install).
PACKAGE_PARTS = ("app", "render", "hardware", "inference", "resources")
#: In a checkout, beside the package's folders: what the tests and docs read.
CHECKOUT_PARTS = ("tests",)
CHECKOUT_FILES = ("pyproject.toml", "README.md", "Makefile", "setup.py", "setup.cfg")
#: The ``kind`` of each record hairdigi writes and reads back, as a refusal names it.
_RECORD_KINDS = {"calibration": "a session's calibration profile", "capture": "a capture's record",
                 "estimate": "an estimate record", "dye": "a dye record"}
#: The most a record is read to be recognised (a larger file is no record hairdigi wrote).
_RECORD_SNIFF_BYTES = 4 << 20


class ProtectedFileError(HairdigiError, ValueError):
    """A command would write over a file it did not make and hairdigi reads back; the message names it."""


def package_folders() -> list[Path]:
    """The folders the installed hairdigi package is made of."""
    found = []
    for part in PACKAGE_PARTS:
        try:
            spec = importlib.util.find_spec(f"hairdigi.{part}")
        except (ImportError, ValueError):
            spec = None
        for location in (spec.submodule_search_locations or []) if spec else []:
            found.append(Path(location).resolve())
    return found


def _checkout_protected(folders: list[Path]) -> tuple[list[Path], list[Path]]:
    """A checkout's protected folders and files: beside the package's folders, under a pyproject.toml."""
    roots = {f.parent for f in folders if (f.parent / "pyproject.toml").is_file()}
    return ([r / part for r in roots for part in CHECKOUT_PARTS],
            [r / name for r in roots for name in CHECKOUT_FILES])


def _within(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def _record_kind(path: Path) -> str | None:
    """What hairdigi record an existing file is, whatever its extension: a calibration profile, a capture's
    record, an estimate record (a result, a dye prediction), a dye record, a dataset's manifest; else None."""
    try:
        if not path.is_file() or path.stat().st_size > _RECORD_SNIFF_BYTES:
            return None
        with open(path, "rb") as f:
            head = f.read(64).lstrip()
            if not head.startswith(b"{"):
                return None
            data = json.loads(head + f.read(_RECORD_SNIFF_BYTES))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(data, dict):
        return None
    kind = data.get("kind")
    if isinstance(kind, str) and kind in _RECORD_KINDS:
        return _RECORD_KINDS[kind]
    if "matrix" in data and "method" in data:
        return _RECORD_KINDS["calibration"]
    if "image_sha256" in data and "image" in data:
        return _RECORD_KINDS["capture"]
    if isinstance(data.get("config"), dict) and "format" in data:
        return "a dataset's manifest"
    if isinstance(data.get("hair"), dict) and ("provenance" in data or "refinement" in data):
        return _RECORD_KINDS["estimate"]      # the first layout, before records had a kind
    return None


def _is_sqlite(path: Path) -> bool:
    """Whether an existing regular file is a SQLite database (its 16-byte header), or its WAL or journal."""
    if path.name.endswith(("-wal", "-shm", "-journal")) and _is_sqlite(path.with_name(path.name.rsplit("-", 1)[0])):
        return True
    try:
        if not path.is_file():
            return False
        with open(path, "rb") as f:
            return f.read(16) == b"SQLite format 3\x00"
    except OSError:
        return False


def protected_reason(path: str | os.PathLike, allow: tuple = ()) -> str | None:
    """Why ``path`` must not be written over: it belongs to a rig session (its calibration, its
    captures), a dataset (manifest, shards) or the hairdigi package (its folders, a checkout's tests
    and top files), or it is, whatever its name, a record hairdigi reads back (a calibration, a capture's
    or an estimate record, a dye), a SQLite database (a swatch library) or a dataset's manifest; None
    when it may be written. ``allow`` lists folders where the package's files may be replaced
    (``export-onnx`` and ``model-card`` write the shipped model and its card).

    The one guard of every file a command writes: the command line's output checks
    (``app.cli.validation.check_output_file``) and :func:`refuse_protected` both ask it."""
    given = Path(path).absolute()
    try:
        real = Path(path).resolve()
    except (OSError, RuntimeError):
        real = given
    for p in dict.fromkeys((given, real)):
        parent = p.parent
        if SessionFolder.of_captures(parent) is not None:
            return f"is part of the rig session {parent.parent} (its captures)"
        if p == SessionFolder(parent).calibration and (p.exists() or SessionFolder(parent).holds_records()):
            return f"is the calibration of the rig session {parent}"
        if (parent / "manifest.json").is_file() and (p.name == "manifest.json" or re.match(r"shard-\d+\.npz$", p.name)):
            return f"is part of the dataset {parent}"
        folders = package_folders()
        extra_folders, extra_files = _checkout_protected(folders)
        if any(_within(p, f) for f in folders + extra_folders) and not any(_within(p, Path(a).resolve()) for a in allow):
            return "is part of the hairdigi package (its code, tests or resources)"
        if p in extra_files:
            return "is part of the hairdigi checkout"
    if _is_sqlite(real):
        return "is a SQLite database (a swatch library?)"
    kind = _record_kind(real)
    if kind:
        return f"is {kind}, which hairdigi reads back"
    return None


def refuse_protected(paths, allow: tuple = ()) -> None:
    """Refuse, before anything is written, when any of ``paths`` (a command's every output) is a file that
    :func:`protected_reason` keeps; :class:`ProtectedFileError` names the file and the fix."""
    for path in paths:
        if path is None:
            continue
        reason = protected_reason(path, allow)
        if reason:
            raise ProtectedFileError(f"{os.fspath(path)} {reason}; writing over it is refused: choose another "
                                     f"output name")


def cache_dir() -> Path:
    """Where hairdigi keeps what it can make again (datasets, response curves): ``HAIRDIGI_CACHE``."""
    return Path(os.environ.get("HAIRDIGI_CACHE", Path.home() / ".cache" / "hairdigi"))


def stream_sha256(f) -> str:
    """The SHA-256 of what a binary file object holds from where it stands, read in 1 MiB pieces (a RAW
    still or a capture image is never held whole for its hash)."""
    digest = hashlib.sha256()
    for piece in iter(lambda: f.read(1 << 20), b""):
        digest.update(piece)
    return digest.hexdigest()


def file_sha256(path: str | os.PathLike) -> str:
    """A file's SHA-256 (:func:`stream_sha256`)."""
    with open(path, "rb") as f:
        return stream_sha256(f)
