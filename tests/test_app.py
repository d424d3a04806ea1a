"""A full simulated session through the window (pytest-qt, offscreen): lights, calibrate, capture,
estimate, twin preview, hairstyle render, export, unplug banner, restart, screenshot."""
import json
import threading

import numpy as np
import pytest

from hairdigi.app.review import thumbnails
from hairdigi.app.review.previews import Stage
from hairdigi.app.gui.main_window import MainWindow
from hairdigi.app.session.rig_session import RigSession
from hairdigi.inference.encoder import Encoder
from hairdigi.render.hairfile import write_hair
from hairdigi.render.strands import hairstyle_strands

FAST = {"hairstyle_size": 48, "hairstyle_strands": 200, "hairstyle_passes": (1, 1), "hairstyle_clean_spp": 2,
        "twin_passes": ((0.5, 1), (1.0, 1)), "twin_clean_spp": ((0.5, 1), (1.0, 1)), "view_strands": 100, "feed_fps": 10}


def open_window(qtbot, folder, onnx_path):
    session = RigSession.simulated_rig(folder, spp=8, encoder=Encoder(onnx_path))
    win = MainWindow(session, FAST, strand_view=False)
    qtbot.addWidget(win)
    win.show()
    qtbot.waitUntil(lambda: win.last_frame is not None, timeout=20000)
    return win, session


def pixmap_array(pixmap):
    """A pixmap's pixels, (h, w, 3) uint8: a copy, made while the QImage that holds them is alive."""
    img = pixmap.toImage().convertToFormat(pixmap.toImage().Format.Format_RGB888)
    rows = np.frombuffer(img.constBits(), np.uint8, img.sizeInBytes()).reshape(img.height(), img.bytesPerLine())
    return rows[:, :3 * img.width()].reshape(img.height(), img.width(), 3).copy()


@pytest.mark.slow
def test_full_simulated_session(qtbot, tiny_model, tmp_path, test_output, monkeypatch):
    _, onnx_path, _ = tiny_model
    folder = tmp_path / "session"
    win, session = open_window(qtbot, folder, onnx_path)
    board = session._board
    _toggle_a_light(qtbot, win, board)
    profile = _calibrate(qtbot, win)
    result, varied = _capture(qtbot, win)
    _check_the_twin_views(win, tmp_path)
    _orbit_and_open_hair_models(qtbot, win, tmp_path, varied)
    _check_a_new_selection_cancels_the_stale_render(qtbot, win)
    _check_the_export(qtbot, win, tmp_path, onnx_path, session)
    shot = win.grab()
    shot.save(str(test_output / "app_after_capture.png"))
    assert pixmap_array(shot).std() > 10               # not a blank window
    _unplug_the_board(qtbot, win, board, folder, result)
    win.close()
    session.close()
    _check_the_restart(qtbot, folder, onnx_path, profile, monkeypatch)


def _toggle_a_light(qtbot, win, board) -> None:
    qtbot.waitUntil(lambda: win.light_buttons[1].isChecked(), timeout=10000)
    win.light_buttons[1].click()                       # light 1 off
    qtbot.waitUntil(lambda: not board.state.on[1], timeout=10000)
    win.light_buttons[1].click()                       # and on again
    qtbot.waitUntil(lambda: board.state.on[1], timeout=10000)


def _calibrate(qtbot, win):
    with qtbot.waitSignal(win.calibrated, timeout=120000) as cal:
        win.calibrate_button.click()
    assert cal.args[0].delta_e2000["after"]["mean"] < cal.args[0].delta_e2000["before"]["mean"]
    qtbot.waitUntil(lambda: "ΔE2000" in win.calibration_label.text(), timeout=20000)    # read in a worker
    return cal.args[0]


def _capture(qtbot, win):
    """The capture, its estimate, twin and hairstyle passes: (the capture's result, whether the hair is varied)."""
    # the first capture of a session reads the shine against the view's per-light tables: the warm-up
    # renders them (96 small renders), and the capture waits for them the first time
    with qtbot.waitSignal(win.captured, timeout=400000) as cap:
        win.capture_button.click()
    result = cap.args[0]
    assert result.params is not None and not result.blocked
    assert result.image_path.exists() and result.meta_path.exists()
    qtbot.waitUntil(lambda: "ΔE2000" in win.match_label.text(), timeout=120000)
    qtbot.waitUntil(lambda: win.render_progress.value() == len(FAST["hairstyle_passes"]), timeout=120000)
    qtbot.waitUntil(lambda: win.model.twin is not None and win.model.twin.stage is Stage.REFINED
                    and win.model.twin.final, timeout=120000)
    # the scenes were built by the warm-up: the capture only updated parameters
    # (a grey share read makes fibre groups: a new structure, built once more at each scale)
    varied = int(win.model.shown.record.appearance.value.varied)
    assert (win.model.twin_renderer.builds, win.model.style_renderer.builds) == (2 + 2 * varied, 1 + varied)
    return result, varied


