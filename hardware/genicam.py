"""GenICam machine-vision cameras (GigE Vision, USB3 Vision) through Aravis: locked settings, raw Bayer frames.

A colour lab's bench camera is a machine-vision camera: hairdigi sets its exposure, gain, pixel format
(the deepest unpacked Bayer format offered: 12-bit where there is one) and black level, turns its
auto modes off, reads every setting back, and records the read-back values (with the serial number)
in each frame's ``camera_settings``, so a calibration made at other settings or on another camera is
stale (``inference.calibration.staleness``). Frames are software-triggered: each ``read()`` triggers
one exposure and waits for it, so a frame taken after a light switches sees the light. Frames are
demosaiced in linear light (``hardware.bayer``) and keep their mosaic for the capture's DNG.

**Binding: PyGObject on Aravis 0.8's introspection data** (Debian 12: ``gir1.2-aravis-0.8`` 0.8.26).
Aravis is the open-source GenICam stack Debian ships, and it has a fake camera (in process, and
``arv-fake-gv-camera-0.8`` over GigE Vision on the loopback) that the tests use for real. The other
two ways were worse here: ``harvesters`` needs a GenTL producer (a vendor's ``.cti``) and Debian
ships none (Aravis 0.8 builds none); ctypes on ``libaravis`` would re-declare every C signature and
GError by hand. PyGObject builds from PyPI against ``libgirepository1.0-dev`` and ``libcairo2-dev``
(pycairo and PyGObject 3.48.2: 39 s on 2 shared cores); it is pinned below 3.50, which needs GLib
2.80's girepository-2.0 (Debian 12 has GLib 2.74).

Every failure is a :class:`CameraError` of one line naming the camera and the feature; a camera that
vanished is reopened by its serial number when it answers again (``read`` tries once, ``reconnect``
waits).
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from hairdigi.hardware.bayer import BayerFormat, bayer_format, demosaic, srgb8, unpack
from hairdigi.hardware.cameras import CameraError, Frame

#: Bayer depths in the order hairdigi prefers them (12 bits: what lab cameras' ADCs give).
PREFERRED_DEPTHS = (12, 16, 14, 10, 8)
#: The auto modes turned off where the camera has them.
AUTO_FEATURES = ("ExposureAuto", "GainAuto", "BalanceWhiteAuto", "BlackLevelAuto")
#: What ``--genicam`` with no ID opens first: a real camera, else Aravis's in-process fake.
FAKE_ID = "Fake_1"
#: Stream buffers queued for the driver.
N_BUFFERS = 4


def load_aravis():
    """Aravis 0.8 through PyGObject, or a CameraError saying what to install."""
    try:
        import gi   # deferred: Aravis through PyGObject is the optional [genicam] extra

        gi.require_version("Aravis", "0.8")
        from gi.repository import Aravis   # deferred: Aravis through PyGObject is the optional [genicam] extra
    except (ImportError, ValueError) as exc:
        raise CameraError(f"GenICam cameras need Aravis 0.8 and PyGObject ({exc}): apt-get install gir1.2-aravis-0.8 "
                          f"libgirepository1.0-dev libcairo2-dev, then pip install 'hairdigi[genicam]'") from None
    return Aravis


def _message(exc: Exception) -> str:
    return getattr(exc, "message", None) or str(exc)


@dataclass(frozen=True)
class DeviceInfo:
    """One camera Aravis found."""

    id: str
    serial: str
    vendor: str
    model: str
    protocol: str


def discover(fake: bool = False) -> list[DeviceInfo]:
    """The GenICam cameras on the GigE and USB3 interfaces (and Aravis's in-process fake with ``fake``)."""
    aravis = load_aravis()
    if fake:
        aravis.enable_interface("Fake")
    aravis.update_device_list()
    return [DeviceInfo(aravis.get_device_id(i), aravis.get_device_serial_nbr(i) or "", aravis.get_device_vendor(i) or "",
                       aravis.get_device_model(i) or "", aravis.get_device_protocol(i) or "")
            for i in range(aravis.get_n_devices())]


@dataclass(frozen=True)
class GenICamSettings:
    """What hairdigi sets on the camera; the camera's read-back values are what is recorded."""

    exposure_us: float = 10_000.0
    gain: float = 0.0                   # the camera's Gain (dB on most; GainRaw where it has no Gain)
    black_level: float | None = None    # BlackLevel; None: as the camera has it. Read back, it is subtracted as
    #                                     counts of the pixel format (Basler's and the fake's unit; a camera that
    #                                     gives it in % of range should be set to 0)
    pixel_format: str | None = None     # a Bayer PFNC name; None: the deepest unpacked Bayer format offered
    timeout_s: float = 2.0              # how long a frame may take after its trigger
    region: tuple[int, int, int, int] | None = None   # x, y, width, height on the sensor; None: as the camera has it


def choose_format(offered: list[str], wanted: str | None) -> BayerFormat | None:
    """The Bayer format to use among ``offered``: ``wanted`` if given and offered, else the preferred depth."""
    if wanted is not None:
        return bayer_format(wanted) if wanted in offered else None
    formats = [f for f in map(bayer_format, offered) if f is not None]
    return min(formats, key=lambda f: PREFERRED_DEPTHS.index(f.bits), default=None)


class GenICamCamera:
    """One GenICam camera, opened by Aravis device ID (None: the first found), with locked settings."""

    def __init__(self, device_id: str | None = None, settings: GenICamSettings = GenICamSettings(),
                 on_open: Callable[["GenICamCamera"], None] | None = None) -> None:
        """``on_open(camera)`` runs each time the camera is opened and set up, before acquisition starts."""
        self.aravis = load_aravis()
        self.wanted = settings
        self.on_open = on_open
        self.device_id = device_id
        self.name = f"genicam:{device_id or 'first camera'}"
        self.serial = ""
        self.exposure_offset_ev = 0.0
        self._lock = threading.RLock()
        self._camera = self._stream = None
        self.readback: dict = {}
        self._open()

    # -- opening and settings ----------------------------------------------------------------
    def _fail(self, feature: str, what: str, fix: str = "") -> CameraError:
        return CameraError(f"{self.name}: {feature}: {what}" + (f"; {fix}" if fix else ""))

    def _open(self) -> None:
        aravis = self.aravis
        if self.device_id == FAKE_ID:
            aravis.enable_interface("Fake")
        try:
            camera = aravis.Camera.new(self.device_id)
        except Exception as exc:
            raise self._fail("open", _message(exc), "check that it is powered and plugged in "
                             "(arv-tool-0.8 lists the cameras Aravis sees)") from None
        self._camera = camera
        try:
            self.serial = camera.get_device_serial_number() or self.serial
            self.name = f"genicam:{camera.get_vendor_name()} {camera.get_model_name()} #{self.serial}"
            self.format = self._configure()
            if self.on_open is not None:
                self.on_open(self)
            self._stream = camera.create_stream(None, None)
            for _ in range(N_BUFFERS):
                self._stream.push_buffer(aravis.Buffer.new_allocate(camera.get_payload()))
            camera.start_acquisition()
        except CameraError:
            self._drop()
            raise
        except Exception as exc:
            self._drop()
            raise self._fail("open", _message(exc)) from None

    def _set(self, feature: str, setter, *args) -> None:
        try:
            setter(*args)
        except Exception as exc:
            raise self._fail(feature, f"cannot be set to {', '.join(map(str, args))} ({_message(exc)})") from None

    def _configure(self) -> BayerFormat:
        """Autos off, then pixel format, exposure, gain, black level and the software trigger; read back."""
        camera, wanted = self._camera, self.wanted
        for feature in AUTO_FEATURES:
            if camera.is_feature_available(feature):
                self._set(feature, camera.set_string, feature, "Off")
        offered = list(camera.dup_available_pixel_formats_as_strings() or ())
        fmt = choose_format(offered, wanted.pixel_format)
        if fmt is None:
            asked = wanted.pixel_format or "an unpacked Bayer format"
            raise self._fail("PixelFormat", f"{asked} is not offered (offered: {', '.join(offered)}); hairdigi needs "
                             "raw Bayer frames")
        self._set("PixelFormat", camera.set_pixel_format_from_string, fmt.name)
        if wanted.region is not None:
            self._set("OffsetX, OffsetY, Width, Height", camera.set_region, *map(int, wanted.region))
        if not camera.is_exposure_time_available():
            raise self._fail("ExposureTime", "the camera has no exposure time control")
        if camera.is_gain_available():
            self._set("Gain", camera.set_gain, float(wanted.gain))
        elif wanted.gain:
            raise self._fail("Gain", f"the camera has no gain control (asked {wanted.gain})")
        if wanted.black_level is not None:
            if not camera.is_black_level_available():
                raise self._fail("BlackLevel", f"the camera has no black level control (asked {wanted.black_level})")
            self._set("BlackLevel", camera.set_black_level, float(wanted.black_level))
        if not camera.is_software_trigger_supported():
            raise self._fail("TriggerSoftware", "the camera cannot be triggered by software")
        self._set("TriggerSource", camera.set_trigger, "Software")
        self._apply_exposure()
        self.readback = self._read_settings(fmt)
        return fmt

    def _apply_exposure(self) -> float:
        """Set ExposureTime to the bench's times 2^offset; returns the camera's value."""
        exposure = self.wanted.exposure_us * 2.0 ** self.exposure_offset_ev
        self._set("ExposureTime", self._camera.set_exposure_time, float(exposure))
        return float(self._camera.get_exposure_time())

    def _read_settings(self, fmt: BayerFormat) -> dict:
        """The settings a calibration depends on, as the camera reports them."""
        camera = self._camera
        autos = {f: camera.get_string(f) for f in AUTO_FEATURES if camera.is_feature_available(f)}
        black = float(camera.get_black_level()) if camera.is_black_level_available() else None
        x, y, width, height = camera.get_region()
        return {"serial": self.serial, "vendor": camera.get_vendor_name(), "model": camera.get_model_name(),
                "pixel_format": camera.get_pixel_format_as_string(), "bits": fmt.bits,
                "exposure_us": float(camera.get_exposure_time()),
                "gain": float(camera.get_gain()) if camera.is_gain_available() else None,
                "black_level": black, "autos": autos, "region": [int(x), int(y), int(width), int(height)]}

    def settings(self) -> dict:
        """The read-back settings (hairdigi is the camera's only writer and its autos are off)."""
        return dict(self.readback)

    def set_exposure_offset(self, ev: float) -> bool:
        """Expose the next frames ``ev`` stops longer than the bench's setting; False where it cannot."""
        with self._lock:
            self.exposure_offset_ev = float(ev)
            if self._camera is None:
                return False
            try:
                got = self._apply_exposure()
            except CameraError as exc:
                self._check_alive(str(exc).removeprefix(f"{self.name}: "))   # gone: raised as such
                self.exposure_offset_ev = 0.0                                # out of its range: the bench's
                self._apply_exposure()
                return False
            return abs(got - self.wanted.exposure_us * 2.0 ** ev) <= 0.02 * got

    # -- frames ------------------------------------------------------------------------------
    def read(self) -> Frame:
        """Trigger one exposure and return it, demosaiced in linear light, with its mosaic."""
        with self._lock:
            if self._camera is None:
                self._reopen()
            counts, frame_id = self._grab()
            fmt = self.format
            black = self.readback.get("black_level") or 0.0
            linear = demosaic(counts, fmt.layout, black, fmt.white)
            meta = {"camera": self.name, "frame": frame_id, "camera_settings": self.settings(),
                    "exposure_offset_ev": self.exposure_offset_ev,
                    "exposure_us": self.wanted.exposure_us * 2.0 ** self.exposure_offset_ev,
                    "bayer": {"format": fmt.name, "layout": fmt.layout, "black": black, "white": fmt.white,
                              "model": self.name}}
            return Frame(srgb8(linear), linear, meta, time.time(), mosaic=counts)

    def _grab(self) -> tuple[np.ndarray, int]:
        stream, aravis = self._stream, self.aravis
        asked = time.time_ns()
        while (stale := stream.try_pop_buffer()) is not None:    # frames exposed before this call
            stream.push_buffer(stale)
        try:
            self._camera.software_trigger()
        except Exception as exc:
            self._lost("TriggerSoftware", _message(exc))
        deadline = time.monotonic() + self.wanted.timeout_s
        while (left := deadline - time.monotonic()) > 0:
            buffer = stream.timeout_pop_buffer(max(1, int(left * 1e6)))
            if buffer is None or buffer.get_system_timestamp() >= asked:
                break
            stream.push_buffer(buffer)      # a free-running camera's frame begun before this call
        else:
            buffer = None
        if buffer is None:
            self._check_alive(f"no frame within {self.wanted.timeout_s:g} s of the trigger")
            raise self._fail("frame", f"no frame within {self.wanted.timeout_s:g} s of the trigger; check the "
                             "cable's bandwidth (arv-camera-test-0.8)")
        try:
            status = buffer.get_status()
            if status != aravis.BufferStatus.SUCCESS:
                raise self._fail("frame", f"the frame arrived incomplete ({status.value_nick}); check the cable")
            width, height = buffer.get_image_width(), buffer.get_image_height()
            try:
                counts = unpack(bytes(buffer.get_image_data()), self.format, width, height)
            except ValueError as exc:
                raise self._fail("frame", str(exc)) from None
            return counts, int(buffer.get_frame_id())
        finally:
            stream.push_buffer(buffer)

    def _check_alive(self, what: str) -> None:
        """A frame did not come: if the camera does not answer either, it is gone."""
        try:
            self._camera.get_exposure_time()
        except Exception as exc:
            self._lost("ExposureTime", f"{what}, and it does not answer ({_message(exc)})")

    def _lost(self, feature: str, what: str):
        self._drop()
        raise self._fail(feature, what, "the camera is gone: check its cable and power; hairdigi reopens it "
                         "when it answers again")

    # -- losing and finding the camera -------------------------------------------------------
    def _drop(self) -> None:
        camera, self._camera, self._stream = self._camera, None, None
        if camera is not None:
            try:
                camera.stop_acquisition()
            except Exception:
                pass   # a camera that vanished cannot stop; its handles are released all the same

    def _reopen(self) -> None:
        """Open the same camera again (by serial where known), with the same settings."""
        serial, name = self.serial, self.name
        found = [d for d in discover(fake=self.device_id == FAKE_ID) if not serial or d.serial == serial]
        if not found:
            raise CameraError(f"{name}: discovery: the camera does not answer; check its cable and power")
        self.device_id = found[0].id if serial else self.device_id
        self._open()

    def reconnect(self, wait_s: float = 30.0, poll_s: float = 1.0) -> bool:
        """Wait up to ``wait_s`` for a vanished camera to answer again, and reopen it; True when it did."""
        deadline = time.monotonic() + wait_s
        while True:
            with self._lock:
                if self._camera is not None:
                    return True
                try:
                    self._reopen()
                    return True
                except CameraError:
                    pass
            if time.monotonic() >= deadline:
                return False
            time.sleep(poll_s)

    def close(self) -> None:
        with self._lock:
            self._drop()
