"""The manual (packaging/manual): it builds with warnings as errors, every page of its nav is built,
every API directive renders its module, and every ``hairdigi`` command it writes (in code blocks and
inline code, in the manual, the README and the pages it includes) names a real subcommand with real
flags of that subcommand, as the command line's own parser has them."""
from __future__ import annotations

import argparse
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MANUAL = ROOT / "packaging" / "manual"
CONFIG = MANUAL / "mkdocs.yml"
DOCS = MANUAL / "docs"

_missing = [m for m in ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")
            if importlib.util.find_spec(m.split(".")[0]) is None
            or (m.count(".") and importlib.util.find_spec(m) is None)]


def _hooks():
    """packaging/manual/hooks.py, which names the repository files the manual includes."""
    spec = importlib.util.spec_from_file_location("hairdigi_manual_hooks", MANUAL / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def nav_pages(nav) -> list[str]:
    """The Markdown files a MkDocs nav names, in order."""
    if isinstance(nav, str):
        return [] if "://" in nav else [nav]
    if isinstance(nav, list):
        return [p for item in nav for p in nav_pages(item)]
    if isinstance(nav, dict):
        return [p for value in nav.values() for p in nav_pages(value)]
    return []


def built_page(site: Path, page: str) -> Path:
    """Where MkDocs (directory URLs) writes ``page``: a/b.md -> a/b/index.html, a/index.md -> a/index.html."""
    stem = page[:-len(".md")]
    if stem == "index" or stem.endswith("/index"):
        return site / f"{stem}.html"
    return site / stem / "index.html"


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    if _missing:
        pytest.skip(f"the manual's tools are not installed ({', '.join(_missing)}): "
                    f"pip install -e '.[docs]' (make setup does)")
    out = tmp_path_factory.mktemp("manual")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(CONFIG), "-d", str(out)],
                         capture_output=True, text=True, timeout=600, env=env)
    assert run.returncode == 0, f"mkdocs build --strict failed:\n{run.stdout}\n{run.stderr}"
    return out


def test_every_page_of_the_nav_is_built(site):
    import yaml

    pages = nav_pages(yaml.safe_load(CONFIG.read_text())["nav"])
    assert len(pages) >= 20 and "index.md" in pages
    included = {uri for _, uri in _hooks().included_files()}
    for page in pages:
        assert (DOCS / page).is_file() or page in included, f"nav names {page}, which is neither in docs/ nor included"
        html = built_page(site, page)
        assert html.is_file(), f"{page} was not built ({html})"
        text = html.read_text()
        assert "<article" in text and len(re.sub(r"<[^>]+>", "", text)) > 300, f"{page} built empty"


def test_every_api_directive_renders_its_module(site):
    directives = 0
    for page in DOCS.rglob("*.md"):
        modules = re.findall(r"^::: (hairdigi\.[\w.]+)", page.read_text(), re.M)
        if not modules:
            continue
        html = built_page(site, page.relative_to(DOCS).as_posix()).read_text()
        for module in modules:
            directives += 1
            assert f'id="{module}"' in html, f"{page.name}: ::: {module} rendered nothing"
    assert directives >= 20


def test_the_pictures_are_the_repositorys_own(site):
    for path, uri in _hooks().included_files():
        if path.suffix == ".png":
            assert (site / uri).read_bytes() == path.read_bytes(), uri
    assert (site / "screenshots" / "app-sim-xvfb.png").is_file()


# --- the commands written in the manual -------------------------------------------------------------

def manual_sources() -> list[Path]:
    """Every Markdown file whose commands a reader may copy: the manual's pages, the repository files it
    includes as pages, the README and render/README.md."""
    included = [path for path, uri in _hooks().included_files() if path.suffix == ".md"]
    return sorted(DOCS.rglob("*.md")) + included + [ROOT / "README.md", ROOT / "render" / "README.md"]


FENCE = re.compile(r"^([ \t]*)(```|~~~)[^\n]*\n(.*?)^\1\2[ \t]*$", re.S | re.M)
INLINE = re.compile(r"(?<!`)`([^`\n]+)`(?!`)")


def command_lines(markdown: str) -> list[str]:
    """Lines of code that run ``hairdigi``: each line of a fenced block (a trailing backslash joins the
    next; comments dropped) and each inline code span, split at ``;`` and ``&&``."""
    chunks = []
    for block in FENCE.finditer(markdown):
        text = re.sub(r"\s*\\\n\s*", " ", block.group(3))
        chunks += [re.sub(r"(^|\s)#\s.*$", "", line) for line in text.splitlines()]
    chunks += INLINE.findall(FENCE.sub("", markdown))
    out = []
    for chunk in chunks:
        out += [part.strip() for part in re.split(r";|&&", chunk) if re.search(r"(^|[\s/])hairdigi\s+\S", part)]
    return out


def _subparsers(parser: argparse.ArgumentParser):
    return next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)


