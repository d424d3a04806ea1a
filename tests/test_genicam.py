"""GenICam cameras through Aravis, against Aravis's own fake cameras: no mocks.

Two fakes: the in-process "Fake" interface (``Fake_1``), which hairdigi also gives a 12-bit RGGB
sensor (``hardware.sim_genicam``), and ``arv-fake-gv-camera-0.8``, a separate process that speaks
GigE Vision on the loopback, which the tests kill to make the camera vanish. Skipped only where
Aravis 0.8 or PyGObject is not installed (``make setup`` installs both).
"""
import json
import shutil
import signal
import subprocess
import time

import numpy as np
import pytest

from hairdigi.hardware.cameras import CameraError

try:
    from hairdigi.hardware.genicam import load_aravis

    Aravis = load_aravis()
except CameraError as exc:     # Aravis or PyGObject absent: nothing here can run
    pytest.skip(str(exc), allow_module_level=True)

from hairdigi.app.session.rig_session import CalibrationStatus, RigSession
from hairdigi.hardware.bayer import bayer_format, demosaic, unpack
from hairdigi.hardware.genicam import FAKE_ID, GenICamCamera, GenICamSettings, discover
from hairdigi.hardware.lights import LightController
from hairdigi.hardware.sim_genicam import open_lab_camera
from hairdigi.hardware.sim_lights import SimulatedLightBoard
from hairdigi.inference.calibration import staleness
from deadlines import within

SPP = 8
GV_SERIAL = "HDTEST"


