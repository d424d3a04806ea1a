import json

import numpy as np
import pytest

from render.params import HairParams, HairParamsError, load_params, sample_params, save_params


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

    from hardware.capture import save_capture
    from render.imageio import save_png

    old = os.umask(0o022)
    try:
        paths = [save_params(tmp_path / "p.json", HairParams()), save_png(tmp_path / "i.png", np.zeros((4, 4, 3), np.uint8)),
                 *save_capture(tmp_path / "cap", np.zeros((4, 4, 3), np.uint8))]
    finally:
        os.umask(old)
    for p in paths:
        assert stat.S_IMODE(os.stat(p).st_mode) == 0o644, p
