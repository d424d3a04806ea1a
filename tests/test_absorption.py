import itertools

import numpy as np

from hairdigi.render.domain.absorption import dye_sigma_a, hair_bsdf, hair_sigma_a, melanin_quantity
from hairdigi.render.domain.params import HairParams


def test_finite_and_non_negative_on_every_corner():
    for rgb in itertools.product((0, 255), repeat=3):
        for dc, mc, mr in itertools.product((0.0, 1.0), repeat=3):
            s = hair_sigma_a(HairParams(rgb, dc, mc, mr))
            assert np.all(np.isfinite(s)) and np.all(s >= 0), (rgb, dc, mc, mr, s)


def test_more_melanin_absorbs_more_in_every_channel():
    values = [hair_sigma_a(HairParams((255, 255, 255), 0, m, 0.7)) for m in np.linspace(0, 1, 21)]
    assert np.all(np.diff(np.array(values), axis=0) > 0)
    assert melanin_quantity(1.0) < 10  # clamped, finite


def test_dye_absorbs_least_in_its_own_channel():
    for channel in range(3):
        rgb = [30, 30, 30]
        rgb[channel] = 230
        s = dye_sigma_a(tuple(rgb), 1.0)
        assert np.argmin(s) == channel


def test_white_dye_and_zero_concentration_add_nothing():
    assert np.allclose(dye_sigma_a((255, 255, 255), 1.0), 0)
    assert np.allclose(dye_sigma_a((0, 0, 0), 0.0), 0)
    base = hair_sigma_a(HairParams((255, 255, 255), 0, 0.4, 0.5))
    assert np.allclose(hair_sigma_a(HairParams((0, 0, 0), 0, 0.4, 0.5)), base)


def test_bsdf_dict_uses_sigma_a_only():
    d = hair_bsdf(HairParams())
    assert d["sigma_a"]["type"] == "rgb" and len(d["sigma_a"]["value"]) == 3
    assert "eumelanin" not in d and "pheomelanin" not in d
    assert hair_bsdf(HairParams(), longitudinal_roughness=0.0)["longitudinal_roughness"] >= 0.05


def test_approximate_albedo_inverts_the_dye_mapping():
    from hairdigi.render.domain.absorption import approximate_albedo
    p = HairParams((200, 100, 50), 1.0, 0.0, 0.5)
    assert np.allclose(approximate_albedo(p), np.array([200, 100, 50]) / 255, atol=1e-6)
    dark = approximate_albedo(HairParams((255, 255, 255), 0, 1.0, 1.0))
    assert np.all(dark < 0.01) and np.all(approximate_albedo(HairParams((255, 255, 255), 0, 0, 0)) == 1)
