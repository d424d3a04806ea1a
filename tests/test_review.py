"""The review model without Qt: warm scenes reused by a capture, the encoder's estimate first and the
refined one after, stale renders cancelled by a new capture, and the ΔE2000 map."""
import dataclasses
import subprocess
import sys
import threading

import numpy as np
import pytest

from hairdigi.app import review
from hairdigi.app.rig_session import RigSession
from hairdigi.inference.encoder import Encoder
from hairdigi.render.metrics import delta_e2000, delta_e_map

SMALL = review.PreviewSettings(twin_passes=((0.5, 1), (1.0, 1)), twin_clean_spp=((0.5, 1), (1.0, 1)), hairstyle_size=48, hairstyle_strands=200,
                               hairstyle_passes=(1, 1), hairstyle_clean_spp=2, view_strands=100)


@pytest.fixture
def calibrated(tmp_path, tiny_model):
    session = RigSession.simulated_rig(tmp_path / "s", spp=8, encoder=Encoder(tiny_model[1]))
    session.calibrate()
    yield session
    session.close()


def test_the_model_imports_without_qt():
    code = ("import sys, hairdigi.app.review; "
            "print(sorted(m for m in ('PySide6', 'pyvista', 'pyvistaqt', 'vtk') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]"


def test_events_call_their_subscribers_in_order():
    events, seen = review.Events(), []
    first = events.twin.connect(lambda v: seen.append(("a", v)))
    events.twin.connect(lambda v: seen.append(("b", v)))
    events.twin.emit(1)
    events.twin.disconnect(first)
    events.twin.emit(2)
    assert seen == [("a", 1), ("b", 1), ("b", 2)]


def test_a_capture_shows_the_encoder_first_then_the_refined_estimate_in_warm_scenes(calibrated, tmp_path):
    model = review.ReviewModel(calibrated, SMALL)
    warmed = model.warm_work()(model.apply, lambda: False)
    assert {"twin", "hairstyle"} <= set(warmed.seconds)
    assert (model.twin_renderer.builds, model.style_renderer.builds) == (2, 1)   # the twin at 2 scales

    stages, twins, passes = [], [], []
    model.events.shown.connect(lambda shown: stages.append(shown.stage))
    model.events.parameters.connect(lambda shown: run_previews(model))
    model.events.twin.connect(twins.append)
    model.events.hairstyle.connect(passes.append)
    captured = model.capture_work()(model.apply, lambda: False)
    model.apply(captured)

    assert stages == ["encoder", "refined"]
    assert model.shown.capture_id == captured.result.capture_id and model.shown.record["refinement"]["ran"]
    # the encoder's look renders one pass; the refined estimate its whole schedule
    # half resolution first, then full; the first look is one pass, rendered by the capture worker
    assert [(t.stage, t.scale, t.spp) for t in twins] == [("encoder", 0.5, 1), ("refined", 0.5, 1), ("refined", 1.0, 1)]
    assert [(p.stage, p.spp) for p in passes] == [("encoder", 1), ("refined", 1), ("refined", 2)]
    # the warm scenes were reused: the capture only updated parameters
    assert (model.twin_renderer.builds, model.style_renderer.builds) == (2, 1)
    twin = model.twin
    assert twin.final and twin.clean_enough and twin.raw.shape == twin.clean.shape == (*model.shown.real.shape[:2], 3)
    assert twin.delta_e_map.shape == model.shown.real.shape[:2] and np.isfinite(twin.delta_e)
    # numbers come from the raw pass: the chip is the raw twin's mean
    np.testing.assert_allclose(twin.hair_linear, twin.raw.reshape(-1, 3).mean(0))

    # the orbit moves the camera of the warm scene: no rebuild
    model.set_view(orbit=(30, 10))
    before = model.hairstyle.raw.copy()
    model.hairstyle_work()(model.apply, lambda: False)
    assert model.style_renderer.builds == 1 and not np.allclose(model.hairstyle.raw, before)

    written = model.save_render("hairstyle", tmp_path / "look")
    assert [p.name for p in written] == ["look.png", "look.exr"]


def run_previews(model):
    """What the window does on ``parameters``: the twin's and the hairstyle's passes (here, in turn)."""
    for work in (model.twin_work(), model.hairstyle_work()):
        work(model.apply, lambda: False)


def test_a_new_capture_cancels_stale_renders(calibrated):
    model = review.ReviewModel(calibrated, dataclasses.replace(SMALL, hairstyle_passes=(1,) * 40, warm=False))
    model.apply(model.capture_work()(model.apply, lambda: False))
    first = model.shown.capture_id
    model.twin_work()(model.apply, lambda: False)                   # the twin goes first, as in the window
    reported, started = [], threading.Event()

    def report(p):
        reported.append(p)
        started.set()
    work = model.hairstyle_work()
    thread = threading.Thread(target=work, args=(report, lambda: False))
    thread.start()
    assert started.wait(120)
    captured = model.capture_work()(model.apply, lambda: False)   # a new capture, while the render runs
    thread.join(120)
    assert not thread.is_alive() and 1 <= len(reported) < 40        # it stopped at its next pass
    for stale in reported:                                          # and what it reported late is dropped
        model.apply(stale)
    assert model.hairstyle.stage == "encoder" and model.hairstyle.key == model.shown.key   # the new first look
    assert all(stale.key != model.shown.key for stale in reported)
    model.apply(captured)
    assert model.shown.capture_id != first and model.hairstyle.key == model.shown.key


def test_the_delta_e_map_shows_colour_differences_not_noise():
    rng = np.random.default_rng(0)
    base = np.full((40, 50, 3), (0.20, 0.12, 0.06))
    noisy = base * rng.uniform(0.5, 1.5, base.shape)                # render-like noise, mean kept
    assert delta_e_map(base, base, 2.0).max() < 1e-9
    assert delta_e_map(base, noisy, 2.0).mean() < 0.5 * delta_e_map(base, noisy, 0.0).mean()
    shifted = base * (1.0, 0.9, 0.8)
    expected = float(delta_e2000(base[0, 0], shifted[0, 0]))
    np.testing.assert_allclose(delta_e_map(base, shifted, 2.0), expected, rtol=1e-6)


def test_one_open_rig_serves_the_command_line_and_the_window(tmp_path):
    from hairdigi.hardware.cameras import CameraError
    from hairdigi.app.rig_session import open_rig

    with pytest.raises(CameraError, match="no camera at"):          # the command line: the error, as it is
        open_rig(tmp_path / "a", camera=str(tmp_path / "no-camera.mp4"))
    session, why = open_rig(tmp_path / "b", camera=str(tmp_path / "no-camera.mp4"), fallback=True)  # the window
    try:
        assert session.simulated and "no camera at" in why and why.endswith("using the simulated rig")
    finally:
        session.close()
