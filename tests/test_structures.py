"""The family of physical swatches, and the estimate on a swatch of a structure it did not assume."""
from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest

from hairdigi.render.domain.bounds import StructureMode, SwatchModel
from hairdigi.render.strands import SWATCH_WIDTH, layered_radius
from hairdigi.render.swatch_family import FAMILY, STRUCTURES, deposit, inside_share, structure_strands


def test_every_structure_builds_deterministically_on_the_holder() -> None:
    for name in STRUCTURES:
        a, b = structure_strands(name, 800, seed=3), STRUCTURES[name](800, 3)    # kept, and built anew
        assert np.array_equal(a.points, b.points), name
        assert structure_strands(name, 800, seed=3) is a and not a.points.flags.writeable, name   # shared: read-only
        assert not np.array_equal(a.points, structure_strands(name, 800, seed=4).points), name
        centre = a.curves().points
        assert np.mean(np.abs(centre[:, 0]) <= SWATCH_WIDTH / 2 + 0.05) > 0.95, name   # on the holder
        assert centre[:, 2].min() > 0, name                                            # above it
    assert set(FAMILY) <= set(STRUCTURES) and "thin" not in FAMILY


def test_the_simulated_rig_hides_its_hair_in_the_structure_named_and_the_judge_renders_those_strands() -> None:
    """``hairdigi rig --sim --hidden-structure`` and ``evaluate --rig --hidden-structures``: the rig's frames
    show a swatch of that structure (a deposited swatch lies higher and darker than the layered one at equal
    sigma_a), cached apart from the layered swatch's, and the judge renders the truth on those strands."""
    from hairdigi.app.evaluation.rig import RigSet, hidden_structure
    from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN, render_light_images
    from hairdigi.render.judge import judge, judge_scene
    from hairdigi.render.metrics import delta_e2000

    size = (80, 60)
    layered = render_light_images(DEFAULT_HIDDEN, size, 4)[0]
    deposited = render_light_images(DEFAULT_HIDDEN, size, 4, swatch_model="deposited")[0]
    again = render_light_images(DEFAULT_HIDDEN, size, 4, swatch_model="deposited")[0]
    assert np.array_equal(deposited, again)                        # kept in the cache under its own key
    centre = (slice(24, 36), slice(32, 48))                        # the swatch, in the middle of the rig's frame
    a, b = (im.sum(0)[centre].reshape(-1, 3).mean(0) for im in (layered, deposited))
    assert delta_e2000(a, b) > 1.0, (a, b)
    assert judge_scene("deposited").swatch_model.value == "deposited"
    assert judge_scene().swatch_model.value == "layered"
    verdict = judge(DEFAULT_HIDDEN, DEFAULT_HIDDEN, judge_scene("deposited"), size=16, spp=4)
    assert verdict.de2000 == 0.0
    other = judge(DEFAULT_HIDDEN, DEFAULT_HIDDEN, judge_scene(), size=16, spp=4)
    assert verdict.truth_linear != other.truth_linear
    config = RigSet(hidden_structures=("deposited", "tilted"))
    assert [hidden_structure(config, k) for k in range(3)] == ["deposited", "tilted", "deposited"]
    assert hidden_structure(RigSet(), 4) is None


def test_structures_long_to_build_are_kept_on_disk_and_a_damaged_file_is_built_again(monkeypatch, tmp_path) -> None:
    """A spread swatch of 8,000 fibres takes 18 s to build: its strands are cached on disk (as response
    curves are), under a name with the geometry's revision; a damaged file is rebuilt, not an error."""
    from hairdigi.render import swatch_family as F

    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path))
    F._built.cache_clear()
    first = structure_strands("deposited", 300, 5)
    (path,) = (tmp_path / "strands").glob("*.npz")
    assert path.name == f"deposited-300-5-r{F.REVISIONS['deposited']}.npz"
    F._built.cache_clear()
    assert np.array_equal(structure_strands("deposited", 300, 5).points, first.points)     # read back
    path.write_bytes(b"not an npz")
    F._built.cache_clear()
    assert np.array_equal(structure_strands("deposited", 300, 5).points, first.points)     # built again
    assert np.load(path)["points"].shape == first.points.shape                              # and saved again
    assert not (tmp_path / "strands" / "layered-300-5-r1.npz").exists()
    structure_strands("layered", 300, 5)                                                     # fast: not kept
    assert not any(p.name.startswith("layered") for p in (tmp_path / "strands").iterdir())
    F._built.cache_clear()


def test_unknown_structure_is_refused_in_one_line() -> None:
    from hairdigi.render.renderer import SceneSpec

    with pytest.raises(ValueError, match="unknown swatch structure 'combed'.*deposited"):
        structure_strands("combed", 100)
    with pytest.raises(ValueError, match="swatch_model 'combed'"):
        SceneSpec("swatch", swatch_model="combed")
    assert SceneSpec("swatch", swatch_model="deposited").swatch_model is SwatchModel.DEPOSITED


