"""Cem Yuksel's ``.hair`` files: every flag combination reads back, renders and shows in the strand
view; bad files fail with one clear line; a model in any units lands on the head."""
import os
import struct
import subprocess
import sys
import textwrap
import time

import cv2
import numpy as np
import pytest

from hairdigi.app.cli import main
from hairdigi.render import head
from hairdigi.render.hairfile import (HAS_COLOR, HAS_POINTS, HAS_SEGMENTS, HAS_THICKNESS, HAS_TRANSPARENCY,
                                      MAX_POINTS_PER_STRAND, RADIUS, HairFile, HairFileError, fit_to_head,
                                      hair_file_bytes, hair_model_strands, read_hair, read_hair_file, write_hair,
                                      write_hair_file)
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.bounds import SceneKind
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.strands import Strands, hairstyle_strands

SIZE, SPP, STRANDS = 24, 1, 60
VALID_FLAGS = [f for f in range(32) if f & HAS_POINTS]


def head_of_hair(n: int = 60, scale: float = 9.0, style: str = "bob") -> np.ndarray:
    """(n, k, 3) polylines of a built-in style (without its mirrored ends), in cm by default."""
    s = hairstyle_strands(style, n, seed=2)
    return s.points.reshape(n, s.counts[0], 3)[:, 1:-1].astype(np.float64) * scale


def hair_with(flags: int, grid: np.ndarray) -> HairFile:
    """A model holding the arrays ``flags`` name; with a segments array the strands' lengths differ."""
    n, k, _ = grid.shape
    rng = np.random.default_rng(flags)
    if flags & HAS_SEGMENTS:
        counts = k - np.arange(n) % 3
        points = np.concatenate([grid[i, :c] for i, c in enumerate(counts)])
    else:
        counts = np.full(n, k)
        points = grid.reshape(-1, 3)
    p = len(points)
    return HairFile(points.astype(np.float32), n,
                    segments=(counts - 1).astype(np.uint16) if flags & HAS_SEGMENTS else None,
                    thickness=rng.uniform(0.01, 0.03, p).astype(np.float32) if flags & HAS_THICKNESS else None,
                    transparency=rng.uniform(0, 1, p).astype(np.float32) if flags & HAS_TRANSPARENCY else None,
                    colour=rng.uniform(0, 1, (p, 3)).astype(np.float32) if flags & HAS_COLOR else None,
                    default_segments=0 if flags & HAS_SEGMENTS else k - 1, default_thickness=0.02,
                    default_transparency=0.25, default_colour=(0.4, 0.3, 0.2), info=f"hairdigi test, flags {flags}")


@pytest.fixture(scope="module")
def flag_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("hair")
    grid = head_of_hair()
    return {flags: write_hair_file(root / f"flags{flags:02d}.hair", hair_with(flags, grid)) for flags in VALID_FLAGS}


@pytest.mark.parametrize("flags", range(32))
def test_every_flag_combination_reads_back_equal(flags, tmp_path):
    hair = hair_with(flags | HAS_POINTS, head_of_hair(12))
    path = tmp_path / "m.hair"
    if flags & HAS_POINTS:
        write_hair_file(path, hair)
        back = read_hair_file(path)
        assert back.flags == flags and back.equals(hair)
        assert path.stat().st_size == len(hair_file_bytes(hair))
        assert np.array_equal(back.counts, hair.counts) and back.strands().n_strands == 12
    else:   # the points array is required: a file without it is refused, whatever else it holds
        data = bytearray(hair_file_bytes(hair))
        struct.pack_into("<I", data, 12, flags)
        path.write_bytes(bytes(data))
        with pytest.raises(HairFileError, match="no points array"):
            read_hair_file(path)


