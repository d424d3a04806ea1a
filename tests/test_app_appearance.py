"""The app's part of reading the appearance: the light selector (each captured frame beside its twin lit the same
way), the appearance (shine, fibre spread, grey share) with its intervals in the parameters panel,
and the twin and hairstyles rendered with the estimated appearance.

One simulated session serves the module: an older capture without single-light frames (the "shine
not measured" kind), then a capture with them (the first renders the view's per-light tables once).
"""
import dataclasses
import json
import threading

import numpy as np
import pytest

from hairdigi.app.models.work import run_now
from hairdigi.app.review import model as review
from hairdigi.app.review.payloads import LightView
from hairdigi.app.review.previews import PreviewSettings
from hairdigi.app.session.rig_session import RigSession
from hairdigi.inference.calibration import apply_profile
from hairdigi.inference.encoder import Encoder
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance, AppearanceEstimate
from hairdigi.render.domain.records import WarningKind
from hairdigi.render.metrics import mean_colour_delta_e
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear

SMALL = PreviewSettings(twin_passes=((1.0, 2),), twin_clean_spp=((1.0, 1),), hairstyle_size=48,
                        hairstyle_strands=200, hairstyle_passes=(1,), hairstyle_clean_spp=1, view_strands=100,
                        warm=False, denoise=False)


@pytest.fixture(scope="module")
def captured(tmp_path_factory, tiny_model):
    """(session, old capture id, new capture id): calibrated, one capture without and one with light frames."""
    session = RigSession.simulated_rig(tmp_path_factory.mktemp("appearance") / "s", spp=8,
                                       encoder=Encoder(tiny_model[1]))
    session.calibrate()
    old = session.capture(per_light=False)
    new = session.capture()
    assert not old.blocked and not new.blocked
    yield session, old.capture_id, new.capture_id
    session.close()


def model_on(session, capture_id):
    model = review.ReviewModel(session, SMALL)
    run_now(model.reload_work(), model.apply)
    run_now(model.select_work(capture_id), model.apply)
    return model


@pytest.mark.slow
def test_a_newer_selection_wins_over_an_older_read_that_comes_back_later(captured):
    session, old, new = captured
    model = review.ReviewModel(session, SMALL)
    run_now(model.reload_work(), model.apply)
    assert {e.id for e in model.records} == {old, new}
    older, newer = model.select_work(old), model.select_work(new)
    late = run_now(older, lambda value: None)           # read, but back after the newer one
    run_now(newer, model.apply)
    model.apply(late)
    assert late.capture_id == old and model.shown.capture_id == new


def test_the_window_reads_records_and_captures_off_the_ui_thread(qtbot, captured, monkeypatch):
    """Which thread read the records and a capture back is recorded in the real readers, which still run."""
    from hairdigi.app.gui.main_window import MainWindow
    from hairdigi.app.session import rig_session as rs

    session, old, new = captured
    records_in, captures_in = [], []
    load_results, load_capture = rs.load_results, session.load_capture
    monkeypatch.setattr(rs, "load_results",
                        lambda folder: records_in.append(threading.get_ident()) or load_results(folder))
    monkeypatch.setattr(session, "load_capture",
                        lambda capture_id: captures_in.append((threading.get_ident(), capture_id)) or load_capture(capture_id))
    ui = threading.get_ident()
    win = MainWindow(session, {**dataclasses.asdict(SMALL), "feed_fps": 5}, strand_view=False)
    qtbot.addWidget(win)
    qtbot.waitUntil(lambda: win.model.shown is not None and win.model.shown.capture_id == new, timeout=20000)
    assert win.session_list.count() == 2 and win.session_list.currentItem().text().startswith(new)
    win.session_list.setCurrentRow([e.id for e in win.model.records].index(old))
    qtbot.waitUntil(lambda: win.model.shown.capture_id == old, timeout=20000)
    assert records_in and {new, old} <= {capture_id for _, capture_id in captures_in}      # the work was seen
    assert ui not in records_in and ui not in [thread for thread, _ in captures_in]
    win.close()


