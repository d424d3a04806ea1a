"""The review model without Qt: warm scenes reused by a capture, the encoder's estimate first and the
refined one after, stale renders cancelled by a new capture, and the ΔE2000 map."""
import dataclasses
import subprocess
import sys
import threading

import numpy as np
import pytest

from hairdigi.app.models.events import Status
from hairdigi.app.models.work import run_now
from hairdigi.app.review import model as review
from hairdigi.app.review.payloads import Captured, Events, Shown
from hairdigi.app.review.previews import PreviewSettings, Stage, TwinPreview
from hairdigi.app.session.rig_session import RigSession
from hairdigi.inference.encoder import Encoder
from hairdigi.render.domain.estimate_parts import ParameterInterval, SpectralInterval, Uncertainty
from hairdigi.render.metrics import delta_e2000, delta_e_map

SMALL = PreviewSettings(twin_passes=((0.5, 1), (1.0, 1)), twin_clean_spp=((0.5, 1), (1.0, 1)), hairstyle_size=48, hairstyle_strands=200,
                               hairstyle_passes=(1, 1), hairstyle_clean_spp=2, view_strands=100)


@pytest.fixture
def calibrated(tmp_path, tiny_model):
    session = RigSession.simulated_rig(tmp_path / "s", spp=8, encoder=Encoder(tiny_model[1]))
    session.calibrate()
    yield session
    session.close()


