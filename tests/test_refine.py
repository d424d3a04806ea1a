"""Refinement by synthesis: the response curve, the inversion, the way back to Table 1, and convergence."""
import numpy as np
import pytest

from hairdigi.render.domain.records import RefinementRecord
from hairdigi.inference.refine import (RefineSettings, fibre_appearance, mean_linear, params_for_sigma, refine,
                                       response_curve)
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.domain.params import HairParams, sample_params
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.domain.rig_geometry import CameraPose, Framing

SMALL = RefineSettings(size=24, spp=8, check_spp=8, iterations=3, strand_seed=3)   # 3: the layered swatch took 3 for copper


def test_sigma_to_table1_reproduces_sigma_and_stays_near_the_prior():
    rng = np.random.default_rng(4)
    for _ in range(12):
        truth, prior = sample_params(rng), sample_params(rng)
        sigma = hair_sigma_a(truth)
        fitted, ok = params_for_sigma(sigma, prior)
        assert ok
        # the fibre colour is reproduced (cube-rooted albedo within 2e-3, about 0.3 ΔE at worst)
        assert np.abs(fibre_appearance(hair_sigma_a(fitted)) - fibre_appearance(sigma)).max() < 2e-3
        # and it is no farther from the prior than the truth, which is one member of the family
        assert np.linalg.norm(fitted.to_vector() - prior.to_vector()) <= \
            np.linalg.norm(truth.to_vector() - prior.to_vector()) + 1e-3


def test_a_colour_no_table1_hair_makes_is_reported_unreachable():
    # far more absorption in red than in blue: melanin absorbs blue most, and a dye saturates at ~1.4
    fitted, ok = params_for_sigma(np.array([6.0, 0.01, 0.01]), HairParams())
    assert not ok and isinstance(fitted, HairParams)


def test_response_curve_is_monotone_cached_and_channel_independent(tmp_path, monkeypatch):
    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path))
    renderer = Renderer(max_cached=2)
    curve = response_curve(CameraPose(20, 30), SMALL, renderer)
    assert np.all(np.diff(curve.mean) < 0) and not curve.cached
    assert curve.mean[0] > 0.2 and curve.mean[-1] < 0.05       # white fibres bright, sigma 12 near black
    again = response_curve(CameraPose(20, 30), SMALL, renderer)
    assert again.cached and np.allclose(again.mean, curve.mean)
    # each channel follows the one curve whatever the other channels absorb (the measured fact)
    spec = SceneSpec("swatch", camera=CameraPose(20, 30), strand_seed=SMALL.strand_seed)
    mixed = renderer.render(np.array([0.2, 1.5, 4.0]), spec, 32, 16, seed=9).linear.reshape(-1, 3).mean(0)
    assert np.allclose(mixed, curve(np.array([0.2, 1.5, 4.0])), rtol=0.08)
    # inverse of the curve at its own knots gives the knots back
    sigma, outside = curve.inverse(curve.mean[2:9])
    assert np.allclose(sigma, curve.sigma[2:9], rtol=1e-6, atol=1e-9) and not outside.any()


@pytest.mark.parametrize("truth", [HairParams((200, 60, 40), 0.7, 0.3, 0.4),      # copper, saturated
                                   HairParams((255, 255, 255), 0.0, 0.95, 0.9),    # black
                                   HairParams((250, 240, 200), 0.2, 0.05, 0.2)])   # platinum
def test_refinement_converges_to_the_noise_floor_from_a_poor_prior(truth, tmp_path, monkeypatch):
    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path))
    renderer = Renderer(max_cached=2)
    pose = CameraPose(25, 140)
    capture = SceneSpec("swatch", camera=pose, strand_seed=11)        # another strand layout than the curve's
    frame = renderer.render(truth, capture, 32, 32, seed=1).srgb
    prior = HairParams((120, 120, 120), 0.5, 0.5, 0.5)
    r = refine(prior, mean_linear(frame), pose, SMALL, renderer)
    judge = lambda hair, seed: renderer.render(hair, capture, 32, 16, seed).linear.reshape(-1, 3).mean(0)  # noqa: E731
    floor = float(delta_e2000(judge(truth, 2), judge(truth, 3)))
    before = float(delta_e2000(judge(prior, 2), judge(truth, 2)))
    after = float(delta_e2000(judge(r.params, 2), judge(truth, 2)))
    assert r.reachable and r.iterations >= 1 and len(r.history) == r.iterations
    assert after < 0.25 * before and after <= 2.0 * floor + 0.6, (before, after, floor, r.history)
    record = r.to_record()
    assert record.ran and record.residual_de2000 == pytest.approx(r.residual_de2000, abs=1e-4)
    assert RefinementRecord.from_json(record.to_json()) == record


