"""The appearance record, fibre groups, one frame per light, the shine in the estimate, and
``estimate --lights``."""
import numpy as np
import pytest

from hairdigi.render.domain.appearance import Appearance, AppearanceError, AppearanceEstimate
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import EstimateRecord, WarningKind
from hairdigi.render.fibres import FIBRE_GROUPS, group_sigma_a, group_z, split_strands
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.strands import swatch_strands

SIGMA = np.array([0.35, 0.6, 1.2])


# --- the record -------------------------------------------------------------------------------
def test_appearance_values_are_checked_and_named():
    with pytest.raises(AppearanceError, match="fibre_spread"):
        Appearance(fibre_spread=-0.1)
    with pytest.raises(AppearanceError, match="grey_fraction"):
        Appearance(grey_fraction=float("nan"))
    assert not Appearance().varied and Appearance(grey_fraction=0.1).varied


def test_an_estimate_record_keeps_its_appearance_and_one_without_still_loads():
    est = AppearanceEstimate(Appearance(0.21, 0.3, 0.1), {"longitudinal_roughness": {"p68": [0.19, 0.23]}},
                             ("longitudinal_roughness", "fibre_spread", "grey_fraction"))
    record = EstimateRecord(hair=HairParams(), appearance=est)
    back = EstimateRecord.from_json(record.to_json())
    assert back.appearance == est and back.appearance.shine_measured
    plain = record.to_json()
    del plain["appearance"]
    assert EstimateRecord.from_json(plain).appearance is None
    plain["appearance"] = {"longitudinal_roughness": 7.0}
    with pytest.raises(RecordError, match="appearance.*longitudinal_roughness"):
        EstimateRecord.from_json(plain)


# --- fibre groups -------------------------------------------------------------------------------
def test_strands_split_into_equal_groups_and_the_stated_grey_share():
    strands = swatch_strands(400, seed=1)
    parts = split_strands(strands, 6, 0.25, seed=3)
    sizes = [p.n_strands for p in parts]
    assert sum(sizes) == 400 and sizes[-1] == 100 and max(sizes[:-1]) - min(sizes[:-1]) <= 1
    z = group_z(FIBRE_GROUPS)
    assert abs(z.mean()) < 1e-9 and abs(np.sqrt(np.mean(z ** 2)) - 1) < 1e-9
    sig = group_sigma_a(SIGMA, FIBRE_GROUPS, 0.4)
    assert np.allclose(np.exp(np.std(np.log([s[0] for s in sig[:-1]]))), np.exp(0.4))


def test_a_grouped_render_matches_a_single_group_of_equal_sigma():
    """Fibre groups of one sigma_a render as one shape does (the split costs no colour), while a
    spread or grey fibres change it."""
    renderer = Renderer(max_cached=2)
    one = renderer.render(SIGMA, SceneSpec("swatch"), 32, 16, seed=5).linear.reshape(-1, 3).mean(0)
    grouped = renderer.render(SIGMA, SceneSpec("swatch", fibre_groups=FIBRE_GROUPS), 32, 16,
                              seed=5).linear.reshape(-1, 3).mean(0)
    assert np.allclose(one, grouped, rtol=0.03), (one, grouped)   # layered swatch: 2.3% apart in red at worst
    greys = renderer.render(SIGMA, SceneSpec("swatch", appearance=Appearance(grey_fraction=0.3)), 32, 16,
                            seed=5).linear.reshape(-1, 3).mean(0)
    assert np.all(greys > 1.2 * one)


# --- capture and estimate on the simulated rig ---------------------------------------------------
@pytest.fixture(scope="module")
def glossy_rig(tmp_path_factory):
    """The simulated rig with a glossy hidden swatch (shine 0.18), calibrated."""
    from hairdigi.app.session.rig_session import RigSession

    session = RigSession.simulated_rig(tmp_path_factory.mktemp("glossy"), HairParams((190, 80, 40), 0.5, 0.5, 0.6),
                                       spp=16, appearance=Appearance(0.18))
    session.calibrate()
    yield session
    session.close()


