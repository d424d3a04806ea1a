"""The simulated rig end to end: chart detection, CCM, exposure, dead lights, capture, staleness."""
import json
import time

import numpy as np

from hairdigi.render.judge import judge
from hairdigi.render.srgb import linear_to_srgb8
import pytest

from hairdigi.app.session.blockers import BlockerKind
from hairdigi.app.session.rig_session import RigSession
from hairdigi.hardware.cameras import FileCamera
from hairdigi.hardware.exposure import ExposureStatus, check_region
from hairdigi.hardware.sim_rig import SIM_SIZE, SimRig
from hairdigi.render.domain.rig_geometry import swatch_roi
from hairdigi.render.camera_model import CameraModel
from hairdigi.inference.calibration import (CalibrationError, apply_profile, calibrate, detect_chart, load_profile,
                                            staleness)
from hairdigi.render.chart import colorchecker_reflectances, rig_chart_targets

SPP = 8


def frame(model=CameraModel(), dead=()):
    return SimRig(camera=model, spp=SPP, dead_lights=set(dead)).read().srgb


def test_chart_is_found_where_the_rig_puts_it():
    det = detect_chart(frame())
    assert det.box[:, 0].min() > 180 and det.box[:, 0].max() < 395  # the chart is right of the swatch
    assert det.patches_srgb8[18].mean() > det.patches_srgb8[23].mean() + 100  # white 9.5 vs black 2


def test_ccm_removes_a_colour_cast():
    img = frame(CameraModel(cast=(1.3, 1.0, 0.7), exposure_ev=-0.4))
    for method in ("Cheung 2004", "Finlayson 2015", "Vandermonde"):
        p = calibrate(img, method)
        assert p.delta_e2000["before"]["mean"] > 5
        assert p.delta_e2000["after"]["mean"] <= 2.0, (method, p.delta_e2000)
    corrected = apply_profile(img, p)
    assert corrected.dtype == np.float32           # linear and unquantised, all the way to the estimate
    again = calibrate(linear_to_srgb8(corrected), linear=corrected)   # the corrected frame already matches the targets
    assert again.delta_e2000["before"]["mean"] < 2.5


def test_targets_are_the_rendered_chart():
    targets, source = rig_chart_targets()
    assert "rendered in the rig" in source
    reflect = colorchecker_reflectances()
    lit = reflect > 0.02   # the cyan patch has no red at all
    ratio = targets[lit] / reflect[lit]
    assert np.all((ratio > 0.5) & (ratio < 0.9))  # reflectance times the rig's irradiance


def test_exposure_check_flags_over_and_under_exposure():
    roi = swatch_roi(SIM_SIZE)
    over = check_region(frame(CameraModel(exposure_ev=2.5)), roi, "swatch")
    under = check_region(frame(CameraModel(exposure_ev=-5.0)), roi, "swatch")
    fine = check_region(frame(), roi, "swatch")
    assert over.status is ExposureStatus.OVER and str(over.status) == "over" and over.suggested_ev < 0
    assert under.status is ExposureStatus.UNDER and under.suggested_ev > 0
    assert fine.status is ExposureStatus.OK


def test_dead_light_is_caught(tmp_path):
    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP, dead={2})
    try:
        assert session.check_lights() == [2]
        assert all(s.on for s in session.light_states())   # the board still says all on
    finally:
        session.close()
    session = RigSession.simulated_rig(tmp_path / "t", spp=SPP)
    try:
        assert session.check_lights() == []
    finally:
        session.close()


def test_toggling_a_light_changes_the_next_frame(tmp_path):
    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP)
    try:
        full = session.frame().srgb.mean()
        session.set_light(0, False)
        assert session.frame().srgb.mean() < full - 5
        session.set_all(False)
        assert session.frame().srgb.mean() < 8
    finally:
        session.close()


def test_capture_is_saved_before_processing_and_blocked_when_uncalibrated(tmp_path):
    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP)
    try:
        result = session.capture()
        assert result.image_path.exists() and result.meta_path.exists()
        meta = json.loads(result.meta_path.read_text())
        assert meta["calibration_id"] is None and len(meta["image_sha256"]) == 64 and meta["lights"]
        assert any(b.kind is BlockerKind.UNCALIBRATED and "not calibrated" in b.message for b in result.blocked)
        assert result.params is None
        record = json.loads((result.image_path.parent / f"{result.capture_id}.result.json").read_text())
        assert record["blocked"] == [b.message for b in result.blocked]
    finally:
        session.close()


def test_no_chart_in_view_blocks_and_explains(tmp_path):
    img = frame()
    img[:, 190:] = 90   # cover the chart
    with pytest.raises(CalibrationError, match="no ColorChecker found"):
        detect_chart(img)