def test_the_model_imports_without_qt():
    code = ("import sys, hairdigi.app.review.model; "
            "print(sorted(m for m in ('PySide6', 'pyvista', 'pyvistaqt', 'vtk') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]"


def test_events_call_their_subscribers_in_order_with_their_declared_payload_only():
    events, seen = Events(), []
    first = events.status.connect(lambda v: seen.append(("a", v.text)))
    events.status.connect(lambda v: seen.append(("b", v.text)))
    events.status.emit(Status("1"))
    events.status.disconnect(first)
    events.status.emit(Status("2"))
    assert seen == [("a", "1"), ("b", "1"), ("b", "2")]
    with pytest.raises(TypeError, match="status"):
        events.status.emit("3")                 # a payload of another type is refused, and no one is called
    assert seen[-1] == ("b", "2")


def test_a_capture_shows_the_encoder_first_then_the_refined_estimate_in_warm_scenes(calibrated, tmp_path):
    model = review.ReviewModel(calibrated, SMALL)
    warmed = run_now(model.warm_work(), model.apply)
    assert {"twin", "hairstyle"} <= set(warmed.seconds)
    assert (model.twin_renderer.builds, model.style_renderer.builds) == (2, 1)   # the twin at 2 scales

    stages, twins, passes = [], [], []
    model.events.shown.connect(lambda shown: stages.append(shown.stage))
    model.events.parameters.connect(lambda shown: run_previews(model))
    model.events.twin.connect(twins.append)
    model.events.hairstyle.connect(passes.append)
    captured = run_now(model.capture_work(), model.apply)

    assert stages == [Stage.ENCODER, Stage.REFINED]
    assert model.shown.capture_id == captured.result.capture_id and model.shown.record.refinement.ran
    # the encoder's look renders one pass; the refined estimate its whole schedule
    # half resolution first, then full; the first look is one pass, rendered by the capture worker
    assert [(t.stage, t.scale, t.spp) for t in twins] == [(Stage.ENCODER, 0.5, 1), (Stage.REFINED, 0.5, 1),
                                                          (Stage.REFINED, 1.0, 1)]
    assert [(p.stage, p.spp) for p in passes] == [(Stage.ENCODER, 1), (Stage.REFINED, 1), (Stage.REFINED, 2)]
    # the warm scenes were reused: the capture only updated parameters (a grey share read makes fibre
    # groups, a new structure, built once more at each scale)
    varied = int(model.shown.record.appearance.value.varied)
    assert (model.twin_renderer.builds, model.style_renderer.builds) == (2 + 2 * varied, 1 + varied)
    twin = model.twin
    assert twin.final and twin.clean_enough and twin.raw.shape == twin.clean.shape and twin.nonfinite == 0
    # the twin's film is the swatch area (to the bench camera's rounding); the map is the film's
    assert np.abs(np.subtract(twin.raw.shape[:2], model.shown.real.shape[:2])).max() <= 2
    assert twin.delta_e_map.shape == twin.raw.shape[:2] and np.isfinite(twin.delta_e)
    # numbers come from the raw pass: the chip is the raw twin's mean
    np.testing.assert_allclose(twin.hair_linear, twin.raw.reshape(-1, 3).mean(0))

    # the orbit moves the camera of the warm scene: no rebuild
    model.set_view(orbit=(30, 10))
    before = model.hairstyle.raw.copy()
    run_now(model.hairstyle_work(), model.apply)
    assert model.style_renderer.builds == 1 + varied and not np.allclose(model.hairstyle.raw, before)

    written = model.save_render("hairstyle", tmp_path / "look")
    assert [p.name for p in written] == ["look.png", "look.exr"]


def run_previews(model):
    """What the window does on ``parameters``: the twin's and the hairstyle's passes (here, in turn)."""
    for work in (model.twin_work(), model.hairstyle_work()):
        run_now(work, model.apply)


def test_the_clean_twin_lets_the_hairstyles_first_pass_go_first(calibrated):
    """The twin's and the hairstyle's passes run side by side, as the window runs them: the hairstyle waits for a
    clean twin, and the twin's further passes wait for the hairstyle's first, so that each preview is shown clean
    before either is polished."""
    import queue

    model = review.ReviewModel(calibrated, dataclasses.replace(SMALL, warm=False))
    run_now(model.capture_work(), model.apply)
    assert model.shown.stage == Stage.REFINED
    works = {"twin": model.twin_work(), "hairstyle": model.hairstyle_work()}
    results: queue.Queue = queue.Queue()

    def worker(name, work):                       # a worker thread: it yields, the model's thread applies
        for p in work.run():
            results.put((name, p))
        results.put((name, None))
    threads = [threading.Thread(target=worker, args=item) for item in works.items()]
    for thread in threads:
        thread.start()
    order, ended = [], 0
    while ended < len(works):
        name, p = results.get(timeout=120)
        if p is None:
            ended += 1
            works[name].ended()
            continue
        model.apply(p)
        order.append((name, getattr(p, "scale", None), p.spp))
    for thread in threads:
        thread.join(10)
    assert order.index(("twin", 0.5, 1)) < order.index(("hairstyle", None, 1)) < order.index(("twin", 1.0, 1)), order


@pytest.mark.slow
def test_a_new_capture_cancels_stale_renders(calibrated):
    model = review.ReviewModel(calibrated, dataclasses.replace(SMALL, hairstyle_passes=(1,) * 40, warm=False))
    run_now(model.capture_work(), model.apply)
    first = model.shown.capture_id
    run_now(model.twin_work(), model.apply)                  # the twin goes first, as in the window
    reported, started = [], threading.Event()

    def worker(work):                                               # a worker thread: it yields, the model applies
        for p in work.run():
            reported.append(p)
            started.set()
    thread = threading.Thread(target=worker, args=(model.hairstyle_work(),))
    thread.start()
    assert started.wait(120)
    kept = []                                                       # a new capture, while the render runs
    captured = run_now(model.capture_work(), lambda x: kept.append(x) if isinstance(x, Captured)
                              else model.apply(x))
    thread.join(120)
    assert not thread.is_alive() and 1 <= len(reported) < 40        # it stopped at its next pass
    for stale in reported:                                          # and what it reported late is dropped
        model.apply(stale)
    assert model.hairstyle.stage == Stage.ENCODER and model.hairstyle.key == model.shown.key   # the new first look
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


@pytest.mark.slow
def test_one_open_rig_serves_the_command_line_and_the_window(tmp_path):
    from hairdigi.hardware.cameras import CameraError
    from hairdigi.app.session.rig_session import open_rig

    with pytest.raises(CameraError, match="no camera at"):          # the command line: the error, as it is
        open_rig(tmp_path / "a", camera=str(tmp_path / "no-camera.mp4"))
    session, why = open_rig(tmp_path / "b", camera=str(tmp_path / "no-camera.mp4"), fallback=True)  # the window
    try:
        assert session.simulated and "no camera at" in why and why.endswith("using the simulated rig")
    finally:
        session.close()


def test_a_pass_with_nonfinite_values_becomes_a_warning_of_the_shown_capture():
    """A NaN or Inf count in a pass is a NONFINITE warning under the shown parameters, once."""
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.records import EstimateRecord, WarningKind

    model = review.ReviewModel(session=None)
    seen = []
    model.events.warnings.connect(seen.append)
    rec = EstimateRecord(hair=HairParams(), uncertainty=Uncertainty(parameters={"dye_r": ParameterInterval(
        120.0, 0.0, 255.0, 200.0, determined=False)}))
    model.shown = Shown("c1", np.zeros((8, 8, 3), np.uint8), (0, 0, 8, 8), (8, 8), rec.hair, Stage.REFINED, rec,
                        key=7)
    raw = np.zeros((8, 8, 3), np.float32)
    for n in (3, 5):
        model.apply(TwinPreview(model._generation["twin"], raw, None, 1, False, False, 0.0, raw[..., 0],
                                raw[0, 0], Stage.REFINED, 0.1, 7, 1.0, nonfinite=n))
    assert [[w.kind for w in ws.items] for ws in seen] == [[WarningKind.NONFINITE]]
    view = model.parameter_view()
    assert "3 NaN or Inf" in view.info and dict(view.lines)["dye_r"].endswith("(undetermined)")


def test_model_state_changes_on_its_own_thread_only():
    model = review.ReviewModel(session=None)
    errors = []

    def elsewhere():
        try:
            model.set_view(style="bob")
        except RuntimeError as exc:
            errors.append(str(exc))
    thread = threading.Thread(target=elsewhere)
    thread.start()
    thread.join(30)
    assert errors and "own thread" in errors[0] and model.style != "bob"


@pytest.mark.slow
def test_a_hairstyle_under_another_light_renders_spectrally_and_is_shown_adapted(calibrated):
    model = review.ReviewModel(calibrated, dataclasses.replace(SMALL, warm=False))
    run_now(model.capture_work(), model.apply)
    looks = {}
    for light in (None, "A", "D65"):
        model.set_view(illuminant=light)
        assert model.hairstyle_spec().illuminant == light and (light is None or light in model.view_label())
        run_now(model.hairstyle_work(), model.apply)
        looks[light] = model.hairstyle.raw.reshape(-1, 3).mean(0)
    # the adapted eye: tungsten is not orange (the scalp and hair keep their hue), and D65 is the RGB world's
    shift = (looks["A"][0] / looks["A"][2]) / (looks[None][0] / looks[None][2])
    assert 0.8 < shift < 1.3, shift     # an RGB render balanced as if lit by tungsten: R/B times ~0.13, blue
    assert np.allclose(looks["D65"], looks[None], rtol=0.25)
    assert "under A" not in model.view_label()                      # D65 chosen last
    model.set_view(style="bob")                                      # other changes keep the light
    assert model.illuminant == "D65"
    with pytest.raises(ValueError, match="unknown light 'candle'"):
        model.set_view(illuminant="candle")


def test_the_window_says_a_records_colour_under_other_lights_and_its_spectral_interval():
    from hairdigi.app.review.text import spectral_lines
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.records import EstimateRecord, SpectralReading

    assert spectral_lines(EstimateRecord(hair=HairParams())) == []
    reading = SpectralReading(HairParams(), "LED-B4", "nikon-5100", 0.01,
                              {"D65": (40.0, 20.0, 20.0), "A": (40.0, 26.0, 24.0)})
    stated = SpectralInterval("nikon-5100", "camera", "every light", 1.21, 5.3)
    lines = spectral_lines(EstimateRecord(hair=HairParams(), spectral=reading, uncertainty=Uncertainty(spectral=stated)))
    assert lines[0].startswith("read in the camera's RGB (nikon-5100 under LED-B4)")
    assert "daylight L* 40" in lines[0] and "tungsten L* 40 (ΔE2000 3.1 from daylight)" in lines[0]
    assert "within ΔE2000 1.21 in 68%" in lines[1]
    undeclared = dataclasses.replace(stated, camera="unknown")
    assert spectral_lines(EstimateRecord(hair=HairParams(), uncertainty=Uncertainty(spectral=undeclared))) == [
        "spectral world (unknown camera): within ΔE2000 1.21 in 68% for every light"]


def test_a_record_whose_refinement_has_no_residual_is_shown_not_crashed():
    """A record file may hold a refinement without its residual (an older or a hand-made one)."""
    from hairdigi.app.review.text import parameter_view
    from hairdigi.app.cli.rig import say_record
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.records import EstimateRecord

    rec = EstimateRecord.from_json({"hair": HairParams().to_dict(), "refinement": {"ran": True, "sigma_a": [0.1, 0.2, 0.3]}})
    view = parameter_view(Shown("x", np.zeros((4, 4, 3)), (0, 0, 4, 4), (4, 4), HairParams(), Stage.REFINED, rec))
    assert "residual ΔE2000 not recorded" in view.info
    said = []
    say_record(rec, said.append)
    assert "residual ΔE2000 not recorded" in said[0]
