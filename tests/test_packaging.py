"""The desktop build's fast checks: one version string everywhere, the install and uninstall scripts,
the screenshot check, and training's one-line message. The build itself (minutes) is not run here:
``packaging/build`` builds and smoke-tests it (packaging/README.md)."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hairdigi.render.domain.version import _pyproject_version, version

ROOT = Path(__file__).resolve().parents[1]
PACKAGING = ROOT / "packaging"


def pyproject_version() -> str:
    text = (ROOT / "pyproject.toml").read_text()
    return re.search(r'^version = "([^"]+)"', text, re.M).group(1)


def test_one_version_string(tmp_path):
    """pyproject.toml, the metadata accessor, ``hairdigi --version`` and an exported record agree."""
    expected = pyproject_version()
    assert version() == expected == _pyproject_version(ROOT / "pyproject.toml")
    out = subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "--version"], capture_output=True, text=True,
                         check=True, cwd=tmp_path).stdout
    assert out.strip() == f"hairdigi {expected}"

    from hairdigi.inference.encoder import Estimate
    from hairdigi.inference.estimate import EstimateResult, record
    from hairdigi.render.domain.params import HairParams

    est = Estimate(HairParams(), np.zeros(6), [])
    encoder = SimpleNamespace(path=Path("encoder.onnx"), sha256="0" * 64, input_size=48)
    rec = record(EstimateResult(HairParams(), est, None), encoder)
    assert json.loads(json.dumps(rec.to_json()))["provenance"]["hairdigi_version"] == expected


def test_version_in_parser_help_and_without_metadata(tmp_path, capsys):
    from hairdigi.app.cli import build_parser

    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip() == f"hairdigi {pyproject_version()}"
    (tmp_path / "pyproject.toml").write_text('[build-system]\nrequires = []\n\n[project]\nname = "x"\n'
                                             'version = "9.8.7"\n\n[tool.x]\nversion = "no"\n')
    assert _pyproject_version(tmp_path / "pyproject.toml") == "9.8.7"
    assert _pyproject_version(tmp_path / "missing.toml") == "unknown"


def test_about_box_names_version_model_and_variant(qtbot):
    from PySide6.QtWidgets import QWidget

    from hairdigi.app.gui.main_window import MainWindow
    from hairdigi.render.variant import select_variant

    host = QWidget()
    qtbot.addWidget(host)
    host.session = SimpleNamespace(encoder=SimpleNamespace(path=Path("encoder.onnx"), sha256="ab" * 32))
    box = MainWindow.show_about(host)
    text = box.text() + "\n" + box.informativeText()
    box.close()
    assert f"hairdigi {version()}" in text and "ab" * 32 in text and select_variant() in text


def test_training_without_torch_is_one_line(tmp_path):
    """Without the train extra (as in the desktop build) ``hairdigi train`` says what to install."""
    (tmp_path / "data").mkdir()
    code = ("import sys; sys.modules['torch'] = None\n"
            "from hairdigi.app.cli import main\n"
            f"sys.exit(main(['train', '--dataset', {str(tmp_path / 'data')!r}, '--out', {str(tmp_path / 'run')!r}]))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        "hairdigi train: error: training needs a developer install: pip install 'hairdigi[train]'"]


def fake_build(folder: Path) -> Path:
    """A stand-in for dist/hairdigi/: an executable that answers --version, and a data file."""
    (folder / "_internal").mkdir(parents=True)
    (folder / "_internal" / "data.txt").write_text("x")
    exe = folder / "hairdigi"
    exe.write_text("#!/bin/sh\necho hairdigi 0.0.0-test\n")
    exe.chmod(0o755)
    return folder


def files_under(home: Path) -> set[str]:
    return {str(p.relative_to(home)) for p in home.rglob("*") if p.is_file() or p.is_symlink()}


def run_script(name: str, home: Path, *args: str) -> subprocess.CompletedProcess:
    env = {"HOME": str(home), "PATH": "/usr/bin:/bin"}
    return subprocess.run(["bash", str(PACKAGING / name), *args], capture_output=True, text=True, env=env)


def test_install_and_uninstall_touch_only_their_files(tmp_path):
    home = tmp_path / "home"
    (home / ".config").mkdir(parents=True)
    (home / ".config" / "keep.conf").write_text("lab settings")
    before = files_under(home)
    build = fake_build(tmp_path / "dist" / "hairdigi")

    done = run_script("install", home, str(build))
    assert done.returncode == 0, done.stderr
    opt = home / ".local" / "opt" / "hairdigi"
    link = home / ".local" / "bin" / "hairdigi"
    entry = home / ".local" / "share" / "applications" / "hairdigi.desktop"
    icon = home / ".local" / "share" / "icons" / "hicolor" / "256x256" / "apps" / "hairdigi.png"
    assert (opt / "_internal" / "data.txt").exists() and os.readlink(link) == str(opt / "hairdigi")
    assert icon.read_bytes() == (PACKAGING / "hairdigi.png").read_bytes()
    desktop = entry.read_text()
    assert f"Exec={opt}/hairdigi app" in desktop and f"TryExec={opt}/hairdigi" in desktop
    assert "Icon=hairdigi" in desktop
    assert subprocess.run([str(link), "--version"], capture_output=True, text=True).stdout.strip() == "hairdigi 0.0.0-test"
    assert run_script("install", home, str(build)).returncode == 0      # again: replaces, does not nest
    assert not (opt / "hairdigi" / "hairdigi").exists()

    done = run_script("uninstall", home)
    assert done.returncode == 0, done.stderr
    assert files_under(home) == before


def test_install_keeps_a_foreign_command(tmp_path):
    home = tmp_path / "home"
    own = home / ".local" / "bin" / "hairdigi"
    own.parent.mkdir(parents=True)
    own.write_text("#!/bin/sh\n")
    done = run_script("install", home, str(fake_build(tmp_path / "build")))
    assert done.returncode == 2 and "not our link" in done.stderr
    assert run_script("uninstall", home).returncode == 0 and own.exists()
    assert run_script("install", home, str(tmp_path / "nowhere")).returncode == 2


def test_desktop_entry_keys():
    keys = dict(line.split("=", 1) for line in (PACKAGING / "hairdigi.desktop").read_text().splitlines() if "=" in line)
    assert keys["Type"] == "Application" and keys["Exec"] == "hairdigi app" and keys["Icon"] == "hairdigi"
    assert keys["Categories"].endswith(";")


def test_screenshot_check(tmp_path):
    """packaging/png_check.py (stdlib only, for the smoke test): a flat image is blank, a busy one is not."""
    import cv2

    sys.path.insert(0, str(PACKAGING))
    try:
        import png_check
    finally:
        sys.path.remove(str(PACKAGING))
    busy = np.random.default_rng(0).integers(0, 256, (40, 60, 4), np.uint8)
    cv2.imwrite(str(tmp_path / "busy.png"), busy)
    cv2.imwrite(str(tmp_path / "flat.png"), np.full((40, 60, 3), 200, np.uint8))
    std, colours = png_check.stats(str(tmp_path / "busy.png"))
    grey = busy[..., 2] * 0.299 + busy[..., 1] * 0.587 + busy[..., 0] * 0.114
    assert std == pytest.approx(grey.std(), abs=1e-6) and colours == len(np.unique(busy[..., :3].reshape(-1, 3), axis=0))
    assert png_check.main([str(tmp_path / "busy.png")]) == 0
    assert png_check.main([str(tmp_path / "flat.png")]) == 1
    (tmp_path / "not.png").write_text("text")
    assert png_check.main([str(tmp_path / "not.png")]) == 2


def run_rthook(tmp_path, argv: list[str], env: dict, failing_libs: tuple[str, ...] = ()) -> subprocess.CompletedProcess:
    """packaging/rthook_hairdigi.py as the build runs it (``sys._MEIPASS`` set), with some libraries unloadable."""
    code = (f"import ctypes, os, runpy, sys\n"
            f"sys._MEIPASS = {str(tmp_path)!r}\n"
            f"sys.argv = {['hairdigi', *argv]!r}\n"
            f"real = ctypes.CDLL\n"
            f"def fake(name, *a, **k):\n"
            f"    if os.path.basename(name) in {failing_libs!r}:\n"
            f"        raise OSError(name + ': cannot open shared object file')\n"
            f"    return real(name, *a, **k)\n"
            f"ctypes.CDLL = fake\n"
            f"runpy.run_path({str(PACKAGING / 'rthook_hairdigi.py')!r})\n"
            f"print(os.environ.get('DRJIT_LIBLLVM_PATH'), os.environ.get('HAIRDIGI_VARIANT'))\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={"PATH": "/usr/bin:/bin", **env})


def test_first_run_checks_are_one_line(tmp_path):
    """The build's runtime hook: no display, a missing GL library, an LLVM that does not load."""
    done = run_rthook(tmp_path, ["app", "--sim"], {})
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "no display" in done.stderr

    done = run_rthook(tmp_path, ["app"], {"DISPLAY": ":99"}, failing_libs=("libEGL.so.1",))
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "libEGL.so.1" in done.stderr and "sudo apt-get install libegl1" in done.stderr

    assert run_rthook(tmp_path, ["app"], {"QT_QPA_PLATFORM": "offscreen"}).returncode == 0

    llvm = tmp_path / "llvm" / "libLLVM.so.19.1"
    llvm.parent.mkdir()
    llvm.write_bytes(b"not a library")
    done = run_rthook(tmp_path, ["render", "--params", "p.json"], {})
    assert done.returncode == 0 and done.stdout.split() == [str(llvm), "scalar_rgb"]
    assert done.stderr.count("\n") == 1 and "sudo apt-get install libllvm19" in done.stderr

    done = run_rthook(tmp_path, ["--version"], {})   # prints only: no checks, no cost
    assert done.returncode == 0 and done.stdout.split() == ["None", "None"] and not done.stderr