def test_the_window_saves_a_render_exports_and_reads_the_calibration_off_the_ui_thread(qtbot, captured, monkeypatch,
                                                                                      tmp_path):
    """Which thread wrote the render and the export, and read the calibration's status, is recorded in the real
    writers and reader, which still run."""
    from hairdigi.app.gui.main_window import MainWindow
    from hairdigi.app.session import rig_session as rs
    from hairdigi.render.io import images

    session, _, new = captured
    threads = {"png": [], "exr": [], "export": [], "calibration": []}

    def recorded(name, fn):
        return lambda *a, **k: threads[name].append(threading.get_ident()) or fn(*a, **k)
    monkeypatch.setattr(images, "save_png", recorded("png", images.save_png))
    monkeypatch.setattr(images, "save_exr", recorded("exr", images.save_exr))
    monkeypatch.setattr(rs, "export_records", recorded("export", rs.export_records))
    monkeypatch.setattr(session, "calibration_status", recorded("calibration", session.calibration_status))
    ui = threading.get_ident()
    win = MainWindow(session, {**dataclasses.asdict(SMALL), "feed_fps": 5}, strand_view=False)
    qtbot.addWidget(win)
    qtbot.waitUntil(lambda: win.model.twin is not None and win.model.shown.capture_id == new, timeout=120000)
    qtbot.waitUntil(lambda: "ΔE2000" in win.calibration_label.text(), timeout=20000)
    saving = win.save_render("twin", tmp_path / "twin")
    exporting = win.export(tmp_path / "all.json")
    qtbot.waitUntil(lambda: saving not in win.tasks and exporting not in win.tasks, timeout=60000)
    assert (tmp_path / "twin.png").stat().st_size > 0 and (tmp_path / "twin.exr").stat().st_size > 0
    assert json.loads((tmp_path / "all.json").read_text())["count"] == 2
    assert all(threads.values()), threads                                   # the work was seen
    assert not [name for name, seen in threads.items() if ui in seen], threads
    win.close()


def test_light_1_shows_its_frame_beside_the_twin_lit_by_light_1_alone(captured):
    session, _, new = captured
    model = model_on(session, new)
    loaded = session.load_capture(new)
    assert len(loaded.light_frames) == 3 and all(f is not None for f in loaded.light_frames)
    seen = []
    model.events.light_view.connect(seen.append)

    model.set_light_view(1)
    assert seen == [LightView(1)] and model.light == 1
    spec, _ = model.twin_scene(1.0)
    assert spec.lights == (0.0, 1.0, 0.0)
    # the captured side is light 1's own frame, corrected with the capture's profile, on the all-lights scale
    x, y, w, h = loaded.roi
    expected = linear_to_srgb8(apply_profile(loaded.light_frames[1][y:y + h, x:x + w], loaded.profile)
                               / np.float32(loaded.light_exposures[1]))
    np.testing.assert_array_equal(model.captured_image(), expected)
    assert not np.array_equal(model.captured_image(), model.shown.real)
    assert not np.array_equal(model.captured_image(), model.shown.light_frames[0])

    run_now(model.twin_work(), model.apply)
    lit_1 = model.twin
    assert lit_1.light == 1 and lit_1.final
    # the twin lit by light 1 alone matches light 1's frame (not the all-lights one) in colour
    de_own = mean_colour_delta_e(srgb8_to_linear(expected), lit_1.raw)
    de_all = mean_colour_delta_e(srgb8_to_linear(model.shown.real), lit_1.raw)
    assert de_own < de_all and de_own < 8, (de_own, de_all)

    model.set_light_view(None)
    assert model.twin_scene(1.0)[0].lights == (1.0, 1.0, 1.0)
    np.testing.assert_array_equal(model.captured_image(), model.shown.real)
    run_now(model.twin_work(), model.apply)
    assert model.twin.light is None
    assert model.twin.raw.mean() > 1.5 * lit_1.raw.mean()      # one light of three: about a third
    with pytest.raises(ValueError, match="lights 0 to 2"):
        model.set_light_view(3)


def test_an_old_capture_says_it_has_no_frame_for_the_light(captured):
    session, old, _ = captured
    model = model_on(session, old)
    assert model.shown.light_frames == ()
    model.set_light_view(2)
    assert model.captured_image() is None
    assert model.captured_text() == "no frame for light 2 in this capture"
    assert model.twin_work() is None and not model.busy()     # nothing renders, nothing waits for it
    # its shine is the default, said so, with the record's warning
    view = model.parameter_view()
    lines = dict(view.appearance)
    assert lines["longitudinal_roughness"] == "shine β_m: 0.30 — not measured (default)"
    assert any(w.kind == WarningKind.APPEARANCE for w in model.shown.record.warnings)
    assert "shine not measured" in view.info