def test_profile_staleness_and_errors(tmp_path):
    p = calibrate(frame())
    assert staleness(p, p.settings) == []
    assert "old" in staleness(p, now=time.time() + 9 * 3600)[0]
    assert "settings changed" in staleness(p, {"camera": "other"})[0]
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(CalibrationError, match="calibrate again"):
        load_profile(tmp_path / "bad.json")
    with pytest.raises(CalibrationError, match="calibrate the rig first"):
        load_profile(tmp_path / "none.json")


def test_session_replays_a_recorded_frame(tmp_path):
    import cv2
    cv2.imwrite(str(tmp_path / "f.png"), frame()[..., ::-1])
    session = RigSession(FileCamera(tmp_path / "f.png"), None, tmp_path / "s", swatch_roi(SIM_SIZE))
    profile = session.calibrate()
    assert profile.delta_e2000["after"]["mean"] < 2
    result = session.capture(estimate=False)
    assert result.image_path.exists() and not result.blocked


@pytest.mark.slow
def test_estimate_of_a_rig_capture_matches_the_rig_chain(tmp_path, tiny_model):
    """``hairdigi estimate`` on a saved rig frame (chart in view, swatch found) gives the rig's estimate."""
    from hairdigi.app.cli import main
    from hairdigi.inference.encoder import Encoder

    _, onnx_path, _ = tiny_model
    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP, encoder=Encoder(onnx_path))
    try:
        session.calibrate()
        result = session.capture()
    finally:
        session.close()
    assert result.params is not None and not result.blocked
    out = tmp_path / "cli.json"
    assert main(["estimate", str(result.image_path), "--calibration", str(session.profile_path),
                 "--model", str(onnx_path), "--out", str(out)]) == 0
    cli = json.loads(out.read_text())
    rig = result.record.to_json()
    x, y, w, h = cli["provenance"]["roi"]
    tx, ty, tw, th = session.swatch_roi
    shared = max(0, min(x + w, tx + tw) - max(x, tx)) * max(0, min(y + h, ty + th) - max(y, ty))
    assert shared >= 0.85 * tw * th                      # the swatch, not the chart
    # the same hair: each fits the swatch area it found (the CLI's finder, the rig's geometry) and
    # renders that same area, so their absorptions agree where it counts, at the rig's swatch pose
    assert cli["refinement"]["region"]["roi"] == [x, y, w, h]
    # ... each with the appearance it read (a grey share read in one and not the other moves the median fibre)
    from hairdigi.render.domain.records import EstimateRecord
    looks = (EstimateRecord.from_json(cli).appearance.value, result.record.appearance.value)
    assert judge(cli["refinement"]["sigma_a"], rig["refinement"]["sigma_a"], looks=looks).de2000 < 0.5


def test_a_changed_camera_exposure_makes_the_profile_stale(tmp_path):
    """Every camera reports its settings; the simulated sensor's exposure change is seen as stale."""
    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP)
    try:
        session.calibrate()
        assert staleness(session.profile, session.settings()) == []
        session.camera.camera.exposure_ev = 0.5            # the operator turns the exposure up
        reasons = staleness(session.profile, session.settings())
        assert reasons and "exposure_ev" in reasons[0]
    finally:
        session.close()


def test_a_real_camera_reports_its_settings(tmp_path):
    """An OpenCV camera (here a video file through cv2.VideoCapture) reports what the driver does."""
    from media import write_video

    from hairdigi.hardware.cameras import OpenCVCamera

    path = write_video(tmp_path / "feed.avi", size=(96, 64))
    camera = OpenCVCamera(str(path))
    try:
        settings = camera.settings()
        assert settings["width"] == 96 and settings["height"] == 64 and "exposure" in settings
        assert camera.read().meta["camera_settings"] == settings
        session = RigSession(camera, None, tmp_path / "s")
        assert session.settings()["width"] == 96 and session.settings()["camera"] == camera.name
    finally:
        camera.close()


def test_an_old_capture_is_reviewed_with_its_own_calibration(tmp_path):
    """A later calibration replaces calibration.json; the earlier capture keeps the profile it was taken with."""
    from hairdigi.inference.calibration import apply_profile

    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP)
    try:
        first = session.calibrate()
        shot = session.capture(estimate=False)
        session.camera.camera.cast = (1.3, 1.0, 0.7)        # the light or white balance changes
        second = session.calibrate()
        assert second.id != first.id and load_profile(session.profile_path).id == second.id
        loaded = session.load_capture(shot.capture_id)
    finally:
        session.close()
    assert loaded.profile.id == first.id
    x, y, w, h = loaded.roi
    expected = apply_profile(loaded.frame[y:y + h, x:x + w].copy(), first)
    assert np.array_equal(loaded.corrected_swatch_linear(), expected)
    assert not np.array_equal(expected, apply_profile(loaded.frame[y:y + h, x:x + w].copy(), second))