def test_every_flag_combination_renders(flag_files):
    renderer = Renderer()
    dark, light = HairParams((255, 255, 255), 0.0, 0.9, 0.9), HairParams((255, 255, 255), 0.0, 0.1, 0.2)
    for flags, path in flag_files.items():
        spec = SceneSpec(str(path), strands=STRANDS)
        assert spec.name == "hairfile" and spec.kind is SceneKind.HAIR_FILE and spec.hair_file == str(path.resolve())
        image = renderer.render(dark, spec, SIZE, SPP, 0)
        assert image.nonfinite == 0 and image.linear.mean() > 0.005, flags
        assert renderer.render(light, spec, SIZE, SPP, 0).linear.mean() > image.linear.mean(), flags   # hair shows


STRAND_VIEW = textwrap.dedent("""
    import sys, numpy as np
    from PySide6.QtWidgets import QApplication
    app = QApplication([])
    from hairdigi.app.gui.strand_view import StrandView
    from hairdigi.render.hairfile import hair_model_strands
    view = StrandView()
    view.resize(300, 300)
    view.show()
    for path in sys.argv[1:]:
        view.show_strands(hair_model_strands(path, 400), (150, 70, 30))
        app.processEvents()
        image = view.plotter.screenshot(return_img=True)
        hair = (np.abs(image.astype(int) - [150, 70, 30]).sum(axis=2) < 90).mean()
        print(path, hair)
    view.close_view()
""")