def test_the_twin_and_hairstyles_render_the_records_appearance(captured):
    session, _, new = captured
    model = model_on(session, new)
    record = model.shown.record
    assert record.appearance is not None and record.appearance.shine_measured
    value = record.appearance.value        # previews render its shine and spread, its grey share to 0.05
    look = dataclasses.replace(value, grey_fraction=round(round(value.grey_fraction / 0.05) * 0.05, 4))
    assert model.hairstyle_spec().look == look and model.twin_scene(1.0)[0].look == look
    assert abs(model.hairstyle_spec().look.grey_fraction - value.grey_fraction) <= 0.025

    varied = Appearance(0.2, 0.3, 0.1)                  # a grey share on the previews' 0.05 steps
    estimate = AppearanceEstimate(varied, {"longitudinal_roughness": {"p68": [0.18, 0.22], "p95": [0.15, 0.25]}},
                                  ("longitudinal_roughness", "fibre_spread", "grey_fraction"))
    model.shown = dataclasses.replace(model.shown, record=dataclasses.replace(record, appearance=estimate))
    assert model.hairstyle_spec().appearance == varied and model.hairstyle_spec().groups > 0
    model.set_view(style="bob")
    assert model.hairstyle_spec().appearance == varied
    assert model.twin_scene(0.5)[0].appearance == varied
    lines = dict(model.parameter_view().appearance)
    assert lines == {"longitudinal_roughness": "shine β_m: 0.20 (68%: 0.18–0.22)", "fibre_spread": "fibre spread: 0.30",
                     "grey_fraction": "grey share: 10%"}
    # a record without an appearance renders the default (uniform) hair
    model.shown = dataclasses.replace(model.shown, record=dataclasses.replace(record, appearance=None))
    assert model.hairstyle_spec().appearance is None and model.hairstyle_spec().look == DEFAULT_APPEARANCE


def test_the_window_shows_the_shine_with_its_interval_and_the_light_selector(qtbot, captured):
    from hairdigi.app.gui.main_window import MainWindow

    session, old, new = captured
    win = MainWindow(session, {**dataclasses.asdict(SMALL), "feed_fps": 5}, strand_view=False)
    qtbot.addWidget(win)
    win.show()
    qtbot.waitUntil(lambda: win.model.shown is not None and win.model.shown.capture_id == new, timeout=20000)
    appearance = win.model.shown.record.appearance
    lo, hi = appearance.intervals["longitudinal_roughness"]["p68"]
    text = win.appearance_labels["longitudinal_roughness"].text()
    assert text == f"shine β_m: {appearance.value.longitudinal_roughness:.2f} (68%: {lo:.2f}–{hi:.2f})"
    assert "not measured" in win.appearance_labels["fibre_spread"].text() or "68%" in \
        win.appearance_labels["fibre_spread"].text()

    win.light_view_buttons[1].click()
    assert win.model.light == 1 and win.light_view_buttons[1].isChecked()
    assert win.real_label.pixmap() is not None and not win.real_label.pixmap().isNull()
    qtbot.waitUntil(lambda: win.model.twin is not None and win.model.twin.light == 1, timeout=120000)
    qtbot.waitUntil(lambda: "light 1 alone" in win.twin_info.text(), timeout=20000)

    ids = [e.id for e in win.model.records]
    win.session_list.setCurrentRow(ids.index(old))             # an old capture, light 1 still chosen
    qtbot.waitUntil(lambda: win.model.shown.capture_id == old, timeout=20000)   # read back in a worker
    assert win.real_label.text() == "no frame for light 1 in this capture"
    assert "not measured" in win.appearance_labels["longitudinal_roughness"].text()
    assert "shine not measured" in win.result_info.text()
    win.light_view_buttons[None].click()                       # all lights: the old capture's own frame again
    assert win.model.light is None and win.light_view_buttons[None].isChecked()
    shown = win.real_label.pixmap()
    assert win.real_label.text() == "" and not shown.isNull()
    np.testing.assert_allclose(mean_rgb(shown), win.model.shown.real.reshape(-1, 3).mean(0), atol=2)
    win.close()


def mean_rgb(pixmap) -> np.ndarray:
    """The mean 8-bit R, G, B of what a label shows."""
    img = pixmap.toImage().convertToFormat(pixmap.toImage().Format.Format_RGB888)
    rows = np.frombuffer(img.constBits(), np.uint8, img.sizeInBytes()).reshape(img.height(), img.bytesPerLine())
    return rows[:, :3 * img.width()].reshape(-1, 3).mean(0)
