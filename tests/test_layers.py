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
    for sub in ("app", "app/gui", "hardware", "inference", "render", "resources"):
        assert f"hairdigi/{sub}/__init__.py" in names
    assert "hairdigi/resources/models/encoder.onnx" in names
    assert not [n for n in names if n.endswith((".log", ".pyc"))]


def test_import_contracts_hold_on_the_built_package(wheel, tmp_path):
    zipfile.ZipFile(wheel).extractall(tmp_path)
    exe = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(tmp_path)}
    result = subprocess.run([exe], cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "4 kept, 0 broken" in result.stdout
    assert "Analyzed 0 files" not in result.stdout


def _modules_after_import(statement: str) -> dict:
    code = (f"import json, sys; {statement}; mods = sys.modules; "
            "mi = mods.get('mitsuba'); print(json.dumps({'mitsuba': 'mitsuba' in mods, "
            "'variant': mi.variant() if mi else None, 'qt': 'PySide6' in mods, 'torch': 'torch' in mods}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    import json
    return json.loads(out.stdout)


def test_the_rig_geometry_imports_without_mitsuba():
    seen = _modules_after_import("import hairdigi.render.base.rig_geometry, hairdigi.inference.preprocess")
    assert not seen["mitsuba"] and not seen["qt"] and not seen["torch"]


def test_importing_the_renderer_chooses_no_variant():
    """The entry points or the first renderer choose Mitsuba's variant; an import never does."""
    seen = _modules_after_import("import hairdigi.render.renderer, hairdigi.render.scenes, "
                                 "hairdigi.inference.training.dataset, hairdigi.app.rig_session")
    assert seen["variant"] is None and not seen["qt"]