def test_every_flag_combination_shows_in_the_strand_view(flag_files, xvfb):
    env = {**os.environ, "DISPLAY": xvfb, "QT_QPA_PLATFORM": "xcb"}
    paths = [str(p) for p in flag_files.values()]
    run = subprocess.run([sys.executable, "-c", STRAND_VIEW, *paths], env=env, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    shown = dict(line.rsplit(" ", 1) for line in run.stdout.strip().splitlines())
    assert sorted(shown) == sorted(paths)
    assert all(float(v) > 0.01 for v in shown.values()), shown      # strands drawn in the hair colour


def _bad(tmp_path, name: str, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def _header(n_strands=2, n_points=8, flags=HAS_SEGMENTS | HAS_POINTS, default_segments=0, magic=b"HAIR"):
    return struct.pack("<4sIIIIff3f88s", magic, n_strands, n_points, flags, default_segments, 0.02, 0.0, 1, 1, 1, b"")


def _good_bytes() -> bytes:
    return _header() + np.array([3, 3], "<u2").tobytes() + np.arange(24, dtype="<f4").tobytes()


@pytest.mark.parametrize("name, data, message", [
    ("short.hair", b"HAIR" + bytes(53), r"truncated: 57 bytes, but a \.hair header alone needs 128"),
    ("cut.hair", _good_bytes()[:-10], rf"truncated: {len(_good_bytes()) - 10} bytes, .*need {len(_good_bytes())}"),
    ("magic.hair", b"NOPE" + _good_bytes()[4:], r"not a \.hair file: it starts with b'NOPE', expected b'HAIR'"),
    ("counts.hair", _header() + np.array([3, 4], "<u2").tobytes() + np.arange(24, dtype="<f4").tobytes(),
     r"counts do not add up: its segments array make 9 points, the header says 8"),
    ("defaults.hair", _header(flags=HAS_POINTS, default_segments=2) + np.arange(24, dtype="<f4").tobytes(),
     r"counts do not add up: 2 strands of 2 default segments make 6 points, the header says 8"),
    ("empty.hair", _header(n_strands=0, n_points=0), r"holds 0 strands"),
    ("nopoints.hair", _header(flags=HAS_SEGMENTS) + np.array([3, 3], "<u2").tobytes(), r"has no points array"),
    ("nan.hair", _header() + np.array([3, 3], "<u2").tobytes() + np.r_[np.arange(20), np.nan, 1, 2, 3].astype("<f4").tobytes(),
     r"1 points are not finite \(NaN or Inf\), the first is point 6"),
])
def test_bad_files_say_what_is_wrong_in_one_line(tmp_path, name, data, message):
    path = _bad(tmp_path, name, data)
    with pytest.raises(HairFileError, match=message) as info:
        read_hair(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_cli_renders_a_hair_file_and_refuses_a_bad_one(tmp_path, capsys):
    params = tmp_path / "p.json"
    params.write_text('{"hair": {"dye_rgb": [170, 60, 30], "dye_concentration": 0.45, '
                      '"melanin_concentration": 0.35, "melanin_ratio": 0.55}}')
    model = write_hair(tmp_path / "model.hair", Strands.from_grid(head_of_hair(80, 10.0, "wavy"), 0.1))
    out = tmp_path / "model.png"
    assert main(["render", "--params", str(params), "--scene", str(model), "--size", "32", "--spp", "2",
                 "--strands", "80", "--out", str(out)]) == 0
    image = cv2.imread(str(out))
    assert image.shape == (32, 32, 3) and image.std() > 1
    assert "model.hair: 80 strands" in capsys.readouterr().out      # says what it rendered of the model
    bad = _bad(tmp_path, "bad.hair", _good_bytes()[:-10])
    assert main(["render", "--params", str(params), "--scene", str(bad), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "truncated" in err and "Traceback" not in err
    with pytest.raises(SystemExit) as exit_info:   # argparse's usage error
        main(["render", "--params", str(params), "--scene", "beehive", "--out", str(tmp_path / "x.png")])
    assert exit_info.value.code == 2 and "or give the path of a .hair file" in capsys.readouterr().err


def test_the_fit_puts_a_model_in_any_units_at_the_same_place(tmp_path):
    scene_units = head_of_hair(300, scale=1.0)
    to_z_up = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])   # y up, face +z  ->  z up, face -y
    fitted = {}
    for unit, scale, rotation in (("mm", 90.0, np.eye(3)), ("m", 0.09, to_z_up)):
        points = (scene_units.reshape(-1, 3) * scale) @ rotation.T
        model = Strands(points.astype(np.float32), np.full(len(points), 0.1 * scale, np.float32),
                        np.full(300, scene_units.shape[1]))
        fitted[unit] = fit_to_head(read_hair(write_hair(tmp_path / f"{unit}.hair", model)))
    assert np.abs(fitted["mm"].points - fitted["m"].points).max() < 2e-3        # same place, same size
    roots = fitted["mm"].points[fitted["mm"].starts()]
    assert np.linalg.norm(roots - scene_units[:, 0], axis=1).mean() < 0.05       # where the style grew them
    assert np.abs(head.sdf(roots)).mean() < 0.03 and head.sdf(fitted["mm"].points).min() > 0   # on the scalp, outside


def test_big_models_are_cut_to_the_budget_and_cached_per_modification(tmp_path):
    rng = np.random.default_rng(0)
    grid = np.repeat(head_of_hair(500, 9.0, "curly"), 4, axis=1)
    grid += rng.normal(0, 0.01, grid.shape)
    path = write_hair(tmp_path / "big.hair", Strands.from_grid(grid, 0.01))
    strands = hair_model_strands(path, n_strands=100)
    assert strands.n_strands == 100 and strands.counts.max() <= MAX_POINTS_PER_STRAND + 2
    assert RADIUS < strands.radii[0] <= 2 * RADIUS                               # thicker, to keep the coverage
    assert hair_model_strands(path, n_strands=100) is strands                      # loaded once
    write_hair(path, Strands.from_grid(grid[:200], 0.01))
    os.utime(path, ns=(time.time_ns(), path.stat().st_mtime_ns + 10_000_000))
    assert hair_model_strands(path, n_strands=100) is not strands                  # saved again: loaded again


def test_scene_spec_names_a_hair_file(tmp_path):
    path = write_hair(tmp_path / "s.hair", Strands.from_grid(head_of_hair(10), 0.1))
    spec = SceneSpec(str(path), strands=50)
    assert spec == SceneSpec(SceneKind.HAIR_FILE, hair_file=str(path), strands=50) and hash(spec) == hash(
        SceneSpec("hairfile", hair_file=str(path), strands=50))
    with pytest.raises(ValueError, match="no such file"):
        SceneSpec(str(tmp_path / "missing.hair"))
    with pytest.raises(ValueError, match="no such file"):
        SceneSpec(SceneKind.HAIR_FILE)
    with pytest.raises(ValueError, match="hair_file applies to"):
        SceneSpec("bob", hair_file=str(path))
