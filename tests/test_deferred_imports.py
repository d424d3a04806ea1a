"""Imports sit at the top of their modules. One inside a function is deferred on purpose and says why: a
``# deferred:`` comment on its line, or in the comment block right above the run of imports it belongs to
(import statements one after another, nothing but blank lines between them: stdlib, third-party and
hairdigi's own in their groups)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("render", "inference", "hardware", "app", "resources")
REASON = "# deferred:"


def _runs(body: list[ast.stmt]) -> list[list[ast.stmt]]:
    """The runs of import statements in ``body`` that follow one another with no other statement between."""
    runs, run = [], []
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            run.append(node)
        elif run:
            runs.append(run)
            run = []
    return runs + ([run] if run else [])


def _comment_above(lines: list[str], lineno: int) -> str:
    """The block of comment lines right above line ``lineno`` (1-based), joined."""
    block, i = [], lineno - 2
    while i >= 0 and lines[i].strip().startswith("#"):
        block.append(lines[i].strip())
        i -= 1
    return " ".join(reversed(block))


def undeclared(path: Path) -> list[str]:
    """``path:line`` of each import inside a function of ``path`` that gives no reason for being there."""
    source = path.read_text()
    lines = source.splitlines()
    found = []
    for fn in ast.walk(ast.parse(source)):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        bodies = [n for n in ast.walk(fn) if hasattr(n, "body") and isinstance(n.body, list)]
        for holder in bodies:
            for block in ("body", "orelse", "finalbody"):      # an except clause is walked as its own body
                for run in _runs([s for s in getattr(holder, block, []) if isinstance(s, ast.stmt)]):
                    said = REASON in _comment_above(lines, run[0].lineno)
                    for node in run:
                        if not (said or REASON in lines[node.lineno - 1]):
                            where = path.relative_to(ROOT if ROOT in path.parents else path.parents[1])
                            found.append(f"{where}:{node.lineno}")
    return sorted(set(found))


def test_every_import_inside_a_function_says_why_it_is_deferred() -> None:
    files = [p for package in PACKAGES for p in sorted((ROOT / package).rglob("*.py"))]
    assert len(files) > 100
    missing = [line for p in files for line in undeclared(p)]
    assert not missing, f"{len(missing)} function-level imports give no '{REASON}' reason: move them to the " \
                        f"module's top, or say why they wait: {missing}"


def test_the_check_finds_an_import_without_a_reason(tmp_path) -> None:
    """The check itself: a bare import inside a function is found; one under a reason, or a run of them, is not."""
    module = tmp_path / "app" / "probe.py"
    module.parent.mkdir()
    module.write_text("def f():\n    import json\n    return json\n\n\n"
                      "def g():\n    # deferred: a reason\n    import json\n    import csv\n    return json, csv\n\n\n"
                      "def h():\n    import json  # deferred: its reason\n    return json\n\n\n"
                      "def k():\n    # deferred: covers the run only\n    import json\n\n    import csv\n"
                      "    x = csv\n    import os\n    return json, x, os\n")
    assert undeclared(module) == ["app/probe.py:2", "app/probe.py:24"]
