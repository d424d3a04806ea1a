"""A 12-bit Bayer sensor for Aravis's in-process fake camera: the simulated rig through a real GenICam stack.

Aravis 0.8's fake camera (Debian 12: 0.8.26; upstream's is the same) offers only 8-bit Bayer formats
of its own test pattern (a jet-coloured diagonal ramp), and no black level, exposure auto or white
balance features. For the simulated rig and the tests hairdigi gives it what a lab camera has:

- a GenICam file: the fake's own, plus ``BayerRG12``, ``BlackLevel``, ``ExposureAuto`` and
  ``BalanceWhiteAuto`` (plain registers of its memory);
- a fill pattern (``arv_fake_camera_set_fill_pattern``, through ctypes: its introspection
  annotation, ``scope call``, would free a Python callback as soon as it is set): a scene's linear
  light, times the exposure and gain in the camera's registers and the sensor's channel response,
  plus the black level, mosaicked RGGB and quantised to 12 bits.

Everything above the pixels is Aravis's own path: features, PixelFormat, PayloadSize, the stream and
its buffers, the software trigger. One field is reached behind its back: a buffer's received size,
which Aravis's own fill patterns set (a private field); its offset is checked against the buffer's
public data pointer and allocated size before anything is written.
"""
from __future__ import annotations

import ctypes
import hashlib
import tempfile
import threading
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from hairdigi.hardware.cameras import CameraError
from hairdigi.hardware.genicam import FAKE_ID, GenICamCamera, GenICamSettings, load_aravis
from hairdigi.render.domain.files import atomic_path

#: PFNC BayerRG12 (unpacked, 16-bit words)
BAYER_RG12 = 0x01100011
WHITE = 4095
#: The registers of the added features (free memory of the fake camera, below its 64 KiB).
REGISTERS = {"BlackLevel": 0xF000, "ExposureAuto": 0xF004, "BalanceWhiteAuto": 0xF008}
#: The exposure at which a scene's linear value 1.0 reaches the white level at gain 0.
REFERENCE_EXPOSURE_US = 10_000.0
#: The optical low-pass filter's blur, in pixels (a Gaussian's sigma): without one, each colour samples
#: a quarter of the pixels, and a rendered scene's per-pixel noise aliases into the chart's patches.
OLPF_SIGMA = 0.8
#: Read noise of the simulated sensor, in counts.
READ_NOISE = 1.5

_REGISTER = """
\t<IntReg Name="{name}Register" NameSpace="Custom">
\t\t<Address>{address:#x}</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
\t\t<Sign>Unsigned</Sign><Endianess>BigEndian</Endianess>
\t</IntReg>"""
_AUTO = """
\t<Enumeration Name="{name}" NameSpace="Standard">
\t\t<EnumEntry Name="Off" NameSpace="Standard"><Value>0</Value></EnumEntry>
\t\t<EnumEntry Name="Continuous" NameSpace="Standard"><Value>2</Value></EnumEntry>
\t\t<pValue>{name}Register</pValue>
\t</Enumeration>"""
_BLACK = """
\t<Float Name="BlackLevel" NameSpace="Standard">
\t\t<pValue>BlackLevelRegister</pValue><Min>0</Min><Max>512</Max>
\t</Float>"""
_RG12 = """<EnumEntry Name="BayerRG12" NameSpace="Standard">
\t\t\t<Value>{value}</Value>
\t\t</EnumEntry>
\t\t<EnumEntry Name="BayerBG8\"""".format(value=BAYER_RG12)


