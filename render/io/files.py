"""Atomic file publication: write to a temporary file beside the target, then rename over it."""
from __future__ import annotations

import os
from pathlib import Path


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


#: A parameter file, calibration profile or manifest is a few kB; anything this large is the wrong file.
MAX_JSON_BYTES = 16 * 1024 * 1024


def read_json(path: str | os.PathLike, error: type[Exception], missing: str, invalid: str):
    """Parse a JSON file; a missing or malformed file raises ``error`` with ``path: missing`` or
    ``path: invalid`` (``{exc}`` in ``invalid`` is replaced by the parser's message)."""
    import json

    path = Path(path)
    try:
        size = path.stat().st_size
        text = path.read_text(encoding="utf-8") if size <= MAX_JSON_BYTES else None
    except FileNotFoundError:
        raise error(f"{path}: {missing}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, not a JSON file; give the file's path") from None
    except PermissionError:
        raise error(f"{path}: permission denied; make it readable (chmod +r) or use a copy") from None
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise error(f"{path}: {invalid.format(exc='not UTF-8 text')}") from None
    if text is None:
        raise error(f"{path}: {size / 1e6:.0f} MB is too large for a hairdigi JSON file (at most "
                    f"{MAX_JSON_BYTES / 1e6:.0f} MB); check the file name")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: {invalid.format(exc=exc)}") from None
    except RecursionError:
        raise error(f"{path}: {invalid.format(exc='nested too deeply')}") from None
