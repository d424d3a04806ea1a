import json
import re

import numpy as np
import pytest

from hairdigi.render.domain.params import HairParams, HairParamsError, load_params, sample_params, save_params


def test_json_round_trip_top_level_and_under_hair(tmp_path):
    p = HairParams((10, 200, 30.5), 0.25, 0.75, 0.1)
    (tmp_path / "top.json").write_text(json.dumps(p.to_dict()))
    save_params(tmp_path / "nested.json", p, model="abc", image_sha256="00")
    assert load_params(tmp_path / "top.json") == p
    assert load_params(tmp_path / "nested.json") == p
    assert json.loads((tmp_path / "nested.json").read_text())["model"] == "abc"


def test_vector_round_trip_and_range():
    rng = np.random.default_rng(0)
    for _ in range(20):
        p = sample_params(rng)
        v = p.to_vector()
        assert v.shape == (6,) and v.min() >= 0 and v.max() <= 1
        q = HairParams.from_vector(v)
        assert np.allclose(q.to_vector(), v, atol=1e-6)


def test_from_vector_clamps_out_of_range():
    p = HairParams.from_vector(np.array([1.2, -0.1, 0.5, 0.5, 2.0, -3.0]))
    assert p.dye_rgb[0] == 255 and p.dye_rgb[1] == 0 and p.melanin_concentration == 1 and p.melanin_ratio == 0


@pytest.mark.parametrize("kwargs, field", [
    (dict(dye_rgb=(256, 0, 0)), "dye_r"),
    (dict(dye_rgb=(0, -1, 0)), "dye_g"),
    (dict(dye_concentration=1.5), "dye_concentration"),
    (dict(melanin_concentration=float("nan")), "melanin_concentration"),
    (dict(melanin_ratio=-0.01), "melanin_ratio"),
])
def test_invalid_values_name_the_field_and_range(kwargs, field):
    with pytest.raises(HairParamsError, match=rf"{field} = .* outside its range \["):
        HairParams(**kwargs)


def test_bad_files_give_clear_errors(tmp_path):
    with pytest.raises(HairParamsError, match="no such parameter file"):
        load_params(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(HairParamsError, match="not valid JSON"):
        load_params(tmp_path / "bad.json")
    (tmp_path / "partial.json").write_text(json.dumps({"dye_rgb": [1, 2, 3]}))
    with pytest.raises(HairParamsError, match="missing dye_concentration"):
        load_params(tmp_path / "partial.json")
    (tmp_path / "short.json").write_text(json.dumps({"dye_rgb": [1, 2], "dye_concentration": 0,
                                                     "melanin_concentration": 0, "melanin_ratio": 0}))
    with pytest.raises(HairParamsError, match="3 values"):
        load_params(tmp_path / "short.json")


def test_atomic_writes_are_readable_by_the_lab(tmp_path):
    """mkstemp makes owner-only files; published captures, exports and models follow the umask."""
    import os
    import stat

    import numpy as np

    from hairdigi.hardware.capture import save_capture
    from hairdigi.render.io.images import save_png

    old = os.umask(0o022)
    try:
        paths = [save_params(tmp_path / "p.json", HairParams()), save_png(tmp_path / "i.png", np.zeros((4, 4, 3), np.uint8)),
                 *save_capture(tmp_path / "cap", np.zeros((4, 4, 3), np.uint8))[:2]]
    finally:
        os.umask(old)
    for p in paths:
        assert stat.S_IMODE(os.stat(p).st_mode) == 0o644, p


@pytest.mark.parametrize("dye_rgb, message", [
    ("123", "got the string '123'"),            # was read as (1, 2, 3)
    ([[1, 2, 3]], "got a list of 1"),
    ([1, 2], "got a list of 2"),
    ([1, 2, 3, 4], "got a list of 4"),
    ([True, 0, 0], "dye_r must be a number, got true"),
    (["1", 2, 3], "dye_r must be a number, got the string '1'"),
    (None, "got null"),
    (128, "got int 128"),
])
def test_dye_rgb_is_exactly_three_numbers(tmp_path, dye_rgb, message):
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"dye_rgb": dye_rgb, "dye_concentration": 0.5, "melanin_concentration": 0.5,
                                "melanin_ratio": 0.5}))
    with pytest.raises(HairParamsError, match=re.escape(message)):
        load_params(path)


@pytest.mark.parametrize("value, message", [
    (True, "got true"), (False, "got false"), ("0.5", "got the string '0.5'"), ([0.5], "got a list [0.5]"),
    (None, "got null"), ({"v": 0.5}, "got dict"),
])
def test_scalars_are_real_numbers_only(tmp_path, value, message):
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"hair": {"dye_rgb": [1, 2, 3], "dye_concentration": 0.5,
                                         "melanin_concentration": value, "melanin_ratio": 0.5}}))
    with pytest.raises(HairParamsError, match=rf"melanin_concentration must be a number, {re.escape(message)}"):
        load_params(path)


def test_numbers_of_any_numeric_type_are_kept():
    p = HairParams(np.array([1, 2, 3]), np.float32(0.5), 1, np.int64(0))
    assert p.dye_rgb == (1.0, 2.0, 3.0) and p.dye_concentration == 0.5 and p.melanin_ratio == 0.0
    assert all(type(v) is float for v in (*p.dye_rgb, p.dye_concentration, p.melanin_concentration))


def test_unreadable_parameter_files_name_the_file_and_the_fix(tmp_path):
    with pytest.raises(HairParamsError, match="is a folder, not a JSON file"):
        load_params(tmp_path)
    (tmp_path / "latin1.json").write_bytes(b'{"dye_rgb": "\xe9"}')
    with pytest.raises(HairParamsError, match="not UTF-8 text"):
        load_params(tmp_path / "latin1.json")
    (tmp_path / "deep.json").write_text("[" * 100_000)
    with pytest.raises(HairParamsError, match="not valid JSON"):
        load_params(tmp_path / "deep.json")


def test_a_failed_image_write_leaves_no_temporary_file(tmp_path):
    from hairdigi.render.io.images import save_exr, save_png

    (tmp_path / "taken.png").mkdir()          # the target is a folder: the final rename fails
    with pytest.raises(OSError):
        save_png(tmp_path / "taken.png", np.zeros((4, 4, 3), np.uint8))
    (tmp_path / "taken.exr").mkdir()
    with pytest.raises(OSError):
        save_exr(tmp_path / "taken.exr", np.zeros((4, 4, 3), np.float32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.exr", "taken.png"]
    with pytest.raises(ValueError, match="name the file with .png"):
        save_png(tmp_path / "o.jpg", np.zeros((4, 4, 3), np.uint8))
