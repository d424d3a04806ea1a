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


def read_json(path: str | os.PathLike, error: type[Exception], missing: str, invalid: str):
    """Parse a JSON file; a missing or malformed file raises ``error`` with ``path: missing`` or
    ``path: invalid`` (``{exc}`` in ``invalid`` is replaced by the parser's message)."""
    import json

    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise error(f"{path}: {missing}") from None
    except json.JSONDecodeError as exc:
        raise error(f"{path}: {invalid.format(exc=exc)}") from None