@pytest.mark.slow
def test_a_capture_takes_one_frame_per_light_and_reads_the_shine(glossy_rig):
    from hairdigi.render.domain.records import CaptureRecord, read_record

    result = glossy_rig.capture()
    capture = read_record(result.meta_path, CaptureRecord)
    assert len(capture.light_images) == 3 and len(capture.light_exposures) == 3
    assert all((result.meta_path.parent / name).is_file() for name in capture.light_images)
    assert [st.on for st in glossy_rig.light_states()] == [True] * 3          # the board is restored
    look = result.record.appearance
    assert look.shine_measured and abs(look.value.longitudinal_roughness - 0.18) <= 0.05, look
    lo, hi = look.intervals["longitudinal_roughness"]["p95"]
    assert lo <= look.value.longitudinal_roughness <= hi
    assert not any("shine not measured" in w.message for w in result.record.warnings)


@pytest.mark.slow
def test_a_capture_without_light_frames_says_the_shine_was_not_measured(glossy_rig):
    result = glossy_rig.capture(per_light=False)
    assert result.record.appearance is not None and not result.record.appearance.shine_measured
    notes = [w for w in result.record.warnings if w.kind is WarningKind.APPEARANCE]
    assert notes and "shine not measured" in notes[0].message


@pytest.mark.slow
def test_a_capture_missing_a_light_frame_fails_with_one_line(glossy_rig, tmp_path):
    import subprocess
    import sys

    result = glossy_rig.capture(estimate=False)
    folder = result.meta_path.parent
    from hairdigi.render.domain.records import CaptureRecord, read_record

    names = read_record(result.meta_path, CaptureRecord).light_images
    (folder / names[1]).unlink()
    loaded = glossy_rig.load_capture(result.capture_id)
    assert len([p for p in loaded.problems if names[1] in p]) == 1
    assert loaded.light_frames[1] is None and loaded.light_frames[0] is not None
    out = subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "estimate", str(result.image_path),
                          "--lights", ",".join(str(folder / n) for n in names), "--out", str(tmp_path / "e.json")],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    lines = [line for line in out.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and names[1] in lines[0], out.stderr
    out = subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "estimate", str(result.image_path),
                          "--lights", ",".join(str(folder / n) for n in (names[0], names[2])),
                          "--out", str(tmp_path / "e.json")], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "not 3" in out.stderr and len(out.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_a_light_of_another_colour_is_warned_about(glossy_rig):
    """One profile corrects every light's frame; a light whose LED is another colour tints the chart's
    greys in its own frame, and the estimate says so."""
    images = glossy_rig.camera.light_images
    original = images[1].copy()
    try:
        images[1] *= np.array([1.25, 1.0, 0.75], np.float32)
        glossy_rig.calibrate()
        tinted = glossy_rig.capture()
    finally:
        images[1] = original
        glossy_rig.calibrate()
    assert any("light 1 tints" in w.message for w in tinted.record.warnings), tinted.record.warning_messages()
    assert not any(f"light {i} tints" in w.message for i in (0, 2) for w in tinted.record.warnings), \
        tinted.record.warning_messages()      # the odd light out is named, not the two whose mean it moves
    assert not any("tints" in w.message for w in glossy_rig.capture().record.warnings)


def test_a_hidden_swatch_file_may_carry_an_appearance_and_a_bad_one_is_named(tmp_path):
    import json

    from hairdigi.app.cli.rig import hidden_appearance
    from hairdigi.render.domain.params import HairParamsError

    hair = {"dye_rgb": [190, 80, 40], "dye_concentration": 0.5, "melanin_concentration": 0.5, "melanin_ratio": 0.6}
    path = tmp_path / "hidden.json"
    path.write_text(json.dumps({"hair": hair}))
    assert hidden_appearance(path) is None
    path.write_text(json.dumps({"hair": hair, "appearance": {"longitudinal_roughness": 0.2, "grey_fraction": 0.1}}))
    assert hidden_appearance(path) == Appearance(0.2, 0.0, 0.1)
    path.write_text(json.dumps({"hair": hair, "appearance": {"grey_fraction": 2}}))
    with pytest.raises(HairParamsError, match="hidden.json.*grey_fraction"):
        hidden_appearance(path)


def test_a_grey_share_is_reported_only_when_its_95_percent_interval_excludes_none():
    """Uniform hair reads a few per cent of greys from its glints (0.07-0.12 on the layered swatch, 68%
    intervals clear of 0): only a share whose 95% interval excludes 0 is told from none."""
    from hairdigi.inference.appearance_reading import _reaches_zero

    uniform_copper = {"p68": [0.019, 0.155], "p95": [0.0, 0.21]}       # the demo's uniform copper, as read
    assert _reaches_zero(uniform_copper)
    assert not _reaches_zero({"p68": [0.13, 0.27], "p95": [0.08, 0.32]})   # a fifth of greys
    assert not _reaches_zero(None)


def test_a_share_reported_as_none_says_it_was_not_told_from_none():
    """A grey share set to 0 by the 95% rule while its 68% interval excludes 0 is not shown as
    "0.00 (68%: 0.02-0.16)", which reads as a contradiction, but as not told from none."""
    from hairdigi.app.review.text import appearance_lines
    from hairdigi.app.cli.rig import appearance_lines as cli_lines
    from hairdigi.render.domain.appearance import AppearanceEstimate

    intervals = {"grey_fraction": {"p68": [0.019, 0.155], "p95": [0.0, 0.21]},
                 "longitudinal_roughness": {"p68": [0.29, 0.31], "p95": [0.27, 0.33]}}
    estimate = AppearanceEstimate(Appearance(0.3, 0.0, 0.0), intervals, ("longitudinal_roughness", "grey_fraction"))
    cli = dict(zip(("shine", "spread", "grey"), cli_lines(estimate)))
    assert cli["grey"] == "grey share 0.00 (not told from none; 95%: 0.00-0.21)"
    assert cli["shine"] == "shine 0.30 (68%: 0.29-0.31)"
    window = dict(appearance_lines(estimate))
    assert window["grey_fraction"].endswith("(not told from none; 95%: 0%–21%)")
    assert "(68%: 0.29–0.31)" in window["longitudinal_roughness"]


def test_greys_are_kept_only_on_the_swatch_the_texture_model_was_fitted_on():
    """The texture tells greys on the layered swatch alone: an estimate made on another member, or mapped to the
    family's mean, states its grey share as not read, and says why; the shine read stays."""
    from hairdigi.app.cli.rig import appearance_lines as cli_lines
    from hairdigi.inference.appearance_reading import AppearanceReading, on_its_structure
    from hairdigi.render.domain.appearance import AppearanceEstimate

    intervals = {"grey_fraction": {"p68": [0.25, 0.35], "p95": [0.2, 0.4]},
                 "longitudinal_roughness": {"p68": [0.29, 0.31], "p95": [0.27, 0.33]}}
    greys = AppearanceReading(AppearanceEstimate(Appearance(0.3, 0.0, 0.3), intervals,
                                                 ("longitudinal_roughness", "grey_fraction"),
                                                 {"grey_fraction": "read from the texture"}))
    assert on_its_structure(greys, "layered") is greys
    for made_on, said in ((None, "the family's mean"), ("deposited", "the deposited swatch")):
        kept = on_its_structure(greys, made_on)
        assert kept.value == Appearance(0.3, 0.0, 0.0) and kept.estimate.measured == ("longitudinal_roughness",)
        assert said in kept.estimate.method["grey_fraction"] and "layered" in kept.estimate.method["grey_fraction"]
        assert "grey_fraction" not in kept.estimate.intervals and "longitudinal_roughness" in kept.estimate.intervals
        assert dict(zip(("shine", "spread", "grey"), cli_lines(kept.estimate)))["grey"].startswith("grey share 0.00")
    shine_only = AppearanceReading(AppearanceEstimate(Appearance(0.3), {}, ("longitudinal_roughness",)))
    assert on_its_structure(shine_only, "deposited") is shine_only
