"""The package and its import rules: one installed package, `hairdigi`, and the layers of the brief as
import-linter contracts (pyproject.toml), checked on the wheel that `pip wheel .` builds."""
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """Built from a copy of the source, so that no stale build/ folder in the checkout leaks into it."""
    src, out = tmp_path_factory.mktemp("src") / "hairdigi", tmp_path_factory.mktemp("wheel")
    skip = shutil.ignore_patterns(".git", ".venv", "build", "dist", "out", "test-output", "*.egg-info",
                                  "__pycache__", ".pytest_cache")
    shutil.copytree(ROOT, src, ignore=skip)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
                    "-w", str(out), str(src)], check=True, capture_output=True, timeout=300)
    (path,) = out.glob("hairdigi-*.whl")
    return path


def test_the_wheel_installs_one_top_level_package(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")} == {"hairdigi"}
    for sub in ("app", "app/cli", "app/dye", "app/evaluation", "app/gui", "app/library", "app/models", "app/review",
                "app/session", "hardware", "inference", "render", "resources"):
        assert f"hairdigi/{sub}/__init__.py" in names
    assert "hairdigi/resources/models/encoder.onnx" in names
    assert not [n for n in names if n.endswith((".log", ".pyc"))]


def lint_imports(site: Path) -> subprocess.CompletedProcess:
    """import-linter on the package installed in ``site``, with the checkout's contracts."""
    exe = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(site)}
    return subprocess.run([exe], cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)


@pytest.fixture(scope="module")
def site(wheel, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("site")
    zipfile.ZipFile(wheel).extractall(path)
    return path


def test_import_contracts_hold_on_the_built_package(site):
    result = lint_imports(site)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "6 kept, 0 broken" in result.stdout
    assert "Analyzed 0 files" not in result.stdout


def test_a_stray_import_breaks_the_contracts(site, tmp_path):
    """The contracts are rules: a copy of the package with an ``app.review.model -> PySide6``, an
    ``app.models.panel -> PySide6``, a ``render -> inference``, an ``app.gui -> app.cli`` and an
    ``app.session -> app.cli`` import (modules no contract lists) fails them."""
    shutil.copytree(site / "hairdigi", tmp_path / "hairdigi")
    with open(tmp_path / "hairdigi" / "app" / "review" / "model.py", "a") as f:
        f.write("\nimport PySide6  # stray\n")
    with open(tmp_path / "hairdigi" / "app" / "models" / "panel.py", "a") as f:
        f.write("\nimport PySide6  # stray\n")
    with open(tmp_path / "hairdigi" / "render" / "metrics.py", "a") as f:
        f.write("\nfrom hairdigi.inference import estimate  # stray\n")
    with open(tmp_path / "hairdigi" / "app" / "gui" / "images.py", "a") as f:
        f.write("\nimport hairdigi.app.cli  # stray\n")
    with open(tmp_path / "hairdigi" / "app" / "session" / "blockers.py", "a") as f:
        f.write("\nimport hairdigi.app.cli.validation  # stray\n")
    result = lint_imports(tmp_path)
    assert result.returncode != 0 and "4 broken" in result.stdout, result.stdout[-3000:]
    assert "hairdigi.app.review.model -> PySide6" in result.stdout
    assert "hairdigi.app.models.panel -> PySide6" in result.stdout
    assert "hairdigi.render.metrics -> hairdigi.inference.estimate" in result.stdout
    assert "hairdigi.app.gui.images -> hairdigi.app.cli" in result.stdout
    assert "hairdigi.app.session.blockers -> hairdigi.app.cli.validation" in result.stdout


def domain_imports(site: Path) -> dict[str, list[str]]:
    """What each module of render.domain imports directly (external packages by their top-level name),
    read by grimp from the package in ``site`` (in a subprocess: this one imports the checkout's)."""
    import json

    code = ("import grimp, json; g = grimp.build_graph('hairdigi', include_external_packages=True, cache_dir=None); "
            "print(json.dumps({m: sorted(g.find_modules_directly_imported_by(m)) "
            "for m in g.find_descendants('hairdigi.render.domain')}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True,
                         env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(site)})
    return json.loads(out.stdout)


def test_render_domain_imports_numpy_and_the_standard_library_only(site, tmp_path):
    allowed = set(sys.stdlib_module_names) | {"numpy"}

    def strays(imports: dict[str, set[str]]) -> set[str]:
        return {f"{m} -> {i}" for m, targets in imports.items() for i in targets
                if not i.startswith("hairdigi.render.domain") and i.split(".")[0] not in allowed}
    assert domain_imports(site) and strays(domain_imports(site)) == set()
    shutil.copytree(site / "hairdigi", tmp_path / "hairdigi")      # and the rule can fail
    with open(tmp_path / "hairdigi" / "render" / "domain" / "params.py", "a") as f:
        f.write("\nfrom hairdigi.render import renderer  # stray\nimport cv2  # stray\n")
    assert strays(domain_imports(tmp_path)) == {"hairdigi.render.domain.params -> hairdigi.render.renderer",
                                              "hairdigi.render.domain.params -> cv2"}


def _modules_after_import(statement: str) -> dict:
    code = (f"import json, sys; {statement}; mods = sys.modules; "
            "mi = mods.get('mitsuba'); print(json.dumps({'mitsuba': 'mitsuba' in mods, "
            "'variant': mi.variant() if mi else None, 'qt': 'PySide6' in mods, 'torch': 'torch' in mods}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    import json
    return json.loads(out.stdout)


def test_the_rig_geometry_imports_without_mitsuba():
    seen = _modules_after_import("import hairdigi.render.domain.rig_geometry, hairdigi.inference.preprocess")
    assert not seen["mitsuba"] and not seen["qt"] and not seen["torch"]


def test_importing_the_renderer_chooses_no_variant():
    """The entry points or the first renderer choose Mitsuba's variant; an import never does."""
    seen = _modules_after_import("import hairdigi.render.renderer, hairdigi.render.scenes, "
                                 "hairdigi.inference.training.dataset, hairdigi.app.session.rig_session")
    assert seen["variant"] is None and not seen["qt"]
