"""Expected errors against bugs: a ``HairdigiError`` (or a file system error) is the user's, one line and
exit status 2; a plain ``ValueError`` is a bug, numpy's included, and keeps its traceback (exit 1)."""
import argparse
import errno
import importlib
import inspect
import json
import pkgutil
import shutil
from pathlib import Path

import numpy as np
import pytest

from hairdigi.app.cli import main
from hairdigi.app.cli.validation import is_expected
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import PACKAGE_PARTS

ROOT = Path(__file__).resolve().parent.parent
#: Modules that cannot be imported outside their own program: the Blender-side script needs bpy;
#: ``python -m hairdigi.app.cli``'s ``__main__`` runs the command line as it is imported.
NOT_IMPORTABLE = ("hairdigi.render.blender_hair", "hairdigi.app.cli.__main__")
#: Optional extras: their modules are skipped where the extra is not installed (the desktop build).
EXTRAS = ("torch", "onnx", "ray", "gi", "bpy")


@pytest.fixture
def record(tmp_path) -> Path:
    path = tmp_path / "auburn.json"
    shutil.copyfile(ROOT / "resources" / "samples" / "auburn.json", path)
    return path


def one_line_error(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err[-2000:]
    return lines[0]


# --- (a) a bug keeps its traceback ---------------------------------------------------------------
def numpy_bug(*args, **kwargs):
    np.zeros(3).reshape(2)   # ValueError: cannot reshape array of size 3 into shape (2,)


def test_a_numpy_value_error_in_a_command_is_a_bug_with_its_traceback(record, tmp_path, monkeypatch, capsys):
    """Before ``HairdigiError``, every ValueError counted as the user's: this one exited 2 in one line,
    and the bug was hidden."""
    from hairdigi.app.cli import export as export_cli

    monkeypatch.setattr(export_cli, "export_record", numpy_bug)
    code = main(["export", str(record), "--format", "materialx", "--out", str(tmp_path / "look.mtlx")])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "Traceback" in err and "cannot reshape array of size 3" in err and "in numpy_bug" in err
    assert err.strip().splitlines()[-1] == ("hairdigi export: internal error (a bug in hairdigi): ValueError; please "
                                            "report it with the traceback above")


@pytest.mark.parametrize("bug", [KeyError("missing"), TypeError("wrong type"), RuntimeError("broken"),
                                 json.JSONDecodeError("Expecting value", "{", 1), UnicodeDecodeError(
                                     "utf-8", b"\xff", 0, 1, "invalid start byte")])
def test_plain_builtin_errors_are_bugs(bug):
    assert not is_expected(bug)


@pytest.mark.parametrize("error", [HairdigiError("x"), OSError(errno.ENOSPC, "No space left on device"),
                                   FileNotFoundError(errno.ENOENT, "No such file", "a.json"), MemoryError(),
                                   argparse.ArgumentTypeError("not a number")])
def test_hairdigi_file_system_and_memory_errors_are_the_users(error):
    assert is_expected(error)


# --- (b) every hairdigi error class derives from HairdigiError ---------------------------------
def _modules():
    """Every module of the package but the window's (Qt) and those an uninstalled extra or another
    program needs; what was skipped, with why."""
    found, skipped = [], {}
    names = []
    for part in PACKAGE_PARTS:   # the package itself is a namespace in an editable install: walk its parts
        package = importlib.import_module(f"hairdigi.{part}")
        names += [package.__name__] + [i.name for i in pkgutil.walk_packages(package.__path__, f"{package.__name__}.")]
    for name in names:
        if name.startswith("hairdigi.app.gui") or name in NOT_IMPORTABLE:
            continue
        try:
            found.append(importlib.import_module(name))
        except ModuleNotFoundError as exc:
            if (exc.name or "").split(".")[0] not in EXTRAS:
                raise
            skipped[name] = exc.name
    return found, skipped


def _error_classes() -> dict[str, type]:
    modules, _ = _modules()
    return {f"{m.__name__}.{name}": cls for m in modules for name, cls in vars(m).items()
            if inspect.isclass(cls) and issubclass(cls, BaseException) and cls.__module__ == m.__name__
            and not name.startswith("_")}


def test_every_error_class_of_hairdigi_is_a_hairdigi_error():
    classes = _error_classes()
    named_error = [n for n in classes if n.endswith("Error")]
    assert len(named_error) >= 22 and "hairdigi.app.cli.CliError" in classes   # the walk found them
    strays = sorted(n for n, cls in classes.items() if not issubclass(cls, HairdigiError))
    assert strays == [], f"derive these from render.domain.errors.HairdigiError: {strays}"


#: The builtin base each error class had before HairdigiError, kept so that ``except ValueError`` (or
#: ``RuntimeError``) written against them still catches them.
BUILTIN_BASES = {
    "app.library.store.LibraryError": ValueError, "app.cli.validation.ArgumentError": ValueError,
    "hardware.cameras.CameraError": RuntimeError, "hardware.lights.LightError": RuntimeError,
    "hardware.lights.LightArgumentError": ValueError, "inference.calibration.CalibrationError": RuntimeError,
    "inference.preprocess.ImageError": ValueError, "inference.appearance_reading.LightFramesError": ValueError,
    "inference.dye.DyeError": ValueError, "inference.encoder.ModelError": RuntimeError,
    "render.hairfile.HairFileError": ValueError, "render.blender_run.BlenderError": RuntimeError,
    "render.denoise.DenoiserMissing": RuntimeError, "render.spectra.SpectrumError": ValueError,
    "render.variant.VariantError": RuntimeError, "render.domain.params.HairParamsError": ValueError,
    "render.domain.record_fields.RecordError": ValueError, "render.domain.appearance.AppearanceError": ValueError,
}


@pytest.mark.parametrize("name", sorted(BUILTIN_BASES))
def test_each_error_keeps_its_builtin_base(name):
    module, cls = name.rsplit(".", 1)
    error = getattr(importlib.import_module(f"hairdigi.{module}"), cls)
    assert issubclass(error, HairdigiError) and issubclass(error, BUILTIN_BASES[name])


# --- (c) the user's errors stay one line and exit status 2 -----------------------------------
def test_a_hairdigi_error_or_a_full_disk_in_a_command_is_one_line(record, tmp_path, monkeypatch, capsys):
    from hairdigi.app.cli import export as export_cli
    from hairdigi.render.domain.record_fields import RecordError

    args = ["export", str(record), "--format", "materialx", "--out", str(tmp_path / "look.mtlx")]

    def refused(*a, **kw):
        raise RecordError(f"{record}: not an estimate record; give one")
    monkeypatch.setattr(export_cli, "export_record", refused)
    assert main(args) == 2
    line = one_line_error(capsys.readouterr().err)
    assert line == f"hairdigi export: error: {record}: not an estimate record; give one"

    def full(*a, **kw):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "look.mtlx"))
    monkeypatch.setattr(export_cli, "export_record", full)
    assert main(args) == 2
    assert one_line_error(capsys.readouterr().err).endswith("No space left on device; free some space or write to "
                                                            "another disk")


def test_user_mistakes_that_builtin_errors_carried_are_one_line(record, tmp_path, monkeypatch, capsys):
    """Mistakes once refused by a plain ValueError (or json's) that now raise the module's HairdigiError."""
    monkeypatch.setenv("HAIRDIGI_LIBRARY", str(tmp_path / "library.sqlite"))
    assert main(["library", "find", "--near", "#12345z"]) == 2
    assert "colour '#12345z' is not #RRGGBB" in one_line_error(capsys.readouterr().err)

    assert main(["export", str(record), "--format", "materialx", "--blend", str(tmp_path / "x.blend"),
                 "--out", str(tmp_path / "look.mtlx")]) == 2
    assert one_line_error(capsys.readouterr().err).endswith("--blend goes with --format blender")

    bad = tmp_path / "evaluation.json"
    bad.write_text('{"buckets": ')
    (tmp_path / "run").mkdir()
    assert main(["model-card", "--evaluation", str(bad), "--run", str(tmp_path / "run"), "--model",
                 str(ROOT / "resources" / "models" / "encoder.onnx"), "--out", str(tmp_path / "card.md")]) == 2
    line = one_line_error(capsys.readouterr().err)
    assert f"{bad}: not JSON" in line and "--evaluation" in line
