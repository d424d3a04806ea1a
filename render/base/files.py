"""Files, written atomically: every writer goes through :func:`atomic_path`, which hands out a
temporary path beside the target and renames it over the target only when the write succeeded, so
no reader ever sees half a file and a failed write leaves the old file in place."""
from __future__ import annotations

import csv
import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator


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


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; published as ``path`` when the block succeeds.

    ``suffix`` (default: ``path``'s) matters to writers that choose the format by extension
    (``cv2.imwrite``, ``np.savez``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=suffix or path.suffix or ".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        publish(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)


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
    """Rows of one shape as CSV, the first row's keys as the header."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return Path(path)


#: A parameter file, calibration profile or manifest is a few kB; anything this large is the wrong file.
MAX_JSON_BYTES = 16 * 1024 * 1024


def read_bytes(path: str | os.PathLike, error: type[Exception], what: str, max_bytes: int,
               too_large: str, missing: str = "no such file") -> bytes:
    """A file's bytes; every way reading fails raises ``error`` naming the path and the fix.

    ``what`` names the expected file ("a JSON file"); ``too_large`` is the fix for a file over
    ``max_bytes``, which is refused before it is read."""
    path = Path(path)
    try:
        if path.is_dir():
            raise error(f"{path}: is a folder, not {what}; give the file's path")
        size = path.stat().st_size
        if size > max_bytes:
            raise error(f"{path}: {size / 1e6:.0f} MB is too large for {what} (at most "
                        f"{max_bytes / 1e6:.0f} MB); {too_large}")
        return path.read_bytes()
    except FileNotFoundError:
        raise error(f"{path}: {missing}") from None
    except PermissionError:
        raise error(f"{path}: permission denied; make it readable (chmod +r) or use a copy") from None
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or exc})") from None


def read_json(path: str | os.PathLike, error: type[Exception], missing: str, invalid: str):
    """Parse a JSON file; a missing or malformed file raises ``error`` with ``path: missing`` or
    ``path: invalid`` (``{exc}`` in ``invalid`` is replaced by the parser's message)."""
    data = read_bytes(path, error, "a JSON file", MAX_JSON_BYTES, "check the file name", missing)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise error(f"{path}: {invalid.format(exc='not UTF-8 text')}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: {invalid.format(exc=exc)}") from None
    except RecursionError:
        raise error(f"{path}: {invalid.format(exc='nested too deeply')}") from None
