"""The texture model: the fibre spread and the grey share read from the swatch area.

Real renders, as ``inference.training.fit_texture`` renders its samples (a quarter of the bench
frame's swatch area, each light alone at 32 spp, through the camera model), with strand layouts and
seeds the model was not fitted on.
"""
from __future__ import annotations

import numpy as np
import pytest

from hairdigi.inference import texture
from hairdigi.inference.training import fit_texture

#: What the packaged model must do on a uniform swatch (see texture_evaluation.json). The grey share
#: is read (held-out MAE 0.057); the spread is not, at 32 spp (its reading stays near the training
#: mean, 0.25, and its p95 interval spans most of 0-0.5): the test only keeps it from reading high.
UNIFORM_GREY_BELOW, UNIFORM_SPREAD_BELOW, GREY_GAP = 0.1, 0.3, 0.05

#: Held-out swatches: (sigma_a, shine, spread, grey share, strand seed): a medium brown with greys
#: and a wide spread, and the same hair uniform.
VARIED = ((0.45, 0.75, 1.5), 0.3, 0.4, 0.25, 90001)
UNIFORM = ((0.45, 0.75, 1.5), 0.3, 0.0, 0.0, 90003)


@pytest.fixture(scope="module")
def renders() -> dict[str, np.ndarray]:
    from hairdigi.render.renderer import Renderer

    renderer = Renderer(max_cached=1)
    out = {}
    for name, (sigma, shine, spread, grey, strand_seed) in (("varied", VARIED), ("uniform", UNIFORM)):
        out[name] = fit_texture.render_swatch_lights(sigma, shine, spread, grey, strand_seed, render_seed=5,
                                                     renderer=renderer, roi=fit_texture.quadrant_roi(1))
    return out


def _read(lights: np.ndarray, case, camera_seed: int = 11, exposure_ev: float = 0.0) -> texture.VariationReading:
    return texture.read_variation(fit_texture.capture(lights, camera_seed, exposure_ev), case[0], case[1])


@pytest.mark.slow
def test_held_out_swatches_are_read_within_the_stated_p95(renders) -> None:
    for name, case in (("varied", VARIED), ("uniform", UNIFORM)):
        reading = _read(renders[name], case)
        for target, truth in (("fibre_spread", case[2]), ("grey_fraction", case[3])):
            lo, hi = reading.intervals[target]["p95"]
            assert lo <= truth <= hi, f"{name}: {target} {truth} outside the read p95 {lo:.3f}-{hi:.3f}"
            lo68, hi68 = reading.intervals[target]["p68"]
            assert lo <= lo68 <= getattr(reading, target) <= hi68 <= hi


def test_a_uniform_swatch_reads_near_zero(renders) -> None:
    uniform, varied = _read(renders["uniform"], UNIFORM), _read(renders["varied"], VARIED)
    assert uniform.grey_fraction < UNIFORM_GREY_BELOW
    assert uniform.fibre_spread < UNIFORM_SPREAD_BELOW
    assert uniform.grey_fraction + GREY_GAP < varied.grey_fraction   # the texture, not the prior, is read


def test_features_ignore_a_global_gain(renders) -> None:
    lights = renders["varied"]
    base = fit_texture.capture(lights, 13)
    feats = texture.texture_features(base)
    for ev in (-0.5, 0.5):   # a gain on the corrected pixels: exactly the same texture
        np.testing.assert_allclose(texture.texture_features(base * np.float32(2.0 ** ev)), feats, rtol=1e-3, atol=1e-4)
    # exposure off by 0.5 EV at the sensor: other noise and quantisation, about the same reading
    ref = _read(lights, VARIED, 13)
    for ev in (-0.5, 0.5):
        other = _read(lights, VARIED, 13, ev)
        for target in texture.TARGETS:
            half68 = np.diff(ref.intervals[target]["p68"])[0] / 2
            assert abs(getattr(other, target) - getattr(ref, target)) < half68, (target, ev)


def test_the_reading_needs_a_texture() -> None:
    with pytest.raises(ValueError, match="too small"):
        texture.texture_features(np.ones((8, 40, 3), np.float32))
    with pytest.raises(ValueError, match="H, W, 3"):
        texture.texture_features(np.ones((40, 40), np.float32))
    flat = np.full((40, 40, 3), 0.2, np.float32)
    assert np.all(np.isfinite(texture.texture_features(flat)))


def test_the_packaged_model_matches_the_features() -> None:
    model = texture.load_model()
    assert model.feature_names == texture.FEATURE_NAMES
    for target in texture.TARGETS:
        k = model.interval[target]["k"]
        assert 0 < k["p68"] < k["p95"]
    # light hair hides its greys: its grey-share interval is wider than dark hair's
    assert model.residual_scale("grey_fraction", texture.lightness((0.003, 0.006, 0.013))) > \
        model.residual_scale("grey_fraction", texture.lightness((0.8, 1.3, 2.6)))