def test_a_structure_mode_without_what_it_needs_is_refused_in_one_line(tmp_path, capsys) -> None:
    """``estimate --structure read`` without single-light frames, or any structure mode with --no-refine,
    is one line naming the fix; nothing is written."""
    from hairdigi.app.cli import main

    image = tmp_path / "swatch.png"
    import cv2

    cv2.imwrite(str(image), np.full((64, 64, 3), 90, np.uint8))
    for extra, words in ((["--structure", "read"], "pass --lights"),
                         (["--structure", "family", "--no-refine"], "--no-refine skips")):
        assert main(["estimate", str(image), "--out", str(tmp_path / "p.json"), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and len(err.splitlines()) == 1, err
        assert not (tmp_path / "p.json").exists()


def test_a_records_colour_interval_carries_the_unknown_structure() -> None:
    """The colour interval is widened to the structure mode's measured one where that is wider, its source
    says so, and a narrower one (family) leaves a wider chain interval as it was."""
    from hairdigi.inference.structure import with_structure
    from hairdigi.render.domain.estimate_parts import Uncertainty

    table = {"source": "evaluate --structures", "shipped": {"p68": 2.0, "p95": 2.9}, "family": {"p68": 1.0, "p95": 1.4}}
    chain = Uncertainty(mean_colour_de2000_p68=0.49, mean_colour_de2000_p95=0.71, mean_colour_source="the chain")
    assumed = with_structure(chain, table, "assumed", "layered")
    assert (assumed.mean_colour_de2000_p68, assumed.mean_colour_de2000_p95) == (2.0, 2.9)
    assert "--structure assumed" in assumed.mean_colour_source and assumed.structure.mode is StructureMode.ASSUMED
    wide = replace(chain, mean_colour_de2000_p68=3.38, mean_colour_de2000_p95=5.11)   # an unknown camera's
    family = with_structure(wide, table, "family")
    assert (family.mean_colour_de2000_p68, family.mean_colour_source) == (3.38, "the chain")
    assert with_structure(chain, None, "assumed") == chain                 # no table shipped: unchanged
    # without single-light frames (a RAW still) the family mode states what mapping alone measured
    table["family_unread"] = {"p68": 1.2, "p95": 2.4}
    unread = with_structure(chain, table, "family", frames=False)
    assert (unread.mean_colour_de2000_p68, unread.mean_colour_de2000_p95) == (1.2, 2.4)
    assert "without single-light frames" in unread.mean_colour_source
    assert with_structure(chain, table, "family").mean_colour_de2000_p95 == 1.4
    assert with_structure(chain, table, "read", frames=False) == chain      # no figures for the mode: unchanged


def test_member_spreads_are_each_members_error_were_the_swatch_that_member() -> None:
    """Mapped to the members' mean, a capture's answer is off by each member's colour of it from the mean's."""
    from hairdigi.inference.refine import SIGMA_LEVELS, ResponseCurve
    from hairdigi.inference.structure import FamilyCurves, member_spreads
    from hairdigi.render.metrics import delta_e2000

    sigma = np.asarray(SIGMA_LEVELS, float)
    curve = lambda scale: ResponseCurve(sigma, scale * 0.45 / (1 + 3 * sigma), 0.0, True)   # noqa: E731
    family = FamilyCurves(curve(1.0), {"light": curve(1.2), "mid": curve(1.0), "dark": curve(0.8)})
    answer = np.array([0.3, 0.8, 2.0])
    spreads = member_spreads(answer, family, {"light": 1.0, "mid": 1.0, "dark": 1.0})
    centre = family.mean_of(None)(answer)
    assert spreads["light"] == round(float(delta_e2000(curve(1.2)(answer), centre)), 3) > 0
    assert spreads["mid"] < min(spreads["light"], spreads["dark"])       # the middle member is nearest the mean
    assert set(member_spreads(answer, family, {"dark": 1.0})) == {"dark"}
    assert member_spreads(answer, family, {"dark": 1.0})["dark"] == 0.0   # one member: the mean is itself


def test_deposited_fibres_rest_on_one_another_and_settle() -> None:
    """Dropped fibres pile up (the stack grows with the count) but settle into hollows: a swatch of
    2000 fibres of radius 0.004 stands 3-16 fibre diameters high at its median fibre (measured 12.5;
    stiff fibres bridge the ones they cross, as hair does), not a loose heap."""
    strands = deposit(2000, 0, 0.004)
    z = strands.curves().points[:, 2]
    layers = np.median(z) / (2 * 0.004)
    assert 3 < layers < 16
    few = deposit(200, 0, 0.004).curves().points[:, 2]
    assert np.median(few) < np.median(z) / 3                    # fewer fibres, a lower stack


def test_no_deposited_fibre_lies_inside_another_at_the_default_swatch() -> None:
    """The drawn B-splines, not just their control points, keep out of one another, at the default
    swatch's fibres (8,000 of radius 0.001, which move a radius sideways between control points).
    Measured 0.12% of points more than 2.5% of a radius inside another fibre (0.35% with 2,000 of
    radius 0.004); the former deposit, checked on its control points only, 68% (45%). Mitsuba and
    Cycles rendered that geometry 10% apart, where they agree within 4% on fibres that keep apart."""
    assert inside_share(deposit(8000, 0, layered_radius(8000))) < 0.005
    assert inside_share(deposit(2000, 0, 0.004)) < 0.01


@pytest.mark.slow
def test_structures_render_apart_at_equal_sigma_a() -> None:
    """At equal sigma_a a deposited swatch renders darker than the layered one at the rig's swatch pose
    (what makes an estimate read through one structure wrong for another)."""
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
    from hairdigi.render.metrics import delta_e2000
    from hairdigi.render.renderer import SceneSpec, default_renderer

    renderer, sigma = default_renderer(), np.array([0.35, 0.6, 1.2])
    means = {m: renderer.render(sigma, SceneSpec("swatch", camera=RIG_SWATCH_POSE, swatch_model=m, strands=3000),
                                32, 32, 5).linear.reshape(-1, 3).mean(0) for m in ("layered", "deposited")}
    assert means["deposited"].sum() < means["layered"].sum()
    assert delta_e2000(means["deposited"], means["layered"]) > 0.7


@pytest.mark.slow
def test_the_structure_read_is_the_one_whose_tables_fit_best() -> None:
    """``read_structure`` fits the shine on every member's per-light tables and keeps the best: frames of a
    member in its tables' own layout are read as that member, with their shine and sigma_a. (Another
    layout of the same swatch moves the lights' shares as much as another structure does: read right in 6
    of 35 hidden swatches, ``evaluate --structures``; the mode is measured, not the default.)"""
    from hairdigi.inference.refine import RefineSettings
    from hairdigi.inference.structure import read_structure
    from hairdigi.render.domain.appearance import Appearance
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
    from hairdigi.render.renderer import SceneSpec, default_renderer

    settings = RefineSettings(size=24, spp=16)
    renderer, truth = default_renderer(), np.array([0.35, 0.6, 1.2])
    members = ("layered", "deposited")
    for hidden in members:
        means = np.array([renderer.render(truth, SceneSpec(
            "swatch", camera=RIG_SWATCH_POSE, swatch_model=hidden, strand_seed=settings.strand_seed,
            lights=tuple(float(j == i) for j in range(3)), appearance=Appearance(0.3)), 24, 64, 9)
            .linear.reshape(-1, 3).mean(0) for i in range(3)])
        reading = read_structure(means, RIG_SWATCH_POSE, settings, renderer, members)
        assert reading.swatch_model == hidden, reading.misfits
        assert set(reading.misfits) == set(members) and reading.misfits[hidden] == min(reading.misfits.values())
        assert abs(reading.shine.longitudinal_roughness - 0.3) < 0.06
        assert np.median(np.abs(np.array(reading.shine.sigma_a) / truth - 1)) < 0.1, (hidden, reading.shine.sigma_a)


def test_a_structure_is_read_decisively_only_when_every_other_member_fits_far_worse() -> None:
    """``decisive``: the best member when the next-best misfit is at least ``DECISIVE`` times its own (the
    spread swatch's frames, read at ratios 2.2-9.2 in ``evaluate --structures``), else None (tilted swatches
    in Cycles, misread as deposited at 1.03-1.60); a tie, or one member alone, decides nothing."""
    from hairdigi.inference.structure import DECISIVE, decisive

    assert decisive({"layered": 0.05, "spread": 0.012, "deposited": 0.027}) == "spread"
    assert decisive({"deposited": 0.019, "loose": 0.030, "tilted": 0.041}) is None
    assert decisive({"a": 0.01, "b": 0.01 * DECISIVE}) == "a"
    assert decisive({"a": 0.01, "b": 0.01 * DECISIVE - 1e-4}) is None
    assert decisive({"a": 0.0, "b": 0.0}) is None
    assert decisive({"a": 0.01}) is None
    assert decisive({"a": 0.01, "b": 0.03}, ratio=4.0) is None


@pytest.mark.slow
def test_a_deposited_swatch_is_estimated_within_the_goal_mapped_to_the_family() -> None:
    """A rough saturated red hidden in a deposited swatch (a layout no curve renders), shot through the
    camera model with its single-light frames at the evaluation's settings: mapped to the family's mean,
    its sigma_a rendered back on the hidden strands is within the goal (1.0 ΔE2000) and nearer than
    assumed layered (``evaluate --structures``: 0.37 against 1.75); the record's colour interval and
    its structure entry say which."""
    from hairdigi.inference.encoder import Encoder
    from hairdigi.inference.estimate import estimate_image
    from hairdigi.inference.preprocess import to_linear
    from hairdigi.inference.refine import RefineSettings
    from hairdigi.inference.training.evaluate import capture
    from hairdigi.render.domain.absorption import hair_sigma_a
    from hairdigi.render.domain.appearance import Appearance
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
    from hairdigi.render.metrics import delta_e2000
    from hairdigi.render.renderer import SceneSpec, default_renderer

    renderer, truth = default_renderer(), hair_sigma_a(HairParams((230, 20, 30), 1.0, 0.08, 0.3))
    settings = RefineSettings()

    def shot(sigma, lights=(1.0, 1.0, 1.0), spp=64):
        spec = SceneSpec("swatch", camera=RIG_SWATCH_POSE, swatch_model="deposited", strand_seed=91,
                         lights=lights, appearance=Appearance(0.45))
        return renderer.render(np.asarray(sigma, float), spec, 48, spp, 13).linear

    frame = capture(shot(truth).astype(np.float32), 1)
    singles = [to_linear(capture(shot(truth, tuple(float(j == i) for j in range(3))).astype(np.float32) * 2.8, 2 + i))
               / np.float32(2.8) for i in range(3)]
    goal = shot(truth, spp=128).reshape(-1, 3).mean(0)
    errors, intervals = {}, {}
    for mode in ("family", "assumed"):
        result = estimate_image(frame, Encoder(), light_images=singles, settings=settings, structure=mode)
        back = shot(result.refinement.sigma_a, spp=128).reshape(-1, 3).mean(0)
        errors[mode] = float(delta_e2000(back, goal))
        intervals[mode] = result.uncertainty
    assert errors["family"] < 1.0, errors
    assert errors["family"] < errors["assumed"], errors
    # each record states its mode's figures from the shipped evaluation (or the chain's, where wider); at
    # 95% the assumed swatch's is the wider (held out 13 and 14: 2.86 against 1.45; at 68% they are near,
    # 0.69 and 0.60, since most swatches the rules rescue are read either way)
    from hairdigi.inference.structure import STRUCTURE_TABLE

    table = json.loads(STRUCTURE_TABLE.read_text())
    for mode, key in (("family", "family"), ("assumed", "shipped")):
        stated = intervals[mode]
        assert stated.structure.mode is StructureMode(mode)
        assert stated.structure.mean_colour_de2000_p95 == round(table[key]["p95"], 3), (mode, stated.structure)
        assert stated.mean_colour_de2000_p95 >= table[key]["p95"] - 1e-9, (mode, stated)
    assert intervals["assumed"].mean_colour_de2000_p95 > intervals["family"].mean_colour_de2000_p95


@pytest.mark.slow
def test_two_layouts_of_one_swatch_give_one_answer() -> None:
    """A copper hair hidden in two strand layouts of the default swatch, at the rig's swatch area: the two
    answers, rendered on a third layout, are within the layout nuisance ``hairdigi bench layouts`` states
    (0.25-0.55 ΔE2000 at this 400x300 frame and these settings; 0.6 here), and each fits its own capture."""
    from dataclasses import replace

    from hairdigi.inference.refine import RefineSettings, refine, scene_for
    from hairdigi.render.domain.absorption import hair_sigma_a
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.rig_geometry import RigRegion, swatch_roi
    from hairdigi.render.metrics import delta_e2000
    from hairdigi.render.renderer import default_renderer

    renderer, hair = default_renderer(), HairParams((190, 80, 40), 0.5, 0.5, 0.6)
    view = RigRegion((400, 300), swatch_roi((400, 300)))
    settings = RefineSettings()
    spec, film = scene_for(view, settings)

    def mean(sigma, layout: int) -> np.ndarray:
        return renderer.render(np.asarray(sigma, float), replace(spec, strand_seed=layout), film, 128, 5
                               ).linear.reshape(-1, 3).mean(0)

    answers = []
    for layout in (201, 202):
        capture = mean(hair_sigma_a(hair), layout)
        sigma = refine(hair, capture, view, settings, renderer).sigma_a
        assert delta_e2000(mean(sigma, layout), capture) < 0.6
        answers.append(mean(sigma, 300))
    assert delta_e2000(*answers) < 0.6


def test_to_family_maps_the_answer_to_the_family_mean_and_keeps_flat_channels() -> None:
    """Pure arithmetic on response curves: a family that renders darker at equal sigma_a takes less
    sigma_a for the same colour; a family equal to the default changes nothing; a dark hair, on the
    curves' flat, surface-reflection end, is kept."""
    from hairdigi.inference.refine import SIGMA_LEVELS, ResponseCurve
    from hairdigi.inference.structure import DARK_SIGMA, FamilyCurves, family_weight, nuisance, to_family

    sigma = np.array(SIGMA_LEVELS)
    default = ResponseCurve(sigma, 0.02 + 0.5 * np.exp(-sigma))
    darker = ResponseCurve(sigma, 0.9 * default.mean)
    same = FamilyCurves(default, {"a": default, "b": default})
    family = FamilyCurves(default, {"a": default, "b": darker})
    answer = np.array([0.1, 0.5, 1.3])
    assert np.allclose(to_family(answer, same), answer, rtol=1e-2)   # the curves interpolate: 0.3% round trip
    mapped = to_family(answer, family)
    assert np.all(mapped < answer)
    assert np.allclose(family.mean(mapped), default(answer), rtol=1e-2)   # the same colour on the family's mean
    black = np.full(3, DARK_SIGMA[1] + 1.0)
    assert np.array_equal(to_family(black, family), black)   # a dark hair keeps its answer
    # between, the map applies in part: log-linearly in the least sigma_a, continuous at both ends
    assert family_weight(np.array([DARK_SIGMA[0], 1.0, 2.0])) == 1.0
    assert family_weight(np.array([DARK_SIGMA[1], 1.0, 2.0])) == 0.0
    middle = np.array([np.sqrt(DARK_SIGMA[0] * DARK_SIGMA[1]), 1.0, 2.0])
    assert abs(family_weight(middle) - 0.5) < 1e-9
    part = to_family(middle, family)
    full = family.mean.inverse(family.default(middle))[0]
    assert np.allclose(np.log(part / middle), 0.5 * np.log(full / middle), atol=1e-9)
    spread = nuisance(mapped, family)
    assert spread["a"] > 0 and spread["b"] > 0           # the family's members lie either side of its mean


def test_a_held_out_set_has_no_named_case_and_spans_the_dark_rule(tmp_path) -> None:
    """``--held-out SEED``: other hairs than the ones the rules were chosen on, dark ones across DARK_SIGMA;
    a run cut short keeps its judged rows only for the same settings."""
    from hairdigi.inference.structure import DARK_SIGMA
    from hairdigi.app.evaluation.structures_evaluation import CASES, StructureSet, _resumed, hidden_hairs
    from hairdigi.render.domain.absorption import hair_sigma_a

    named = hidden_hairs(StructureSet(random=3))
    assert [n for n, _, _ in named[:len(CASES)]] == list(CASES)
    held = hidden_hairs(StructureSet(random=6, seed=11))
    assert len(held) == 12 and not {n for n, _, _ in held} & set(CASES)
    assert {h for _, h, _ in held}.isdisjoint({h for _, h, _ in named})
    dark = [hair_sigma_a(h) for n, h, _ in held if n.startswith("dark")]
    light = [hair_sigma_a(h) for n, h, _ in held if n.startswith("random")]
    assert len(dark) == 6 and max(s.min() for s in dark) < 2.5     # dark brown to black ...
    assert min(s.min() for s in dark) > DARK_SIGMA[1]             # ... all beyond the map's reach
    assert min(s.min() for s in dark) > np.median([s.min() for s in light])
    assert hidden_hairs(StructureSet(random=6, seed=11)) == held
    assert hidden_hairs(StructureSet(random=6, seed=12)) != held

    path = tmp_path / "structures_evaluation.json"
    settings = {"size": 48, "spp": 64, "seed": 11}
    path.write_text(json.dumps({"settings": settings, "rows": [{"hidden": "dark 0", "structure": "loose"}]}))
    assert _resumed(path, settings) == [{"hidden": "dark 0", "structure": "loose"}]
    assert _resumed(path, {**settings, "spp": 128}) == []
    path.write_text("{not json")
    assert _resumed(path, settings) == []


#: A held-out hair (``evaluate --structures --held-out 11``'s "random 2"), hidden in a spread swatch.
SPREAD_TRUTH = (35.2, 201.0, 170.9), 0.512, 0.817, 0.549


def _spread_shot(sigma, lights=(1.0, 1.0, 1.0), spp: int = 64) -> np.ndarray:
    """The spread swatch of ``SPREAD_TRUTH`` (``sigma``: its sigma_a; a tuple: its Table 1 parameters) at the
    rig's swatch pose, 48², linear."""
    from hairdigi.render.domain.absorption import hair_sigma_a
    from hairdigi.render.domain.appearance import Appearance
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
    from hairdigi.render.renderer import SceneSpec, default_renderer

    if isinstance(sigma, tuple):
        sigma = hair_sigma_a(HairParams(*sigma))
    spec = SceneSpec("swatch", camera=RIG_SWATCH_POSE, swatch_model="spread", strand_seed=504,
                     lights=lights, appearance=Appearance(0.493))
    return default_renderer().render(np.asarray(sigma, float), spec, 48, spp, 515).linear


def _spread_captures() -> tuple[np.ndarray, list[np.ndarray]]:
    """The spread swatch captured (8-bit, as a camera), and its single-light frames (linear, each at 1/2.8)."""
    from hairdigi.inference.preprocess import to_linear
    from hairdigi.inference.training.evaluate import capture

    frame = capture(_spread_shot(SPREAD_TRUTH).astype(np.float32), 300)
    singles = [to_linear(capture(_spread_shot(SPREAD_TRUTH, tuple(float(j == i) for j in range(3))).astype(np.float32)
                                 * 2.8, 307 + 7 * i)) / np.float32(2.8) for i in range(3)]
    return frame, singles


@pytest.mark.slow
def test_a_swatch_out_of_the_layered_swatchs_reach_is_estimated_on_its_structure_read() -> None:
    """A held-out hair (``evaluate --structures --held-out 11``'s "random 2") hidden in a swatch of spread
    fibres: no hair on the layered swatch renders its colour (the evaluation, on the former spread swatch
    whose fibres sank into one another: residual 1.28, fit 1.70; the spread swatch now stands looser and
    darker still), so even the assumed mode's estimate reads the structure from the single-light frames and keeps it
    (residual under 0.3, fit under 1.0); the record says so, and its interval is the read mode's."""
    from hairdigi.inference.encoder import Encoder
    from hairdigi.inference.estimate import UNREACHED_DE, estimate_image
    from hairdigi.render.metrics import delta_e2000

    frame, singles = _spread_captures()
    result = estimate_image(frame, Encoder(), light_images=singles, structure="assumed")
    said = [w.message for w in result.warnings if w.message.startswith("structure:")]
    assert said and "read from the single-light frames" in said[0], [w.message for w in result.warnings]
    assert result.refinement.region.swatch_model is not SwatchModel.LAYERED
    # kept because it at least halves the layered swatch's residual (over UNREACHED_DE); the residual itself
    # carries the check renders' noise on a swatch of sparse crossing fibres (0.40 and 0.64 on two builds of
    # the tables), so the truth below judges the answer
    layered, read = (float(v) for v in re.findall(r"residual(?: ΔE2000)? ([0-9.]+)\)", said[0])[:2])
    assert layered > UNREACHED_DE and read < layered / 2, said[0]
    assert result.uncertainty.structure.mode is StructureMode.READ
    goal = _spread_shot(SPREAD_TRUTH, spp=128).reshape(-1, 3).mean(0)
    back = _spread_shot(result.refinement.sigma_a, spp=128).reshape(-1, 3).mean(0)
    assert delta_e2000(back, goal) < 1.0
    # the family mode (the default) does not map a swatch its frames tell decisively to the family's mean (where
    # the spread swatch lies far from it: 3.66 in held out 13 before this rule): it refines on the structure read
    family = estimate_image(frame, Encoder(), light_images=singles)
    assert family.refinement.region.swatch_model is SwatchModel.SPREAD, family.refinement.region
    assert family.refinement.region.structure.startswith("read decisively"), family.refinement.region
    assert family.uncertainty.structure.mode is StructureMode.FAMILY
    assert delta_e2000(_spread_shot(family.refinement.sigma_a, spp=128).reshape(-1, 3).mean(0), goal) < 1.0


@pytest.mark.slow
def test_a_still_without_frames_refines_on_the_structure_the_rigs_frames_read_of_the_same_swatch() -> None:
    """A RAW still has no single-light frames: in the family mode it was mapped to the family's mean, and a spread
    swatch's stills came out 2.9-4.1 from the truth through the simulated rig. The rig's own frames of the same
    swatch read its structure decisively (``read_rig_structure``); the still borrows that reading, refines on it,
    and its record says where the reading came from."""
    from hairdigi.inference.encoder import Encoder
    from hairdigi.inference.estimate import estimate_image, read_rig_structure
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
    from hairdigi.render.metrics import delta_e2000

    frame, singles = _spread_captures()
    borrowed = read_rig_structure(frame, singles, RIG_SWATCH_POSE)
    assert borrowed.decided == "spread" and borrowed.frames.swatch_model == "spread", borrowed
    assert borrowed.texture is None          # an all-hair crop has no rig view's texture
    goal = _spread_shot(SPREAD_TRUTH, spp=128).reshape(-1, 3).mean(0)
    still = estimate_image(frame, Encoder(), structure="family", borrowed=borrowed)
    assert still.refinement.region.swatch_model is SwatchModel.SPREAD
    assert "the rig's single-light frames of the same swatch" in still.refinement.region.structure
    assert still.appearance.value.longitudinal_roughness == borrowed.frames.value.longitudinal_roughness
    assert still.uncertainty.structure.mode is StructureMode.FAMILY
    assert delta_e2000(_spread_shot(still.refinement.sigma_a, spp=128).reshape(-1, 3).mean(0), goal) < 1.0


def test_a_still_and_the_live_frames_share_the_familys_curves() -> None:
    """``family_view``: a RAW still of twice the feed's resolution, its swatch found a few pixels off, maps to
    the live frame's canonical region, so the family's curves (12 renders) are not rendered again for each
    still; a region at the frame's edge stays inside it, and a pose (an all-hair crop) is its own view."""
    from hairdigi.inference.structure import FAMILY_FRAME, family_view
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE, RigRegion

    live = family_view(RigRegion((400, 300), (30, 56, 130, 189)))
    still = family_view(RigRegion((800, 600), (61, 113, 259, 377)))
    assert live == still and live.frame_size == (400, 300)
    assert all(v % FAMILY_FRAME[1] == 0 for v in live.roi)
    assert family_view(RigRegion((400, 300), (30, 56, 150, 189))) != live      # another region is another view
    edge = family_view(RigRegion((1000, 750), (990, 740, 10, 10)))
    x, y, w, h = edge.roi
    assert w > 0 and h > 0 and x + w <= edge.frame_size[0] and y + h <= edge.frame_size[1]
    assert family_view(RIG_SWATCH_POSE) is RIG_SWATCH_POSE


def test_the_texture_tells_streaks_along_the_fibres_from_an_even_top_whichever_way_they_run() -> None:
    """Pure image statistics: dark voids that run down the image (fibres dropped one by one) correlate along
    the fibres and orient the texture; the noise of an even top of fibres does neither; turning the image
    keeps the orientation order; an area too small is refused in one line."""
    from hairdigi.inference.texture import streaks

    rng = np.random.default_rng(3)
    even = 0.2 * np.exp(rng.normal(0.0, 0.2, (160, 120, 1))) * np.ones(3, np.float32)
    voids = np.ones((160, 120), np.float32)
    for x in rng.choice(120, 18, replace=False):
        voids[:, x] *= 0.4                                     # a void's shadow, the length of the area
    streaked = even * voids[..., None]
    a, b = streaks(even), streaks(streaked)
    assert abs(a.along) < 0.02 and a.order < 0.2, a
    assert b.along > 0.1 and b.order > 0.5, b
    turned = streaks(np.ascontiguousarray(streaked.transpose(1, 0, 2)), fibre_axis=1)
    assert abs(turned.along - b.along) < 0.02 and abs(turned.order - b.order) < 0.05, (turned, b)
    with pytest.raises(ValueError, match="at least"):
        streaks(even[:8, :8])
    with pytest.raises(ValueError, match="fibre_axis"):
        streaks(even, fibre_axis=2)


def test_the_texture_weights_the_family_mean_and_its_record_says_so() -> None:
    """A streak-free texture weights the members the family map averages (``FamilyCurves.mean_of``): their mean
    lies nearer the layered swatch than the whole family's, and the record line names the class, the statistics
    and the weights; an undecided or streaked texture keeps the whole family."""
    from hairdigi.inference.refine import SIGMA_LEVELS, ResponseCurve
    from hairdigi.inference.structure import TEXTURE_MEMBERS, FamilyCurves, TextureReading, to_family

    sigma = np.array(SIGMA_LEVELS)
    layered = ResponseCurve(sigma, 0.02 + 0.5 * np.exp(-sigma))
    members = {m: ResponseCurve(sigma, (1.0 if m in TEXTURE_MEMBERS["streak-free"] else 0.8) * layered.mean)
               for m in FAMILY}
    family = FamilyCurves(layered, members)
    answer = np.array([0.1, 0.5, 1.3])
    free = TextureReading("streak-free", 0.001, 0.1)
    undecided = TextureReading(None, 0.02, 0.1)
    assert undecided.weights is None
    whole = to_family(answer, family)
    narrowed = to_family(answer, family, weights=free.weights)
    assert np.all(np.abs(np.log(narrowed / answer)) < np.abs(np.log(whole / answer)))
    assert np.allclose(to_family(answer, family, weights=undecided.weights), whole)
    line = free.describe()
    assert "streak-free" in line and "0.001" in line and "layered 1" in line, line
    assert "undecided" in undecided.describe()
    # a streaked texture keeps the whole family (its own members alone took deposited answers dark, through the rig)
    streaked = TextureReading("streaked", 0.1, 0.9)
    assert streaked.weights is None and np.allclose(to_family(answer, family, weights=streaked.weights), whole)
    assert streaked.describe().endswith("every member kept"), streaked.describe()
    # streaks beyond any member's (the family's rig frames at most 0.287, a coarse deposit) are no structure of
    # the family's: the estimate flags them (the clumped swatch read 0.350-0.478)
    assert not streaked.unmodelled and not TextureReading("streaked", 0.287, 0.99).unmodelled
    assert TextureReading("streaked", 0.35, 0.99).unmodelled


@pytest.mark.slow
def test_the_rigs_frames_of_a_layered_and_a_deposited_swatch_read_apart_by_their_texture(tmp_path) -> None:
    """``hairdigi bench streaks --quick``: the simulated rig's live frames of the demo's copper (two noise seeds,
    the camera model's) and its RAW still (a 12-bit DNG of twice the resolution, read back through rawpy and
    scaled to the canonical width): the layered swatch reads streak-free, the deposited one streaked, and the
    bench writes its table, summary and plot."""
    from hairdigi.app.cli import main

    assert main(["bench", "streaks", "--quick", "--out", str(tmp_path)]) == 0
    saved = json.loads((tmp_path / "streaks.json").read_text())
    summary = {**saved["summary"], "rows": saved["rows"]}
    kinds = {(r["member"], r["source"], r["kind"]) for r in summary["rows"]}
    assert kinds == {("layered", "live", "streak-free"), ("layered", "raw still", "streak-free"),
                     ("deposited", "live", "streaked"), ("deposited", "raw still", "streaked")}, summary["rows"]
    assert len(summary["rows"]) == 6
    assert summary["shares"]["layered"] == {"streak-free": 1.0, "n": 3}
    assert (tmp_path / "streaks.csv").stat().st_size > 0 and (tmp_path / "streaks.png").stat().st_size > 1000


def test_frames_no_structure_fits_are_flagged_and_state_a_wider_interval() -> None:
    """``unmodelled``: where even the best member's misfit is over ``UNMODELLED_MISFIT`` (the family's own swatches
    read at most 0.036 through the rig), no structure of the family fits; the record's interval is then what a
    structure outside the family measured, and says so."""
    from hairdigi.inference.structure import STRUCTURE_TABLE, UNMODELLED_MISFIT, unmodelled, with_structure
    from hairdigi.render.domain.estimate_parts import Uncertainty

    assert unmodelled({"layered": 0.09, "deposited": 0.074}) == 0.074
    assert unmodelled({"layered": 0.09, "deposited": 0.036}) is None
    assert unmodelled({"a": UNMODELLED_MISFIT}) is None and unmodelled(None) is None and unmodelled({}) is None
    table = json.loads(STRUCTURE_TABLE.read_text())
    chain = Uncertainty(mean_colour_de2000_p68=0.5, mean_colour_de2000_p95=1.0)
    known, unknown = (with_structure(chain, table, "family", None, modelled=m) for m in (True, False))
    assert known.mean_colour_de2000_p95 == pytest.approx(table["family"]["p95"], abs=1e-3)
    assert unknown.mean_colour_de2000_p95 == pytest.approx(table["unmodelled"]["p95"], abs=1e-3)
    assert "a structure none of the family fits" in unknown.mean_colour_source and "clumped" in unknown.mean_colour_source


@pytest.mark.slow
def test_a_clumped_swatch_outside_the_family_is_flagged_and_a_deposited_one_is_not(tmp_path) -> None:
    """Through the simulated rig (the default mode): a swatch of clumped fibres, drawn outside the family, fits no
    member's per-light tables at the rig's region and is flagged with the wider interval; a deposited one is not.
    (An all-hair crop of the clumped swatch's centre reads as deposited, misfit 0.011: the rig's whole region, its
    clumps and the gaps between them, is what no member fits.) On platinum hair the frames fit a member, but the
    texture's streaks are stronger than any member's, so it is flagged too; and the clumps' gaps read as a third
    grey to the texture model (fitted on the layered swatch): the record keeps no grey share and says why."""
    from hairdigi.app.session.rig_session import RigSession
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.records import WarningKind

    def record(model: str, hair: HairParams = HairParams((190, 80, 40), 0.5, 0.5, 0.6)):
        session = RigSession.simulated_rig(tmp_path / f"{model}-{hair.melanin_concentration}", hidden=hair, spp=16,
                                           swatch_model=model)
        try:
            session.calibrate()
            return session.capture().record
        finally:
            session.close()

    clumped, deposited = record("clumped"), record("deposited")
    flagged = [w.message for w in clumped.warnings if w.kind is WarningKind.STRUCTURE]
    assert flagged and "no swatch structure hairdigi draws" in flagged[0], [w.message for w in clumped.warnings]
    assert clumped.uncertainty.mean_colour_de2000_p95 >= 4.7
    platinum = record("clumped", HairParams((245, 240, 225), 0.15, 0.04, 0.2))
    appearance = platinum.appearance
    assert appearance.value.grey_fraction == 0.0 and "grey_fraction" not in appearance.measured
    assert appearance.method["grey_fraction"].startswith("not read: the texture tells greys only on the layered "
                                                         "swatch"), appearance.method
    # its frames fit a member (light hair's frames misfit every structure less), but its texture's streaks
    # are stronger than any member's: flagged all the same, with the wider interval
    flagged = [w.message for w in platinum.warnings if w.kind is WarningKind.STRUCTURE]
    assert flagged and "the swatch's texture shows streaks along the fibres" in flagged[0], platinum.warnings
    assert platinum.uncertainty.mean_colour_de2000_p95 >= 4.7
    assert not [w for w in deposited.warnings if w.kind is WarningKind.STRUCTURE], deposited.warnings
    assert deposited.uncertainty.mean_colour_de2000_p95 < 2.0