def _check_the_twin_views(win, tmp_path) -> None:
    # the chips: the estimated hair colour (the twin's mean) and the dye, each labelled
    assert win.chip.text() == "hair" and win.dye_chip.text() == "dye"
    assert win.chip.styleSheet() != win.dye_chip.styleSheet()
    # the raw path-traced twin is one click away, and shows at once (no re-render)
    denoised = pixmap_array(win.synth_label.pixmap()).copy()
    win.denoise_box.setChecked(False)
    assert not np.array_equal(pixmap_array(win.synth_label.pixmap()), denoised)
    win.denoise_box.setChecked(True)
    saved = win.model.save_render("twin", tmp_path / "twin.png")
    assert [p.suffix for p in saved] == [".png", ".exr"] and all(p.stat().st_size > 0 for p in saved)


def _orbit_and_open_hair_models(qtbot, win, tmp_path, varied: int) -> None:
    # the camera orbits: the hairstyle re-renders from the warm scene
    win.orbit_sliders[0].setValue(30)
    with qtbot.waitSignal(win.hairstyle_done, timeout=120000):
        pass
    assert win.model.orbit == (30.0, 0.0) and win.model.style_renderer.builds == 1 + varied

    # a .hair model opens as a hairstyle; a bad one shows its error in the banner, and the app goes on
    good, bad = tmp_path / "bob.hair", tmp_path / "cut.hair"
    write_hair(good, hairstyle_strands("bob", 60))
    bad.write_bytes(good.read_bytes()[:300])
    with qtbot.waitSignal(win.hairstyle_done, timeout=120000):
        win.open_hair_model(good)
    assert win.style_box.currentText() == "bob.hair" and "bob.hair" in win.render_progress.format()
    win.open_hair_model(bad)
    qtbot.waitUntil(lambda: win.banner.isVisible(), timeout=60000)
    assert "cut.hair" in win.banner.text() and "truncated" in win.banner.text()
    win.banner.hide()
    win.style_box.setCurrentText("straight")
    assert win.model.hair_file is None


def _check_a_new_selection_cancels_the_stale_render(qtbot, win) -> None:
    # no event is processed in between: the job started for "straight" is still the window's
    old = win.render_task
    assert old is not None and not old.is_cancelled
    win.style_box.setCurrentText("curly")
    assert old.is_cancelled and win.render_task is not old
    with qtbot.waitSignal(win.hairstyle_done, timeout=120000):
        pass


def _check_the_export(qtbot, win, tmp_path, onnx_path, session) -> None:
    task = win.export(tmp_path / "all.json")           # written in a worker
    qtbot.waitUntil(lambda: task not in win.tasks, timeout=20000)
    exported = tmp_path / "all.json"
    assert win.statusBar().currentMessage() == f"exported to {exported}"
    record = json.loads(exported.read_text())
    assert record["hair"]["dye_rgb"] and record["provenance"]["model"]["sha256"] == Encoder(onnx_path).sha256
    assert record["provenance"]["calibration"]["id"] == session.profile.id
    # refined after the capture, off the UI thread, and the residual is shown with the warnings list
    assert record["refinement"]["ran"] and record["refinement"]["residual_de2000"] >= 0
    assert isinstance(record["warnings"], list) and "residual ΔE2000" in win.result_info.text()


def _unplug_the_board(qtbot, win, board, folder, result) -> None:
    # the light board vanishes: a banner, and nothing captured is lost
    board.unplug()
    win.light_buttons[0].click()
    qtbot.waitUntil(lambda: win.banner.isVisible(), timeout=20000)
    assert "light board" in win.banner.text() and str(folder) in win.banner.text()
    assert result.image_path.exists()


def _check_the_restart(qtbot, folder, onnx_path, profile, monkeypatch) -> None:
    # restart: the session, its calibration and its capture come back
    on_ui_thread = []                 # per thumbnail read from disk: was it the UI thread that read it?
    read = thumbnails.read_thumbnail
    monkeypatch.setattr(thumbnails, "read_thumbnail", lambda *a, **k: on_ui_thread.append(
        threading.current_thread() is threading.main_thread()) or read(*a, **k))
    win2, session2 = open_window(qtbot, folder, onnx_path)
    qtbot.waitUntil(lambda: win2.session_list.count() == 1, timeout=20000)     # the records are read in a worker
    assert session2.profile.id == profile.id
    assert "blocked" not in win2.session_list.item(0).text()
    # its thumbnail comes from a worker, not from a disk read on the UI thread, and the icon shows it
    qtbot.waitUntil(lambda: not win2.session_list.item(0).icon().isNull(), timeout=20000)
    assert on_ui_thread and not any(on_ui_thread), on_ui_thread
    thumb = win2.model.thumbnails[win2.model.records[0].id]
    assert thumb.shape == (48, 64, 3)
    np.testing.assert_array_equal(pixmap_array(win2.session_list.item(0).icon().pixmap(64, 48)), thumb)
    win2.close()
    session2.close()