def _is_placeholder(token: str) -> bool:
    """A word the reader replaces: NAME, RECORD.json, [...], an ellipsis."""
    return bool(re.fullmatch(r"[A-Z][A-Z0-9_]*(?:\.\w+)?\.*|\.\.\.|…", token))


def check_command(line: str, parser: argparse.ArgumentParser) -> list[str]:
    """What is wrong with one ``hairdigi ...`` line: an unknown subcommand, a flag its subcommand does not
    have, or a choice it does not offer (``bench NAME``). An empty list when all is right."""
    tokens = line.split()
    start = next(i for i, t in enumerate(tokens) if t == "hairdigi" or t.endswith("/hairdigi"))
    words = [t.strip("[]()'\",") for t in tokens[start + 1:]]
    words = [w for w in words if w and w not in ("|",)]
    problems, current, path = [], parser, ["hairdigi"]
    positionals = []
    for word in words:
        if word.startswith("--"):
            flag = word.split("=", 1)[0]
            if flag in ("--help", "--debug"):
                continue
            if flag not in current._option_string_actions:
                problems.append(f"{' '.join(path)} has no flag {flag}")
            continue
        if word.startswith("-"):
            continue
        sub = _subparsers(current)
        if sub is not None and not positionals:
            if _is_placeholder(word):   # hairdigi COMMAND ...: nothing more to check
                return problems
            if word not in sub.choices:
                problems.append(f"{' '.join(path)} has no subcommand {word!r} (it has {', '.join(sub.choices)})")
                return problems
            current, path = sub.choices[word], path + [word]
            continue
        positionals.append(word)
        if len(positionals) == 1:   # the first positional argument, where it offers choices (bench NAME)
            first = next((a for a in current._actions if not a.option_strings
                          and not isinstance(a, argparse._SubParsersAction)), None)
            if first is not None and first.choices and not _is_placeholder(word):
                options = {w for w in re.split(r"[|,]", word) if w}
                wrong = sorted(options - set(map(str, first.choices)))
                if wrong:
                    problems.append(f"{' '.join(path)}: {', '.join(wrong)} is not one of {', '.join(first.choices)}")
    if len(path) == 1 and not any(w.startswith("--") for w in words):
        problems.append("no subcommand")
    return problems


@pytest.fixture(scope="module")
def parser() -> argparse.ArgumentParser:
    from hairdigi.app.cli import build_parser

    return build_parser()


def test_every_command_in_the_manual_is_real(parser):
    checked, problems = 0, []
    for source in manual_sources():
        for line in command_lines(source.read_text()):
            checked += 1
            problems += [f"{source.relative_to(ROOT)}: `{line}`: {p}" for p in check_command(line, parser)]
    assert not problems, "commands the command line does not have:\n" + "\n".join(problems)
    assert checked >= 100, f"only {checked} hairdigi commands found: is the extraction broken?"


@pytest.mark.parametrize("line, wrong", [
    ("hairdigi render --params P.json --out x.png", None),
    ("hairdigi render --params P.json --bogus 3 --out x.png", "has no flag --bogus"),
    ("hairdigi estimate photo.png --lights L0.png,L1.png,L2.png [--structure assumed|family|read] --out e.json", None),
    ("hairdigi estimate photo.png --light L0.png --out e.json", "has no flag --light"),
    ("hairdigi renderr --out x.png", "no subcommand 'renderr'"),
    ("hairdigi library find --near #aa3311 --under studio --k 5", None),
    ("hairdigi library find --nearest RECORD.json", "hairdigi library find has no flag --nearest"),
    ("hairdigi COMMAND --help", None),
    ("hairdigi library search --near RECORD.json", "no subcommand 'search'"),
    ("hairdigi dye card copper.json --out card.png", None),
    ("hairdigi dye card copper.json --pair a b", "hairdigi dye card has no flag --pair"),
    ("hairdigi bench spectral", None),
    ("hairdigi bench spectrum", "spectrum is not one of"),
    ("HAIRDIGI_BLENDER=~/bpy/bin/python hairdigi evaluate --cycles --out out/eval-cycles", None),
    (".venv/bin/hairdigi evaluate --cycle", "has no flag --cycle"),
])
def test_the_command_check_finds_what_is_wrong(parser, line, wrong):
    problems = check_command(line, parser)
    if wrong is None:
        assert problems == []
    else:
        assert problems and wrong in problems[0], problems


def test_commands_are_found_in_blocks_and_inline_code():
    text = ("Run `hairdigi rig --sim` first.\n\n```bash\nhairdigi dye dose copper.json \\\n    --base B.json "
            "--target #RRGGBB   # the dose\nmake test\n```\n\nThe `hairdigi` program.\n")
    assert command_lines(text) == ["hairdigi dye dose copper.json --base B.json --target #RRGGBB",
                                   "hairdigi rig --sim"]
