import json
import subprocess
import sys

import cv2
import pytest

from hairdigi.app.cli import main


@pytest.fixture
def params_file(tmp_path):
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"hair": {"dye_rgb": [200, 30, 30], "dye_concentration": 0.6,
                                         "melanin_concentration": 0.3, "melanin_ratio": 0.5}}))
    return path


def test_render_writes_png_and_exr(tmp_path, params_file, capsys):
    out, exr = tmp_path / "o.png", tmp_path / "o.exr"
    assert main(["render", "--params", str(params_file), "--scene", "swatch", "--size", "32", "--spp", "2",
                 "--strands", "200", "--camera", "20,45", "--out", str(out), "--exr", str(exr)]) == 0
    img = cv2.imread(str(out))
    assert img.shape == (32, 32, 3) and img.std() > 1
    assert exr.stat().st_size > 0
    assert "wrote" in capsys.readouterr().out


def test_render_reports_its_non_finite_count(tmp_path, params_file, capsys):
    assert main(["render", "--params", str(params_file), "--size", "16", "--spp", "1", "--strands", "100",
                 "--out", str(tmp_path / "o.png")]) == 0
    assert "0 non-finite values" in capsys.readouterr().out


def test_expected_errors_are_one_line_and_debug_shows_the_traceback(tmp_path, params_file, capsys):
    args = ["render", "--params", str(params_file), "--size", "16", "--out", str(params_file)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is also the --params input" in err and "Traceback" not in err
    assert main(args + ["--debug"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and err.strip().endswith("choose another output name")


def test_a_bug_keeps_its_traceback(tmp_path, params_file, capsys, monkeypatch):
    import hairdigi.app.cli as cli_module

    def broken(args):
        raise TypeError("a bug")
    real = cli_module.build_parser

    def parser():
        p = real()
        p._subparsers._group_actions[0].choices["render"].set_defaults(func=broken)
        return p
    monkeypatch.setattr(cli_module, "build_parser", parser)
    assert main(["render", "--params", str(params_file), "--out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "TypeError: a bug" in err and "internal error" in err


def test_render_hairstyle(tmp_path, params_file):
    out = tmp_path / "h.png"
    assert main(["render", "--params", str(params_file), "--scene", "curly", "--size", "32", "--spp", "1",
                 "--strands", "100", "--env", "soft", "--out", str(out)]) == 0
    assert cv2.imread(str(out)).shape == (32, 32, 3)


def test_bad_params_file_is_a_one_line_error(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"dye_rgb": [300, 0, 0], "dye_concentration": 0,
                               "melanin_concentration": 0, "melanin_ratio": 0}))
    assert main(["render", "--params", str(bad), "--size", "16", "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "dye_r = 300.0 is outside its range [0, 255]" in err and "Traceback" not in err
    assert not (tmp_path / "x.png").exists()


def test_bad_camera_and_unknown_scene(tmp_path, params_file, capsys):
    assert main(["render", "--params", str(params_file), "--camera", "abc", "--out", str(tmp_path / "x.png")]) == 2
    assert "POLAR,AZIMUTH" in capsys.readouterr().err
    run = subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "render", "--params", str(params_file),
                          "--scene", "beehive", "--out", "x.png"], capture_output=True, text=True)
    assert run.returncode == 2 and "'beehive' is not a scene" in run.stderr


@pytest.mark.slow
def test_demo_quick(tmp_path, capsys):
    """The headless main job: the simulated rig's chain, then renders."""
    assert main(["demo", "--quick", "--out", str(tmp_path)]) == 0
    for name in ("swatch", "straight", "curly"):
        assert cv2.imread(str(tmp_path / f"{name}.png")).std() > 1
    out = capsys.readouterr().out
    assert "calibration" in out and "ΔE2000 mean" in out and "capture:" in out and str(tmp_path) in out
    assert list((tmp_path / "session" / "captures").glob("*.png"))


@pytest.mark.slow
def test_bench_render_quick_writes_a_table_where_depth_matters(tmp_path, capsys):
    """The benchmark's table and plot; too few bounces (depth 4) must show as colour error."""
    import csv

    assert main(["bench", "render", "--quick", "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader(open(tmp_path / "render_bench.csv")))
    out = capsys.readouterr().out
    assert (tmp_path / "render_bench.png").stat().st_size > 0 and "cases" in out
    assert "non-finite values returned by the path tracer over all cases: 0" in out
    assert all(r["nonfinite"] == "0" for r in rows)
    swatch = [r for r in rows if r["scene"] == "swatch"]
    shallow = next(r for r in swatch if r["sweep"] == "depth")
    deep = next(r for r in swatch if r["sweep"] == "spp" and r["spp"] == shallow["spp"])
    assert int(shallow["depth"]) < int(deep["depth"])
    assert float(shallow["mean_delta_e2000"]) > 2 * float(deep["mean_delta_e2000"])
    assert all(float(r["seconds"]) > 0 for r in rows)