def test_a_raw_still_of_the_rig_is_a_capture_calibrated_on_its_own_chart(tmp_path):
    """A still camera's DNG of the rig (its own colour cast and exposure): copied into the session
    first, calibrated on the chart in the still, estimated, and reviewed later with that profile."""
    from hairdigi.hardware.sim_still import write_raw_still

    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP)
    try:
        session.calibrate()
        live = session.capture()
        # a still camera of twice the feed's resolution (each 2 x 2 Bayer cell sees one feed pixel),
        # with a colour cast and an exposure of its own
        radiance = session.camera.radiance().repeat(2, axis=0).repeat(2, axis=1)
        still = write_raw_still(tmp_path / "IMG_0001.dng", radiance * np.array([1.25, 1.0, 0.8]) * 0.7)
        result = session.import_still(still)
        loaded = session.load_capture(result.capture_id)
    finally:
        session.close()
    assert result.image_path.read_bytes() == still.read_bytes()          # kept as shot, before processing
    assert not result.blocked and result.params is not None
    assert result.record.provenance.calibration["delta_e2000_after"]["mean"] < 1.5
    # the same swatch as the live capture (each renders its own swatch area): the same hair, judged
    # at the rig's swatch pose
    looks = (result.record.appearance.value, live.record.appearance.value)   # each with the greys it read
    assert judge(result.record.refinement.sigma_a, live.record.refinement.sigma_a, looks=looks).de2000 < 1.0
    assert loaded.profile is not None and loaded.frame.shape == radiance.shape


def test_a_file_that_is_not_a_raw_still_is_refused_before_anything_is_written(tmp_path):
    from hairdigi.app.session.rig_session import import_still

    png = tmp_path / "frame.png"
    png.write_bytes(b"not used")
    with pytest.raises(ValueError, match="not a RAW still"):
        import_still(tmp_path / "s", png, "no encoder needed")
    assert not (tmp_path / "s").exists()


def test_rig_still_on_the_command_line(tmp_path, capsys):
    """``hairdigi rig --still``: no camera or board; the still's file is refused if it is not RAW."""
    from hairdigi.app.cli import main
    from hairdigi.hardware.sim_still import write_raw_still

    png = tmp_path / "x.png"
    png.write_bytes(b"\x89PNG")
    assert main(["rig", "--still", str(png), "--session", str(tmp_path / "s")]) == 2
    assert "not a RAW still" in capsys.readouterr().err
    rig = SimRig(spp=SPP)
    still = write_raw_still(tmp_path / "IMG_2.dng", (rig.radiance() * 0.8).repeat(2, 0).repeat(2, 1))
    assert main(["rig", "--still", str(still), "--session", str(tmp_path / "s")]) == 0
    out = capsys.readouterr().out
    assert "calibrated on the still's own chart" in out and "estimate in" in out
    assert len(list((tmp_path / "s" / "captures").glob("*.dng"))) == 1


def test_the_shipped_chart_targets_are_the_chart_rendered_in_todays_rig():
    """``resources/charts/rig_chart_targets.json`` is ``render_chart_targets``' output: a change to the
    rig's lights, holder or chart that would make calibration aim at stale targets fails here."""
    from hairdigi.render.chart_targets import render_chart_targets
    from hairdigi.render.metrics import delta_e2000

    shipped, source = rig_chart_targets()
    assert source.startswith("rendered in the rig")
    fresh = render_chart_targets(spp=32)
    de = delta_e2000(fresh, shipped)
    assert de.mean() < 0.5 and de.max() < 1.5, de


@pytest.mark.slow
def test_an_over_exposed_swatch_is_captured_again_as_the_operator_is_told(tmp_path):
    """Glossy white hair's glints clip at the bench's exposure; the evaluations then do what the message
    says (``capture_as_told``): lower the exposure, calibrate again, capture again."""
    from hairdigi.app.session.blockers import EXPOSURE_STEP_EV, capture_as_told
    from hairdigi.render.domain.appearance import Appearance
    from hairdigi.render.domain.params import HairParams

    white = HairParams((255, 255, 255), 0.0, 0.0, 0.3)
    session = RigSession.simulated_rig(tmp_path / "session", hidden=white, spp=8,
                                       appearance=Appearance(longitudinal_roughness=0.12))
    try:
        session.calibrate()
        first = session.capture()
        assert [b.kind for b in first.blocked] == [BlockerKind.OVER_EXPOSED], first.blocked
        assert "lower the exposure" in first.blocked[0].message
        result, profile = capture_as_told(session)
        assert result.record is not None, result.blocked
        assert profile is not None and session.camera.camera.exposure_ev <= -EXPOSURE_STEP_EV
    finally:
        session.close()


def test_a_still_borrows_no_reading_from_an_uncalibrated_rig_nor_from_a_board_that_is_gone(tmp_path):
    """``RigSession.borrowed_reading`` (a RAW still in the family mode takes the rig's own reading of the swatch):
    frames corrected by no calibration are not read, and a light board that stops answering leaves the still to
    be estimated without the reading, not the import failing."""
    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP, structure="family")
    try:
        assert session.borrowed_reading() is None
        session.calibrate()
        session._board.close()
        assert session.borrowed_reading() is None
    finally:
        session.close()