@pytest.fixture
def gv_camera():
    """A GigE Vision fake camera on 127.0.0.1 (its own process); yields (device id, start, kill)."""
    tool = shutil.which("arv-fake-gv-camera-0.8")
    if tool is None:
        pytest.skip("arv-fake-gv-camera-0.8 not installed (apt-get install aravis-tools)")
    procs = []

    def start():
        procs.append(subprocess.Popen([tool, "-i", "127.0.0.1", "-s", GV_SERIAL], stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
        for _ in range(50):
            if any(d.serial == GV_SERIAL for d in discover()):
                return
            time.sleep(0.1)
        raise AssertionError("the GigE Vision fake camera did not answer discovery")

    def kill():
        procs[-1].send_signal(signal.SIGKILL)
        procs[-1].wait()

    start()
    yield f"Aravis-Fake-{GV_SERIAL}", start, kill
    for p in procs:
        if p.poll() is None:
            p.kill()
            p.wait()


def test_discovery_finds_the_fake_cameras(gv_camera):
    found = {d.id: d for d in discover(fake=True)}
    assert found[FAKE_ID].protocol == "Fake" and found[FAKE_ID].vendor == "Aravis"
    gv = found[gv_camera[0]]
    assert gv.serial == GV_SERIAL and gv.protocol == "GigEVision" and gv.model == "Fake"


def test_settings_are_set_read_back_and_recorded(gv_camera):
    camera = GenICamCamera(gv_camera[0], GenICamSettings(exposure_us=20_000, gain=3))
    try:
        s = camera.settings()
        # the fake's ExposureTimeAbs and GainRaw, read back through GenICam; its only auto mode is off
        assert s["exposure_us"] == 20_000 and s["gain"] == 3 and s["autos"] == {"GainAuto": "Off"}
        assert s["serial"] == GV_SERIAL and s["pixel_format"] == "BayerBG8"   # the first of its deepest Bayer formats
        assert camera._camera.get_string("GainAuto") == "Off"
        frame = camera.read()
        assert frame.meta["camera_settings"] == s and frame.meta["camera"] == f"genicam:Aravis Fake #{GV_SERIAL}"
        assert camera.set_exposure_offset(1.0) and camera._camera.get_exposure_time() == 40_000
        assert camera.set_exposure_offset(0.0) and camera.settings()["exposure_us"] == 20_000
    finally:
        camera.close()
    with pytest.raises(CameraError, match=rf"^genicam:Aravis Fake #{GV_SERIAL}: BlackLevel: the camera has no "):
        GenICamCamera(gv_camera[0], GenICamSettings(black_level=64))
    with pytest.raises(CameraError, match=r"PixelFormat: BayerRG12 is not offered \(offered: BayerBG8"):
        GenICamCamera(gv_camera[0], GenICamSettings(pixel_format="BayerRG12"))
    with pytest.raises(CameraError, match=r"^genicam:nonesuch: open: .*arv-tool-0.8"):
        GenICamCamera("nonesuch")


def _fake_frame(pixel_format: str):
    """One frame of the in-process fake camera's own test pattern, with its frame id, through Aravis alone."""
    camera = Aravis.Camera.new(FAKE_ID)
    camera.set_pixel_format_from_string(pixel_format)
    buffer = camera.acquisition(2_000_000)
    assert buffer.get_status() == Aravis.BufferStatus.SUCCESS
    width, height = buffer.get_image_width(), buffer.get_image_height()
    data = np.frombuffer(bytes(buffer.get_image_data()), np.uint8)
    return data.reshape(height, width, -1), int(buffer.get_frame_id())


@pytest.mark.parametrize("pixel_format", ["BayerGR8", "BayerGB8"])
def test_a_bayer_frame_decodes_to_the_fake_cameras_own_pattern(pixel_format):
    """The fake draws colour (x + y + frame id) mod 255 of a jet colour map: in RGB8 for every pixel, in
    Bayer formats one colour a pixel. Each decoded Bayer sample is its RGB8 pixel, shifted by the
    frames' id difference. (Its BayerRG8 and BayerBG8 swap red and blue: Aravis 0.8.26 and upstream.)"""
    discover(fake=True)
    rgb, rgb_id = _fake_frame("RGB8")
    camera = GenICamCamera(FAKE_ID, GenICamSettings(pixel_format=pixel_format))
    try:
        frame = camera.read()
    finally:
        camera.close()
    fmt = bayer_format(pixel_format)
    shift = (frame.meta["frame"] - rgb_id) % 255
    height, width = frame.mosaic.shape
    x = np.arange(width)
    # the pixel at (x, y) of the Bayer frame shows the RGB8 frame's colour at ((x + shift) mod 255, y)
    expected = rgb[:, (x + shift) % 255].astype(np.float32)
    for i, colour in enumerate(fmt.layout):
        c = "RGB".index(colour)
        sites = (slice(i // 2, None, 2), slice(i % 2, None, 2))
        assert np.array_equal(frame.mosaic[sites], expected[sites][..., c].astype(np.uint16)), (colour, i)
        assert np.allclose(frame.linear[sites][..., c], expected[sites][..., c] / 255.0, atol=1e-6)


def _patches():
    """A known scene: four flat colour patches, linear."""
    scene = np.empty((240, 320, 3), np.float32)
    colours = [(0.6, 0.3, 0.15), (0.1, 0.2, 0.4), (0.05, 0.05, 0.05), (0.8, 0.8, 0.8)]
    for k, colour in enumerate(colours):
        scene[120 * (k // 2):120 * (k // 2 + 1), 160 * (k % 2):160 * (k % 2 + 1)] = colour
    return scene, colours


def test_a_12_bit_bayer_frame_decodes_to_its_scene(tmp_path):
    """The fake camera with hairdigi's 12-bit RGGB sensor: BayerRG12 read through Aravis, the black level
    subtracted, demosaiced in linear light, back to the scene it was shown; its DNG reads back the same."""
    from hairdigi.hardware.capture import save_capture
    from hairdigi.hardware.cameras import read_raw

    scene, colours = _patches()
    camera, sensor = open_lab_camera(lambda: scene, GenICamSettings(black_level=64), size=(320, 240))
    try:
        s = camera.settings()
        assert s["pixel_format"] == "BayerRG12" and s["bits"] == 12 and s["black_level"] == 64
        assert s["autos"] == {"ExposureAuto": "Off", "GainAuto": "Off", "BalanceWhiteAuto": "Off"}
        frames = [camera.read() for _ in range(4)]
        assert sensor.problem is None and sensor.frames >= 4
        assert frames[0].mosaic.max() > 255 and frames[0].mosaic.max() <= 4095   # 12 bits, not 8
        assert frames[0].mosaic.min() >= 64 - 10                                 # the black pedestal is in the data
        linear = np.mean([f.linear for f in frames], axis=0)
        for k, colour in enumerate(colours):
            y, x = 60 + 120 * (k // 2), 80 + 160 * (k % 2)
            got = linear[y - 30:y + 30, x - 40:x + 40].reshape(-1, 3).mean(axis=0)
            assert np.allclose(got, colour, rtol=0.01, atol=0.002), (k, got, colour)
        assert camera.set_exposure_offset(1.0)                    # twice the light, set on the camera
        brighter = camera.read().linear[60 - 30:60 + 30, 80 - 40:80 + 40].reshape(-1, 3).mean(axis=0)
        assert np.allclose(brighter, np.minimum(2 * np.array(colours[0]), 1.0), rtol=0.01)
        image, _, record = save_capture(tmp_path, frames[0].srgb, mosaic=(frames[0].mosaic, frames[0].meta["bayer"]),
                                        frame_meta=frames[0].meta)
    finally:
        camera.close()
    assert image.suffix == ".dng" and record.image == image.name
    still = read_raw(image)           # the RAW still path (rawpy) reads the capture's mosaic
    y, x = 60, 80
    assert np.allclose(still.linear[y - 30:y + 30, x - 40:x + 40].reshape(-1, 3).mean(axis=0),
                       frames[0].linear[y - 30:y + 30, x - 40:x + 40].reshape(-1, 3).mean(axis=0), rtol=0.01)


def test_bayer_unpacking():
    fmt = bayer_format("BayerGB12")
    assert fmt.layout == "GBRG" and fmt.white == 4095 and bayer_format("BayerRG12p") is None
    counts = np.array([[4095, 1], [2048, 64]], np.uint16)
    assert np.array_equal(unpack(counts.astype("<u2").tobytes(), fmt, 2, 2), counts)
    flat = demosaic(np.full((4, 4), 64 + 4031 // 2, np.uint16), "RGGB", 64, 4095)
    assert np.allclose(flat, 2015 / 4031, atol=1e-6)
    with pytest.raises(ValueError, match="needs 8 bytes"):
        unpack(b"\0" * 4, fmt, 2, 2)


def test_a_capture_of_four_frames_through_the_session(tmp_path):
    """The simulated rig through the fake camera: three single-light frames, each exposed longer on the
    camera itself, then the frame with all lights; saved as a DNG with the read-back settings; a
    calibration at other settings is stale and says which."""
    session = RigSession.simulated_rig(tmp_path / "s", spp=SPP, genicam=FAKE_ID)
    try:
        camera, sensor = session.camera, session.camera.sensor
        profile = session.calibrate()
        assert profile.delta_e2000["after"]["mean"] < 1.0 and profile.settings["pixel_format"] == "BayerRG12"
        before = session.frames.frames_read
        result = session.capture(estimate=False)
        assert session.frames.frames_read - before == 4 and sensor.problem is None
        meta = json.loads(result.meta_path.read_text())
        assert meta["image"].endswith(".dng") and len(meta["light_images"]) == 3
        assert meta["light_exposures"] == [2 ** 1.5] * 3          # set on the camera, not guessed
        settings = meta["frame_meta"]["camera_settings"]
        assert settings["exposure_us"] == 10_000 and settings["serial"] == camera.serial
        assert camera._camera.get_exposure_time() == 10_000      # the bench's exposure is back
        loaded = session.load_capture(result.capture_id)
        assert loaded.linear is not None and loaded.problems == []
        assert session.calibration_status()[0] is CalibrationStatus.OK
        from hairdigi.inference.calibration import load_profile
        assert staleness(load_profile(session.profile_path), session.settings()) == []   # as saved, too
        camera.wanted = GenICamSettings(exposure_us=12_000)   # the operator changes the exposure
        camera.set_exposure_offset(0.0)
        camera.readback = camera._read_settings(camera.format)
        status, reasons = session.calibration_status()
        assert status is CalibrationStatus.STALE and "exposure_us" in reasons[0]
        other = dict(profile.settings, serial="OTHER", camera="genicam:Aravis Fake #OTHER")
        assert "camera, serial" in staleness(profile, other)[0]
    finally:
        session.close()


class _SwitchThenVanish:
    """The rig's real light board, whose second light's switch-on is when the camera vanishes."""

    def __init__(self, lights, vanish):
        self.lights, self.vanish = lights, vanish

    def __getattr__(self, name):
        return getattr(self.lights, name)

    def set_light(self, index, on, *args):
        if index == 1 and on and self.vanish is not None:
            self.vanish, vanish = None, self.vanish
            vanish()
        return self.lights.set_light(index, on, *args)


def test_the_camera_vanishing_mid_capture(tmp_path, gv_camera):
    """The GigE camera's process is killed between two single-light frames: one line naming the camera
    and what failed, nothing of the capture on disk, the lights as they were; it is reopened when back."""
    device, start, kill = gv_camera
    board = SimulatedLightBoard()
    lights = LightController(board.port)
    camera = GenICamCamera(device, GenICamSettings(timeout_s=1.0))
    session = RigSession(camera, _SwitchThenVanish(lights, kill), tmp_path / "s", swatch_roi=(10, 10, 100, 100))
    try:
        for i in range(3):
            lights.set_light(i, True, 200)
        states = lights.status()
        t0 = time.monotonic()
        with pytest.raises(CameraError) as caught:
            session.capture(estimate=False)
        message = str(caught.value)
        assert "\n" not in message and message.startswith(f"genicam:Aravis Fake #{GV_SERIAL}: ")
        assert "camera is gone" in message and ("TriggerSoftware" in message or "ExposureTime" in message)
        assert time.monotonic() - t0 < within(20)
        assert not (tmp_path / "s" / "captures").exists() or not any((tmp_path / "s" / "captures").iterdir())
        assert lights.status() == states
        with pytest.raises(CameraError, match="discovery: the camera does not answer"):
            camera.read()
        start()
        assert camera.reconnect(wait_s=10)
        result = session.capture(estimate=False)
        assert result.image_path.suffix == ".dng" and len(list((tmp_path / "s" / "captures").glob("*-light*.png"))) == 3
    finally:
        session.close()
        board.close()


def test_the_live_feed_waits_for_a_vanished_camera(gv_camera):
    """The window's feed (the frame source's thread): an error when the camera goes, frames when it is back."""
    from hairdigi.hardware.frame_source import FrameSource

    device, start, kill = gv_camera
    source = FrameSource(GenICamCamera(device, GenICamSettings(timeout_s=1.0)), fps=10)
    frames, errors = [], []
    source.subscribe(frames.append, errors.append)
    try:
        deadline = time.monotonic() + 10
        while len(frames) < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        kill()
        while not errors and time.monotonic() < deadline + 10:
            time.sleep(0.05)
        assert len(errors) == 1 and errors[0].startswith(f"genicam:Aravis Fake #{GV_SERIAL}: ")
        assert source.running                           # waiting for the camera, not stopped
        start()
        seen = len(frames)
        deadline = time.monotonic() + 15
        while len(frames) <= seen and time.monotonic() < deadline:
            time.sleep(0.1)
        assert len(frames) > seen and source.error is None
    finally:
        source.close()


def test_rig_on_the_command_line_names_a_missing_camera(capsys):
    from hairdigi.app.cli import main

    assert main(["rig", "--genicam", "nonesuch", "--session", "/tmp/hairdigi-no-session"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "genicam:nonesuch: open:" in err
