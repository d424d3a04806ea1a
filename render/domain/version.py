"""hairdigi's one version string: ``version`` in pyproject.toml, read at run time from the installed
distribution's metadata (a wheel, an editable install, or the desktop build, which bundles it)."""
from __future__ import annotations

import re
from functools import lru_cache
from importlib import metadata
from pathlib import Path

DISTRIBUTION = "hairdigi"
#: The checkout's pyproject.toml: read only when no metadata is installed (a bare source tree).
PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"


@lru_cache(maxsize=1)
def version() -> str:
    """The version of hairdigi, e.g. ``"0.1.0"``."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return _pyproject_version(PYPROJECT)


def _pyproject_version(path: Path) -> str:
    """``version`` of ``[project]`` in a pyproject.toml (a regex: tomllib is Python 3.11+)."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        return "unknown"
    project = re.search(r"^\[project\]\s*$(.*?)(?=^\[|\Z)", text, re.M | re.S)
    found = project and re.search(r'^version\s*=\s*"([^"]+)"', project.group(1), re.M)
    return found.group(1) if found else "unknown"
