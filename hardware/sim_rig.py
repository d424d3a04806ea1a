"""The simulated rig: a swatch with hidden "true" hair parameters and a ColorChecker, rendered by Mitsuba.

Each light is rendered alone once (and cached on disk); a frame is the sum of the lights that the
simulated board has switched on, times their intensity, passed through a camera model (exposure,
gain, a white-balance cast, shot and read noise, clipping, sRGB and 8 bits: ``render.camera_model``,
the same model that training applies to its renders). The renders' glints are spread over their
neighbours with their energy kept (``spread_glints``), as a sensor integrates them: removing them
took real light away from hair. Toggling a light
changes the feed at once, with no re-render.
"""
from __future__ import annotations

import hashlib
import json
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hairdigi.hardware.cameras import Frame
from hairdigi.render.domain import rig_geometry
from hairdigi.render.camera_model import NOMINAL_EXPOSURE, CameraModel, sensor_response, spread_glints  # noqa: F401
from hairdigi.render.domain.files import atomic_path, cache_dir
from hairdigi.render.chart import colorchecker_reflectances
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance
from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import DEFAULT_SWATCH_MODEL, Renderer, SceneSpec
from hairdigi.render.swatch_family import REVISIONS

SIM_SIZE = (400, 300)
#: The hidden swatch of the demo: a copper-dyed light brown.
DEFAULT_HIDDEN = HairParams((190, 80, 40), 0.5, 0.5, 0.6)
CACHE_VERSION = 5  # bumped when the absorption mapping or the light images change (4: glints spread, not removed;
#                   5: the layered swatch, render.renderer.DEFAULT_SWATCH_MODEL)


def light_images_path(hidden: HairParams | np.ndarray, size=SIM_SIZE, spp: int = 32, strand_seed: int = 0,
                      pose: rig_geometry.CameraPose = rig_geometry.CameraPose(),
                      half_width: float = rig_geometry.RIG_HALF_WIDTH, appearance: Appearance = DEFAULT_APPEARANCE,
                      illuminant: str | None = None, sensitivities: str | None = None,
                      swatch_model: str | None = None) -> Path:
    """Where ``render_light_images`` caches the light images of these settings (it may not exist yet)."""
    view = [] if pose == rig_geometry.CameraPose() and half_width == rig_geometry.RIG_HALF_WIDTH else \
        [pose.polar_deg, pose.azimuth_deg, pose.distance, half_width]
    look = [] if appearance == DEFAULT_APPEARANCE else [appearance.to_dict()]
    if illuminant is not None:   # a CSV is keyed by its content, so an edited file renders again
        look += [{"illuminant": _content_key(illuminant), "sensitivities": _content_key(sensitivities),
                  "chart": 2}]   # 2: the chart's spectra bent to its reference colours (render.chart)
    if swatch_model not in (None, DEFAULT_SWATCH_MODEL.value):   # with its geometry's revision
        look += [{"swatch_model": swatch_model, "revision": REVISIONS.get(swatch_model, 1)}]
    hair = hidden.to_dict() if isinstance(hidden, HairParams) else [round(float(v), 6) for v in np.ravel(hidden)]
    key = hashlib.sha256(json.dumps([CACHE_VERSION, hair, list(size), spp, strand_seed, *view, *look],
                                    sort_keys=True).encode()).hexdigest()[:16]
    return cache_dir() / "sim-rig" / f"lights-{key}.npz"


def render_light_images(hidden: HairParams | np.ndarray, size=SIM_SIZE, spp: int = 32, strand_seed: int = 0,
                        cache: bool = True, pose: rig_geometry.CameraPose = rig_geometry.CameraPose(),
                        half_width: float = rig_geometry.RIG_HALF_WIDTH,
                        appearance: Appearance = DEFAULT_APPEARANCE, illuminant: str | None = None,
                        sensitivities: str | None = None, swatch_model: str | None = None
                        ) -> tuple[np.ndarray, int]:
    """(3, H, W, 3) linear images of the rig lit by each light alone, and the NaN or Inf values their renders
    returned (replaced by 0; kept in the cache with them; a warning when any), seen by a camera at ``pose``
    around the rig's target (default: the bench camera), cached by their settings. ``hidden`` is
    Table 1 parameters or a median fibre's sigma_a (an absorption spectrum in a spectral rig);
    ``appearance`` its shine and fibre variation. ``illuminant`` (the LEDs' SPD) renders the rig
    spectrally, the chart with its measured spectra, seen by the CIE observer or by a camera's
    ``sensitivities`` (its raw RGB): ``render.renderer.SceneSpec``. ``swatch_model``: the hidden swatch's
    physical structure (``render.swatch_family``; None: hairdigi's own, layered)."""
    path = light_images_path(hidden, size, spp, strand_seed, pose, half_width, appearance, illuminant,
                             sensitivities, swatch_model)
    if cache and path.exists():
        with np.load(path) as data:
            return data["images"], int(data["nonfinite"])
    renderer = Renderer(max_cached=1)
    chart = tuple(map(tuple, colorchecker_reflectances()))
    images, nonfinite = [], 0
    for i in range(rig_geometry.N_LIGHTS):
        lights = tuple(1.0 if j == i else 0.0 for j in range(rig_geometry.N_LIGHTS))
        spec = SceneSpec("swatch", framing="rig", chart=chart, target=rig_geometry.RIG_TARGET, camera=pose,
                         half_width=half_width, lights=lights, strand_seed=strand_seed,
                         appearance=None if appearance == DEFAULT_APPEARANCE else appearance,
                         illuminant=illuminant, sensitivities=sensitivities, swatch_model=swatch_model)
        result = renderer.render(hidden, spec, size, spp, seed=17 + i)
        images.append(result.linear)
        nonfinite += result.nonfinite
    if nonfinite:
        warnings.warn(f"the simulated rig's light images held {nonfinite} NaN or Inf values, rendered as 0",
                      RuntimeWarning, stacklevel=2)
    stack = np.stack([spread_glints(im) for im in images]).astype(np.float32)
    if cache:
        with atomic_path(path, ".npz") as tmp:
            np.savez(tmp, images=stack, nonfinite=nonfinite)
    return stack, nonfinite


