"""Shine from the rig's three lights: the renderer renders a given shine, and
the shine is read back from single-light renders of known shine."""
from dataclasses import replace

import numpy as np
import pytest

from hairdigi.render.domain.appearance import Appearance
from hairdigi.inference.refine import RefineSettings, scene_for
from hairdigi.inference.appearance_reading import dark_lights, read_appearance
from hairdigi.inference.shine import estimate_shine, shine_tables
from hairdigi.render.domain.rig_geometry import N_LIGHTS, RigRegion, swatch_roi
from hairdigi.render.renderer import Renderer, SceneSpec

SMALL = RefineSettings(size=24, spp=16, check_spp=16)


def test_a_shine_set_on_a_loaded_scene_renders_as_a_scene_built_with_it():
    """``longitudinal_roughness`` reaches the hair BSDF through ``mi.traverse``: a scene loaded at the
    default shine and updated renders as one loaded at that shine; and shine changes the colour."""
    sigma = np.array([0.35, 0.6, 1.2])
    glossy = SceneSpec("swatch", appearance=Appearance(0.15))
    warm = Renderer(max_cached=1)
    warm.render(sigma, SceneSpec("swatch"), 24, 4, seed=0)           # built at 0.3
    updated = warm.render(sigma, glossy, 24, 16, seed=5).linear
    fresh = Renderer(max_cached=1).render(sigma, glossy, 24, 16, seed=5).linear
    assert np.allclose(updated, fresh, atol=1e-5)
    default = warm.render(sigma, SceneSpec("swatch"), 24, 16, seed=5).linear
    assert abs(default.mean() - fresh.mean()) > 0.2 * default.mean()
    with pytest.raises(ValueError, match="longitudinal_roughness"):
        SceneSpec("swatch", appearance=Appearance(0.0))


@pytest.mark.slow
def test_shine_is_read_from_the_three_lights(tmp_path, monkeypatch):
    """Renders of the rig's swatch area, one light at a time, at a known shine and with another strand
    layout and seed than the tables': the shine read back is within 0.05 of the truth."""
    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path))
    size = (400, 300)
    view = RigRegion(size, swatch_roi(size))
    renderer = Renderer(max_cached=2)
    tables = shine_tables(view, SMALL, renderer=renderer)
    spec, film = scene_for(view, SMALL)
    sigma = np.array([0.3, 0.7, 1.6])
    readings = {}
    for beta in (0.15, 0.5):
        single = np.array([renderer.render(sigma, replace(spec, strand_seed=5, appearance=Appearance(beta),
                                                          lights=tuple(float(i == light) for i in range(N_LIGHTS))),
                                           film, 32, 123).linear.reshape(-1, 3).mean(0) for light in range(N_LIGHTS)])
        est = estimate_shine(single, tables)
        assert abs(est.longitudinal_roughness - beta) <= 0.05 + 1e-9, (beta, est)   # the grid's step is 0.01
        # and the colour with it (red and green; at 24² and 16 spp the tables' darkest blue is noise)
        assert np.allclose(est.sigma_a[:2], sigma[:2], rtol=0.4) and est.sigma_a[2] > 1.0, (sigma, est.sigma_a)
        readings[beta] = single
    # glossy hair leaves light 0's swatch at the noise floor while the light itself is on: that is read as
    # glossy, not refused; a light whose whole frame is dark is dead, and the shine is not read
    lit = np.full((N_LIGHTS, 3), 0.05)
    assert dark_lights(readings[0.15]) == ([], [0]) and dark_lights(readings[0.15], lit) == ([], [0])
    glossy = read_appearance(readings[0.15], view, SMALL, renderer, frame_levels=lit)
    assert glossy.estimate.measured == ("longitudinal_roughness",) and glossy.value.longitudinal_roughness <= 0.2
    dead = read_appearance(readings[0.15], view, SMALL, renderer, frame_levels=lit * [[0.001], [1], [1]])
    assert "longitudinal_roughness" not in dead.estimate.measured
    assert any("light 0 left its own frame dark" in w.message for w in dead.warnings)
