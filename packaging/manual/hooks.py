"""MkDocs hooks of hairdigi's manual (``packaging/manual/mkdocs.yml``).

- The API pages: mkdocstrings reads the sources statically (griffe), without importing them, so no
  page starts a GUI or loads Mitsuba. The repository's folders are installed as ``hairdigi.<folder>``
  (``[tool.setuptools.package-dir]`` in pyproject.toml), a mapping griffe cannot follow, so the
  build lays a ``hairdigi/`` folder of links to them in a temporary directory and searches there.
- The pictures and a few pages live with what they describe, not in ``docs/``: the app's own
  screenshots, the benchmark and evaluation plots, the model card. They are added to the build
  from where they are (``INCLUDED_PICTURES``, ``INCLUDED_PAGES``), never copied into the source tree.
- The docstrings write Sphinx roles (":func:`name`"); the pages show the name as code, without the role.
"""
from __future__ import annotations

import re
import shutil
import tempfile
import tomllib
from pathlib import Path

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File, Files

#: The repository's root (this file is packaging/manual/hooks.py).
ROOT = Path(__file__).resolve().parents[2]

#: Files of the repository that the manual shows as they are: (glob under ROOT, folder in the site).
INCLUDED_PICTURES = (
    ("packaging/screenshots/*.png", "screenshots"),
    ("packaging/bench/*/*.png", "bench"),
    ("packaging/evaluation/*/*.png", "evaluation"),
    ("resources/models/*.png", "models"),
)

#: Markdown files of the repository that are pages of the manual: (file under ROOT, page in the site).
INCLUDED_PAGES = (
    ("resources/models/encoder.md", "figures/model-card.md"),
    ("resources/models/swatch-structure.md", "rendering/swatch-structure.md"),
    ("packaging/README.md", "developer/desktop-build.md"),
)

_api_tree: Path | None = None

#: Sphinx roles in docstrings (":func:`name`"): the name is shown as code, the role dropped.
_ROLE = re.compile(r":(?:py:)?(?:func|meth|class|data|attr|mod|exc|obj|const):(?=<code>)")


def package_dirs() -> dict[str, Path]:
    """``hairdigi.<name>`` -> its folder, as pyproject.toml maps them."""
    mapping = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    return {name: ROOT / folder for name, folder in mapping.items()}


def api_source_tree(where: Path) -> Path:
    """A ``hairdigi/`` folder under ``where`` whose subfolders link to the repository's packages."""
    package = where / "hairdigi"
    package.mkdir(parents=True, exist_ok=True)
    for name, folder in package_dirs().items():
        (package / name.split(".", 1)[1]).symlink_to(folder, target_is_directory=True)
    return where


def included_files() -> list[tuple[Path, str]]:
    """Every repository file the manual shows, as (its path, its URI in the site)."""
    out = []
    for pattern, folder in INCLUDED_PICTURES:
        for path in sorted(ROOT.glob(pattern)):
            inner = path.relative_to(ROOT / pattern.split("/*", 1)[0])
            out.append((path, f"{folder}/{inner.as_posix()}"))
    out += [(ROOT / source, page) for source, page in INCLUDED_PAGES]
    return out


@event_priority(100)   # before mkdocstrings reads its handler's options
def on_config(config):
    global _api_tree
    if _api_tree is None or not _api_tree.is_dir():   # once a process (mkdocs serve rebuilds)
        _api_tree = api_source_tree(Path(tempfile.mkdtemp(prefix="hairdigi-manual-api-")))
    python = config.plugins["mkdocstrings"].config.handlers.setdefault("python", {})
    python["paths"] = [str(_api_tree)]
    return config


def on_files(files: Files, config) -> Files:
    for path, uri in included_files():
        files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files


def on_page_content(html: str, page, config, files) -> str:
    return _ROLE.sub("", html)


def on_shutdown():
    if _api_tree is not None:
        shutil.rmtree(_api_tree, ignore_errors=True)