def test_the_region_the_refinement_renders_is_the_region_it_fits():
    """A rig view's swatch area: the render's crop, scaled back to the frame, is exactly the pixels
    whose mean is fitted (geometry, no render), and it is the area the operator's ROI names to within
    one render pixel."""
    import numpy as np

    from hairdigi.inference.refine import RefineSettings, fitted_pixels, scene_for
    from hairdigi.render.domain.rig_geometry import RigRegion

    for frame, roi in (((400, 300), (30, 73, 130, 154)), ((800, 600), (61, 147, 259, 307)), ((400, 300), (0, 0, 400, 300))):
        region = RigRegion(frame, roi)
        film, crop, fitted = region.render_plan(48 * 48)
        spec, size = scene_for(region, RefineSettings())
        assert spec.crop == crop and size == film and spec.framing is Framing.RIG
        sx, sy = film[0] / frame[0], film[1] / frame[1]
        # the crop, mapped back to frame pixels, is the fitted region
        assert fitted == (round(crop[0] / sx), round(crop[1] / sy),
                          round((crop[0] + crop[2]) / sx) - round(crop[0] / sx),
                          round((crop[1] + crop[3]) / sy) - round(crop[1] / sy))
        # and it covers the ROI, larger by less than one render pixel on each side
        assert fitted[0] <= roi[0] < fitted[0] + 1 / sx + 1 and fitted[1] <= roi[1] < fitted[1] + 1 / sy + 1
        assert 0 <= fitted[0] + fitted[2] - (roi[0] + roi[2]) < 1 / sx + 1
        image = np.zeros((frame[1], frame[0], 3), np.float32)
        x, y, w, h = fitted
        image[y:y + h, x:x + w] = 1.0
        assert fitted_pixels(image, region).min() == 1.0 and fitted_pixels(image, region).size == w * h * 3


def test_a_cropped_render_is_that_window_of_the_whole_film(tmp_path):
    """The film crop renders the same scene's window: its mean matches the same window of the full render."""
    import numpy as np

    from hairdigi.render.domain.rig_geometry import RIG_HALF_WIDTH, RIG_TARGET
    from hairdigi.render.metrics import delta_e2000

    renderer = Renderer(max_cached=2)
    full = SceneSpec("swatch", framing="rig", target=RIG_TARGET, half_width=RIG_HALF_WIDTH)
    crop = (10, 20, 30, 36)
    window = SceneSpec("swatch", framing="rig", target=RIG_TARGET, half_width=RIG_HALF_WIDTH, crop=crop)
    sigma = np.array([0.3, 0.6, 1.2])
    a = renderer.render(sigma, full, (100, 75), 64, seed=3).linear[20:56, 10:40]
    b = renderer.render(sigma, window, (100, 75), 64, seed=4).linear
    assert b.shape == (36, 30, 3)
    assert float(delta_e2000(a.reshape(-1, 3).mean(0), b.reshape(-1, 3).mean(0))) < 0.8
    # and a different window is a different colour (the holder shows there): the crop is not ignored
    c = renderer.render(sigma, SceneSpec("swatch", framing="rig", target=RIG_TARGET, half_width=RIG_HALF_WIDTH,
                                         crop=(70, 0, 30, 36)), (100, 75), 64, seed=4).linear
    assert float(delta_e2000(c.reshape(-1, 3).mean(0), b.reshape(-1, 3).mean(0))) > 3.0


def test_a_variation_whose_curve_cannot_reach_the_colour_says_how_far_it_falls_short():
    """``curve_reach``: the swatch's own prediction, no render. Uniform fibres reach any colour on their curve
    (about 0); a fifth of grey fibres lightens every hair, so a colour darker than the darkest it makes is out
    of reach by its distance: the estimate then skips that variation's check renders."""
    from hairdigi.inference.refine import SIGMA_LEVELS, ResponseCurve, curve_reach
    from hairdigi.render.domain.appearance import Appearance

    sigma = np.array(SIGMA_LEVELS)
    curve = ResponseCurve(sigma, 0.02 + 0.5 * np.exp(-sigma))   # every channel's, of its own sigma_a
    reachable = curve(np.array([0.4, 0.8, 1.6]))
    uniform, greys = Appearance(0.3), Appearance(0.3, grey_fraction=0.2)
    assert curve_reach(curve, uniform, reachable) < 0.05    # the interpolants' round trip
    assert curve_reach(curve, greys, reachable) < 0.1       # lighter hair of more sigma_a makes it too
    darkest = curve(np.full(3, sigma[-1]))
    assert curve_reach(curve, uniform, darkest) < 0.05
    assert curve_reach(curve, greys, darkest) > 2.0         # no hair with a fifth of greys is that dark


def test_the_unrendered_last_step_gives_the_answer_the_rendered_one_gives(tmp_path, monkeypatch):
    """``check_last`` off: the last corrected sigma_a is not rendered. The answer is the one the refinement that
    renders it gives (that render only measures its residual), from one check render instead of two; the residual
    said is the check's colour moved along the curve."""
    from dataclasses import replace

    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path))
    renderer = Renderer(max_cached=2)
    pose = CameraPose(25, 140)
    capture = SceneSpec("swatch", camera=pose, strand_seed=11)
    target = mean_linear(renderer.render(HairParams((200, 60, 40), 0.7, 0.3, 0.4), capture, 32, 32, seed=1).linear)
    prior = HairParams((120, 120, 120), 0.5, 0.5, 0.5)
    rendered = refine(prior, target, pose, replace(SMALL, iterations=2, check_last=True, tolerance_de=0.0), renderer)
    predicted = refine(prior, target, pose, replace(SMALL, iterations=2, check_last=False, tolerance_de=0.0), renderer)
    assert (rendered.iterations, predicted.iterations) == (2, 1)
    assert predicted.params == rendered.params and np.array_equal(predicted.sigma_a, rendered.sigma_a)
    assert predicted.history == rendered.history[:1]
    assert predicted.residual_de2000 == pytest.approx(float(delta_e2000(predicted.rendered, target)), abs=1e-9)
    assert not np.allclose(predicted.rendered, rendered.rendered)   # said from the curve, not measured