def lab_genicam_xml(fake_xml: str) -> str:
    """The fake camera's GenICam file with a 12-bit Bayer format, a black level and two autos added."""
    if "<EnumEntry Name=\"BayerBG8\"" not in fake_xml or "</RegisterDescription>" not in fake_xml:
        raise CameraError("genicam:Aravis Fake: GenICam file: not the fake camera's as hairdigi knows it")
    added = _BLACK + "".join(_AUTO.format(name=n) for n in ("ExposureAuto", "BalanceWhiteAuto")) + \
        "".join(_REGISTER.format(name=n, address=a) for n, a in REGISTERS.items())
    xml = fake_xml.replace("<EnumEntry Name=\"BayerBG8\"", _RG12, 1)
    return xml.replace("</RegisterDescription>", added + "\n</RegisterDescription>", 1)


def _library():
    """libaravis with the few C signatures the fill pattern needs."""
    lib = ctypes.CDLL("libaravis-0.8.so.0")
    lib.arv_buffer_get_data.restype = ctypes.c_void_p
    lib.arv_buffer_get_data.argtypes = (ctypes.c_void_p, ctypes.c_void_p)
    for name in ("arv_buffer_get_image_width", "arv_buffer_get_image_height"):
        getattr(lib, name).restype = ctypes.c_int
        getattr(lib, name).argtypes = (ctypes.c_void_p,)
    lib.arv_fake_camera_read_register.restype = ctypes.c_int
    lib.arv_fake_camera_read_register.argtypes = (ctypes.c_void_p, ctypes.c_int64, ctypes.POINTER(ctypes.c_uint32))
    lib.arv_fake_camera_set_fill_pattern.restype = None
    lib.arv_fake_camera_set_fill_pattern.argtypes = (ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)
    return lib


FillPattern = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_uint32)
_GOBJECT_SIZE = 24           # GObject on 64-bit: the ArvBuffer's private pointer follows it
_PRIV_DATA, _PRIV_RECEIVED = 16, 48   # ArvBufferPrivate: allocated_size, is_preallocated, data, ..., received_size


def _pointer(gobject) -> int:
    """The C address of a PyGObject wrapper's object."""
    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.restype, get.argtypes = ctypes.c_void_p, (ctypes.py_object, ctypes.c_char_p)
    return get(gobject.__gpointer__, None)