def _content_key(name: str | None) -> str | None:
    """A light's or camera's name, or a CSV's name and content hash."""
    if name is None or not Path(name).is_file():
        return name
    return f"{Path(name).name}:{hashlib.sha256(Path(name).read_bytes()).hexdigest()[:16]}"


@dataclass
class SimRig:
    """The bench in software: light images, a camera model, and the board whose state it follows."""

    hidden: HairParams = DEFAULT_HIDDEN
    camera: CameraModel = field(default_factory=CameraModel)
    size: tuple[int, int] = SIM_SIZE
    spp: int = 32
    dead_lights: set[int] = field(default_factory=set)
    seed: int = 0
    board: object | None = None   # a SimulatedLightBoard; None means all lights on at full power
    pose: rig_geometry.CameraPose = rig_geometry.CameraPose()     # the camera around the rig's target
    half_width: float = rig_geometry.RIG_HALF_WIDTH                # what its view shows at the target
    appearance: Appearance = DEFAULT_APPEARANCE                    # the hidden swatch's shine and fibres
    strand_seed: int = 0                                           # its strand layout
    illuminant: str | None = None        # the LEDs' SPD (render.spectra): a spectral rig; None: RGB, white
    sensitivities: str | None = None     # a spectral rig's camera (render.spectra.CAMERAS or a CSV)
    swatch_model: str | None = None      # the hidden swatch's structure (render.swatch_family); None: layered

    def __post_init__(self) -> None:
        #: ``nonfinite``: NaN or Inf values the light images' renders returned (replaced by 0)
        self.light_images, self.nonfinite = render_light_images(self.hidden, self.size, self.spp, self.strand_seed, pose=self.pose,
                                                half_width=self.half_width, appearance=self.appearance,
                                                illuminant=self.illuminant, sensitivities=self.sensitivities,
                                                swatch_model=self.swatch_model)
        self.exposure_offset_ev = 0.0
        self._rng = np.random.default_rng(self.seed)
        self.name = "sim-rig"
        self.frames_served = 0

    def levels(self) -> np.ndarray:
        levels = np.array(self.board.state.levels() if self.board is not None else (1.0,) * rig_geometry.N_LIGHTS, np.float32)
        for i in self.dead_lights:
            levels[i] = 0.0
        return levels

    def radiance(self) -> np.ndarray:
        """Linear radiance reaching the sensor for the current light state, at the bench's nominal
        exposure (``NOMINAL_EXPOSURE``)."""
        scale = NOMINAL_EXPOSURE * 2.0 ** self.exposure_offset_ev
        return np.tensordot(self.levels() * scale, self.light_images, axes=1)

    def set_exposure_offset(self, ev: float) -> bool:
        """Expose the next frames ``ev`` stops longer than the bench's setting (single-light frames)."""
        self.exposure_offset_ev = float(ev)
        return True

    def read(self) -> Frame:
        linear = self.radiance()
        srgb = sensor_response(linear, self.camera, self._rng)
        self.frames_served += 1
        return Frame(srgb, None, {"camera": self.name, "frame": self.frames_served,
                                  "lights": self.levels().tolist(), "camera_model": self.camera.settings(),
                                  "exposure_offset_ev": self.exposure_offset_ev,
                                  "camera_settings": self.settings()},
                     time.time())

    def settings(self) -> dict:
        """What a calibration depends on: the simulated sensor's exposure and gain."""
        model = self.camera.settings()
        return {key: model[key] for key in ("exposure_ev", "gain")}

    def close(self) -> None:
        pass

    @property
    def roi(self) -> tuple[int, int, int, int]:
        return rig_geometry.swatch_roi(self.size, pose=self.pose, half_width=self.half_width)