def test_uncalibrated_capture_is_kept_and_blocked(qtbot, tiny_model, tmp_path):
    _, onnx_path, _ = tiny_model
    win, session = open_window(qtbot, tmp_path / "s", onnx_path)
    with qtbot.waitSignal(win.captured, timeout=120000) as cap:
        win.capture_button.click()
    result = cap.args[0]
    assert result.params is None and any("not calibrated" in b.message for b in result.blocked)
    assert result.image_path.exists()
    assert "blocked" in win.session_list.item(0).text()
    with pytest.raises(ValueError, match="nothing to export"):
        win.export(tmp_path / "x.json")
    win.close()
    session.close()


@pytest.mark.slow
def test_a_raw_still_is_a_capture_source_in_the_window(qtbot, tiny_model, tmp_path):
    """File > Import RAW still: the still joins the session as a capture, calibrated on its own chart."""
    from hairdigi.hardware.sim_still import write_raw_still

    _, onnx_path, _ = tiny_model
    win, session = open_window(qtbot, tmp_path / "s", onnx_path)
    still = write_raw_still(tmp_path / "IMG_7.dng", (session.camera.radiance() * 0.8).repeat(2, 0).repeat(2, 1))
    with qtbot.waitSignal(win.captured, timeout=120000) as cap:
        win.import_still(still)
    result = cap.args[0]
    assert not result.blocked and result.params is not None
    assert result.image_path.suffix == ".dng" and result.image_path.read_bytes() == still.read_bytes()
    qtbot.waitUntil(lambda: win.session_list.count() == 1, timeout=20000)
    win.close()
    session.close()


def test_a_capture_cancelled_before_a_worker_took_it_is_still_taken():
    """Closing the window right after Capture cancels every task; one cancelled before a worker picked it up
    never started, so the capture asked for was lost (the window-close test failed so under load). A task
    that must start takes its first step anyway, and its generator runs the capture to its end; any other
    cancelled task does not start."""
    from hairdigi.app.gui.workers import Task

    for must_start, expected in ((True, ["started", "finished"]), (False, [])):
        steps: list[str] = []

        def work():
            steps.append("started")
            try:
                yield "first look"
            finally:
                steps.append("finished")      # the capture's thread is joined here, as capture_passes does

        task = Task(work, "capture", must_start=must_start)
        task.cancel()                         # before any worker ran it
        task.run()
        assert steps == expected, must_start


def test_a_tasks_expected_failure_says_its_fix_and_a_bug_says_it_is_one(capsys):
    """A task that fails with a ``HairdigiError`` shows its message (the problem and the fix) as it is; any other
    exception is a bug: the banner says so and names it, and its traceback goes to the log."""
    from hairdigi.app.gui.workers import Task
    from hairdigi.app.library.store import LibraryError

    for error, expected in ((LibraryError("the library is read-only; make it writable"),
                             "library: the library is read-only; make it writable"),
                            (KeyError("rows"), "library failed: KeyError: 'rows' (a bug in hairdigi")):
        said: list[str] = []

        def fail(error=error):
            raise error

        task = Task(fail, "library")
        task.signals.failed.connect(said.append)
        task.run()
        assert len(said) == 1 and said[0].startswith(expected), said
        assert ("Traceback" in capsys.readouterr().err) == isinstance(error, KeyError)


def test_a_capture_that_ends_after_its_window_is_gone_touches_nothing(qtbot, tiny_model, tmp_path):
    """A capture still in flight when the window closes finishes later: its slots must not touch the
    deleted window (it raised 'Internal C++ object (QPushButton) already deleted'); the capture is kept."""
    from shiboken6 import Shiboken

    _, onnx_path, _ = tiny_model
    session = RigSession.simulated_rig(tmp_path / "s", spp=8, encoder=Encoder(onnx_path))
    win = MainWindow(session, {**FAST, "warm": False}, strand_view=False)   # not added to qtbot: deleted here
    win.show()
    qtbot.waitUntil(lambda: win.last_frame is not None, timeout=60000)
    win.capture()
    win.close()                        # waits for the pool: the capture's signals are queued, not yet delivered
    Shiboken.delete(win)               # the window's widgets are gone, as after the app's own close
    qtbot.wait(300)                    # the queued done/finished arrive now: an error here fails the test
    assert list((tmp_path / "s" / "captures").glob("*.json"))
    session.close()