class LabSensor:
    """A 12-bit RGGB sensor filling the fake camera's buffers from ``scene()``: (H, W, 3) linear light."""

    def __init__(self, scene: Callable[[], np.ndarray], response=(1.0, 1.0, 1.0), seed: int = 0,
                 blur: float = OLPF_SIGMA) -> None:
        self.scene = scene
        self.blur = blur
        self.response = np.asarray(response, np.float32)
        self._rng = np.random.default_rng(seed)
        self._lib = _library()
        self._callback = FillPattern(self._fill)   # kept alive while the camera holds it
        self._fake = None
        self.frames = 0
        self.problem: str | None = None

    def attach(self, camera: GenICamCamera) -> None:
        """Fill ``camera``'s frames (an in-process fake camera, opened and set up)."""
        fake = camera._camera.get_device().get_fake_camera()
        self._fake = _pointer(fake)
        self._fake_object = fake
        self._lib.arv_fake_camera_set_fill_pattern(self._fake, ctypes.cast(self._callback, ctypes.c_void_p), None)

    def register(self, name: str) -> int:
        value = ctypes.c_uint32()
        self._lib.arv_fake_camera_read_register(self._fake, REGISTERS[name], ctypes.byref(value))
        return int(value.value)

    def counts(self, width: int, height: int, exposure_us: float, gain: float) -> np.ndarray:
        """The (height, width) uint16 RGGB mosaic of the scene at this exposure and gain."""
        light = np.asarray(self.scene(), np.float32)
        if light.shape[:2] != (height, width):
            light = cv2.resize(light, (width, height), interpolation=cv2.INTER_AREA)
        if self.blur:     # the optical low-pass filter in front of a Bayer sensor
            light = cv2.GaussianBlur(light, (0, 0), self.blur)
        black = self.register("BlackLevel")
        scale = (exposure_us / REFERENCE_EXPOSURE_US) * 10.0 ** (gain / 20.0) * (WHITE - black)
        rgb = light * (self.response * np.float32(scale))
        mosaic = np.empty((height, width), np.float32)
        mosaic[0::2, 0::2] = rgb[0::2, 0::2, 0]
        mosaic[0::2, 1::2] = rgb[0::2, 1::2, 1]
        mosaic[1::2, 0::2] = rgb[1::2, 0::2, 1]
        mosaic[1::2, 1::2] = rgb[1::2, 1::2, 2]
        mosaic = self._rng.poisson(np.clip(mosaic, 0, None)).astype(np.float32) + black
        mosaic += self._rng.normal(0.0, READ_NOISE, mosaic.shape).astype(np.float32)
        return np.clip(np.round(mosaic), 0, WHITE).astype(np.uint16)

    def _fill(self, buffer, _data, exposure_us, gain, pixel_format) -> None:
        try:
            if pixel_format != BAYER_RG12:
                self.problem = f"pixel format {pixel_format:#x}: the lab sensor fills BayerRG12 only"
                return
            lib = self._lib
            width, height = lib.arv_buffer_get_image_width(buffer), lib.arv_buffer_get_image_height(buffer)
            data = lib.arv_buffer_get_data(buffer, None)
            priv = ctypes.c_void_p.from_address(buffer + _GOBJECT_SIZE).value
            allocated = ctypes.c_size_t.from_address(priv).value
            size = 2 * width * height
            if ctypes.c_void_p.from_address(priv + _PRIV_DATA).value != data or allocated < size:
                self.problem = "this Aravis's buffer layout is not the one hairdigi knows: frames left empty"
                return
            counts = self.counts(width, height, float(exposure_us), float(gain))
            ctypes.memmove(data, counts.ctypes.data, size)
            ctypes.c_size_t.from_address(priv + _PRIV_RECEIVED).value = size
            self.frames += 1
        except Exception as exc:     # a ctypes callback cannot raise: the frame is left empty and read() says so
            self.problem = f"{type(exc).__name__}: {exc}"


_xml_lock = threading.Lock()


def use_lab_genicam() -> Path:
    """Make Aravis's in-process fake camera load the lab camera's GenICam file (written once per process)."""
    aravis = load_aravis()
    with _xml_lock:
        xml = aravis.FakeCamera.new("hairdigi").get_genicam_xml()
        xml = lab_genicam_xml(xml[0] if isinstance(xml, tuple) else xml)
        name = f"hairdigi-fake-lab-camera-{hashlib.sha256(xml.encode()).hexdigest()[:12]}.xml"
        path = Path(tempfile.gettempdir()) / name      # one file per Aravis version, shared by processes
        if not path.exists():
            with atomic_path(path, ".xml") as tmp:
                Path(tmp).write_text(xml)
        aravis.set_fake_camera_genicam_filename(str(path))
        aravis.enable_interface("Fake")
    return path


def open_lab_camera(scene: Callable[[], np.ndarray], settings: GenICamSettings = GenICamSettings(),
                    response=(1.0, 1.0, 1.0), size: tuple[int, int] | None = None,
                    device_id: str = FAKE_ID) -> tuple[GenICamCamera, LabSensor]:
    """The fake camera as a 12-bit lab camera showing ``scene``, opened through :class:`GenICamCamera`;
    ``size`` (width, height) sets its region."""
    if device_id != FAKE_ID:
        raise CameraError(f"genicam:{device_id}: the simulated rig shows through Aravis's in-process fake camera "
                          f"({FAKE_ID}) only; leave out --sim for a real camera")
    use_lab_genicam()
    if size is not None:
        settings = GenICamSettings(**{**settings.__dict__, "region": (0, 0, int(size[0]), int(size[1]))})
    sensor = LabSensor(scene, response)
    camera = GenICamCamera(FAKE_ID, settings, on_open=sensor.attach)   # its frames are the sensor's from the first
    camera.sensor = sensor
    return camera, sensor
