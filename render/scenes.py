"""Mitsuba scene dictionaries: the swatch rig, the white furnace, and portraits of hairstyles.

Every builder returns a plain dict for ``mi.load_dict``. The hair shape is always keyed ``"hair"``,
its BSDF ``"hair.bsdf"``, the camera ``"sensor"`` and the rig lights ``"light0"``–``"light2"``: the
renderer updates those through ``mi.traverse`` without reloading the scene.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from hairdigi.render.variant import mi

# The rig: a flat holder in the z = 0 plane, its normal along +z, strands along y.
HOLDER_SIZE = (3.8, 4.0)      # the 1 x 1.4 swatch, with room for the chart on its right
HOLDER_CENTER = (0.6, -0.75)
HOLDER_ALBEDO = 0.18          # mid grey, like a photographic grey card
#: Bench light positions: (polar°, azimuth°) around the holder normal, at LIGHT_DISTANCE.
LIGHT_POSITIONS = ((50.0, 90.0), (50.0, 210.0), (50.0, 330.0))
LIGHT_DISTANCE = 3.0
LIGHT_SIZE = 0.8
LIGHT_RADIANCE = 16.0
#: Half-width of the view at the holder for each framing. "crop" sees only hair, even at the
#: steepest training camera (45°: 0.28 / cos 45° = 0.40 < 0.5, the swatch half-width);
#: "rig" sees the whole swatch on its holder.
FRAMING_HALF_WIDTH = {"crop": 0.28, "rig": 0.95}
CAMERA_DISTANCE = 4.0

ENVIRONMENTS = ("studio", "soft")
SKIN_ALBEDO = (0.55, 0.38, 0.30)


@dataclass(frozen=True)
class CameraPose:
    """A camera on a sphere around a target: polar angle from the normal (+z), azimuth, distance."""

    polar_deg: float = 0.0
    azimuth_deg: float = 0.0
    distance: float = CAMERA_DISTANCE

    def __post_init__(self) -> None:
        if not 0.0 <= self.polar_deg < 90.0:
            raise ValueError(f"camera polar angle {self.polar_deg}° must be in [0, 90)")
        if not self.distance > 0.0:
            raise ValueError(f"camera distance {self.distance} must be positive")

    def position(self, target: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        return np.asarray(target, float) + self.distance * spherical_direction(self.polar_deg, self.azimuth_deg)

    @classmethod
    def parse(cls, text: str, default_distance: float = CAMERA_DISTANCE) -> "CameraPose":
        """From ``"POLAR,AZIMUTH[,DIST]"`` in degrees and scene units."""
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise ValueError(f"camera {text!r} must be POLAR,AZIMUTH[,DIST] numbers, e.g. 20,45") from None
        if len(values) not in (2, 3):
            raise ValueError(f"camera {text!r} must be POLAR,AZIMUTH[,DIST], e.g. 20,45 or 20,45,4")
        return cls(*values) if len(values) == 3 else cls(*values, distance=default_distance)


def spherical_direction(polar_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector at ``polar`` from +z and ``azimuth`` from +x."""
    t, p = np.radians(polar_deg), np.radians(azimuth_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def look_at(origin: np.ndarray, target: np.ndarray, up_hint: np.ndarray = np.array([0.0, 1.0, 0.0])):
    """A ``mi.ScalarTransform4f`` looking from ``origin`` at ``target``; the up hint is made safe."""
    forward = np.asarray(target, float) - np.asarray(origin, float)
    forward /= np.linalg.norm(forward)
    up = np.asarray(up_hint, float)
    if abs(np.dot(up, forward)) > 0.999:
        up = np.array([1.0, 0.0, 0.0])
    return mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=list(map(float, target)),
                                          up=up.tolist())


def sensor(camera_pose: CameraPose, target, size: int | tuple[int, int], fov_deg: float,
           spp: int = 16) -> dict:
    width, height = (size, size) if isinstance(size, int) else size
    return {
        "type": "perspective",
        "fov": fov_deg,
        "fov_axis": "x",
        "to_world": look_at(camera_pose.position(target), np.asarray(target, float)),
        "film": {"type": "hdrfilm", "width": width, "height": height, "pixel_format": "rgb",
                 "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": spp},
    }


def framing_fov(framing: str, distance: float) -> float:
    if framing not in FRAMING_HALF_WIDTH:
        raise ValueError(f"unknown framing {framing!r}; choose one of {', '.join(FRAMING_HALF_WIDTH)}")
    return float(np.degrees(2 * np.arctan(FRAMING_HALF_WIDTH[framing] / distance)))


def area_light(position: np.ndarray, target, size: float, radiance: float | tuple) -> dict:
    """A square area light (a softbox) at ``position`` facing ``target``."""
    to_world = look_at(position, np.asarray(target, float)) @ mi.ScalarTransform4f().scale([size / 2, size / 2, 1])
    value = [radiance] * 3 if np.isscalar(radiance) else list(radiance)
    return {"type": "rectangle", "to_world": to_world, "flip_normals": False,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": value}}}


def hair_shape(curve_file: str, bsdf: dict) -> dict:
    return {"type": "bsplinecurve", "filename": curve_file, "bsdf": bsdf}


def integrator(max_depth: int) -> dict:
    """Path tracer; Russian roulette from depth 5 (measured 2.4x faster than none, same mean)."""
    return {"type": "path", "max_depth": int(max_depth), "rr_depth": 5}


def rig_lights(intensities=(1.0, 1.0, 1.0)) -> dict:
    """The three bench lights, keyed ``light0``–``light2``."""
    return {f"light{i}": area_light(light_position(i), (0, 0, 0), LIGHT_SIZE, LIGHT_RADIANCE * float(intensities[i]))
            for i in range(len(LIGHT_POSITIONS))}


def light_position(index: int) -> np.ndarray:
    """Centre of rig light ``index`` (it faces the holder's centre)."""
    return LIGHT_DISTANCE * spherical_direction(*LIGHT_POSITIONS[index])


@functools.lru_cache(maxsize=None)
def light_corners(index: int) -> np.ndarray:
    """(4, 3) corners of rig light ``index``, as ``rig_lights`` places it (read-only, cached)."""
    m = np.asarray(look_at(light_position(index), np.zeros(3)).matrix, dtype=float)
    half = LIGHT_SIZE / 2
    corners = np.array([m[:3, 3] + half * (sx * m[:3, 0] + sy * m[:3, 1]) for sx, sy in
                        ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    corners.setflags(write=False)
    return corners


def light_blocks_view(pose: CameraPose, half_width: float = FRAMING_HALF_WIDTH["crop"],
                      target=(0.0, 0.0, 0.0), samples: int = 5) -> bool:
    """Whether a rig light stands between the camera and the framed square of the holder.

    The lights are one-sided softboxes at 50° from the normal: a camera behind one sees its dark
    back (a black or part-black image). Rays go to a ``samples`` x ``samples`` grid over the square.
    """
    camera = pose.position(target)
    grid = np.linspace(-half_width, half_width, samples)
    ends = np.array([(target[0] + x, target[1] + y, target[2]) for x in grid for y in grid])
    for i in range(len(LIGHT_POSITIONS)):
        a, b, _, d = light_corners(i)
        u, v = b - a, d - a
        normal = np.cross(u, v)
        rays = ends - camera
        denom = rays @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((a - camera) @ normal) / denom
        hits = camera + t[:, None] * rays
        s1, s2 = (hits - a) @ u / (u @ u), (hits - a) @ v / (v @ v)
        inside = (np.abs(denom) > 1e-12) & (t > 0) & (t < 1) & (s1 >= 0) & (s1 <= 1) & (s2 >= 0) & (s2 <= 1)
        if inside.any():
            return True
    return False


# The bench camera of the (simulated) rig: straight down on the holder, the swatch on the left and
# a 6 x 4 colour chart on its right, in a 4:3 frame.
CHART_CENTER = (1.35, 0.0)
CHART_PATCH = 0.17
CHART_GAP = 0.03
RIG_TARGET = (0.725, 0.0, 0.0)
RIG_HALF_WIDTH = 1.375
#: The bench camera as the swatch's centre sees it: above RIG_TARGET at CAMERA_DISTANCE, so 10.3°
#: off the swatch's normal towards the chart. Refinement renders the swatch from this pose.
RIG_SWATCH_POSE = CameraPose(float(np.degrees(np.arctan2(RIG_TARGET[0], CAMERA_DISTANCE))), 0.0,
                             float(np.hypot(RIG_TARGET[0], CAMERA_DISTANCE)))


def rig_pixel(x: np.ndarray, y: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates of holder-plane points (z = 0) in the rig view, for a camera at polar 0.

    A pinhole camera looking straight at a plane maps it linearly; the image's up is +y.
    """
    width, height = size
    scale = width / (2 * RIG_HALF_WIDTH)
    return ((np.asarray(x) - RIG_TARGET[0]) * scale + width / 2,
            (RIG_TARGET[1] - np.asarray(y)) * scale + height / 2)


def project(points: np.ndarray, pose: CameraPose, target, half_width: float, size: tuple[int, int]) -> np.ndarray:
    """Pixel coordinates (u, v) of world points seen by the swatch camera at ``pose`` around ``target``.

    The pinhole of ``sensor``: Mitsuba's ``look_at`` frame (camera +x is the image's left, +y its
    up) and a horizontal field of view showing ``half_width`` at the target. For the bench camera
    (polar 0) on the holder plane it equals ``rig_pixel``.
    """
    width, height = size
    origin = pose.position(target)
    forward = np.asarray(target, float) - origin
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 1.0, 0.0]) if abs(forward[1]) < 0.999 else np.array([1.0, 0.0, 0.0])
    left = np.cross(up, forward)
    left /= np.linalg.norm(left)
    new_up = np.cross(forward, left)
    rel = np.atleast_2d(np.asarray(points, float)) - origin
    x, y, z = rel @ left, rel @ new_up, rel @ forward
    focal = (width / 2) / (half_width / pose.distance)
    return np.column_stack([width / 2 - focal * x / z, height / 2 - focal * y / z])


def seen_from(point, pose: CameraPose, target) -> CameraPose:
    """The pose of the camera at ``pose`` around ``target`` as ``point`` sees it (polar from +z)."""
    rel = pose.position(target) - np.asarray(point, float)
    distance = float(np.linalg.norm(rel))
    polar = float(np.degrees(np.arccos(np.clip(rel[2] / distance, -1, 1))))
    azimuth = float(np.degrees(np.arctan2(rel[1], rel[0]))) % 360.0
    return CameraPose(polar, azimuth if polar > 1e-9 else 0.0, distance)


def chart_patch_centres() -> np.ndarray:
    """(24, 2) holder-plane centres of the chart's patches, row by row from the top left."""
    pitch = CHART_PATCH + CHART_GAP
    return np.array([(CHART_CENTER[0] + (col - 2.5) * pitch, CHART_CENTER[1] + (1.5 - row) * pitch)
                     for row in range(4) for col in range(6)])


def chart_patches(reflectances: np.ndarray, center=CHART_CENTER, patch=CHART_PATCH, gap=CHART_GAP) -> dict:
    """A 6 x 4 colour chart of diffuse patches lying on the holder, keyed ``chart00``–``chart23``.

    ``reflectances`` is (24, 3) linear RGB in the renderer's colour space, row by row from the top
    left (brown skin) as on an X-Rite ColorChecker Classic viewed with its dark skin patch top-left.
    """
    reflectances = np.clip(np.asarray(reflectances, float).reshape(24, 3), 0.0, 1.0)
    shapes = {}
    pitch = patch + gap
    shapes["chart_board"] = {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f().translate([center[0], center[1], 0.0005])
        @ mi.ScalarTransform4f().scale([3 * pitch + gap, 2 * pitch + gap, 1]),
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.02, 0.02, 0.02]}},
    }
    for i, rgb in enumerate(reflectances):
        row, col = divmod(i, 6)
        x = center[0] + (col - 2.5) * pitch
        y = center[1] + (1.5 - row) * pitch
        shapes[f"chart{i:02d}"] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().translate([x, y, 0.001])
            @ mi.ScalarTransform4f().scale([patch / 2, patch / 2, 1]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb.tolist()}},
        }
    return shapes


def swatch_fov(framing: str, distance: float, half_width: float | None = None) -> float:
    """Horizontal FOV (degrees) that shows ``half_width`` (or the framing's) at the holder from ``distance``."""
    if half_width is None:
        return framing_fov(framing, distance)
    return float(np.degrees(2 * np.arctan(half_width / distance)))


PORTRAIT_FOV = 36.0


def swatch_scene(curve_file: str, bsdf: dict, camera_pose: CameraPose, size: int, framing: str = "crop",
                 max_depth: int = 16, lights=(1.0, 1.0, 1.0), chart: np.ndarray | None = None,
                 target=(0.0, 0.0, 0.0), half_width: float | None = None) -> dict:
    """The bench: holder, swatch, three lights and a camera on a sphere around the holder's normal."""
    fov = swatch_fov(framing, camera_pose.distance, half_width)
    scene = {
        "type": "scene",
        "integrator": integrator(max_depth),
        "sensor": sensor(camera_pose, target, size, fov),
        "holder": {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().translate([HOLDER_CENTER[0], HOLDER_CENTER[1], 0.0])
            @ mi.ScalarTransform4f().scale([HOLDER_SIZE[0] / 2, HOLDER_SIZE[1] / 2, 1]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [HOLDER_ALBEDO] * 3}},
        },
        "hair": hair_shape(curve_file, bsdf),
        **rig_lights(lights),
    }
    if chart is not None:
        scene.update(chart_patches(chart))
    return scene


def furnace_scene(curve_file: str, bsdf: dict, camera_pose: CameraPose, size: int, max_depth: int = 256) -> dict:
    """Hair alone under a uniform white environment of radiance 1: a lossless fibre must look white."""
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth, "rr_depth": max_depth},
        "sensor": sensor(camera_pose, (0, 0, 0), size, framing_fov("crop", camera_pose.distance)),
        "hair": hair_shape(curve_file, bsdf),
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
    }


PORTRAIT_CAMERA = CameraPose(polar_deg=0.0, azimuth_deg=90.0, distance=7.5)
PORTRAIT_TARGET = (0.0, -0.55, 0.0)


def portrait_camera_position(pose: CameraPose) -> np.ndarray:
    """Portrait cameras orbit the head: polar from the face direction (+z), azimuth from +x."""
    return np.asarray(PORTRAIT_TARGET) + pose.distance * spherical_direction(pose.polar_deg, pose.azimuth_deg)


def portrait_lights(env: str) -> dict:
    if env not in ENVIRONMENTS:
        raise ValueError(f"unknown environment {env!r}; choose one of {', '.join(ENVIRONMENTS)}")
    if env == "studio":  # three-point: key front-right-high, fill front-left, rim behind
        return {
            "key": area_light(np.array([3.5, 3.0, 5.0]), PORTRAIT_TARGET, 2.0, 9.0),
            "fill": area_light(np.array([-5.0, 0.5, 4.0]), PORTRAIT_TARGET, 2.5, 2.5),
            "rim": area_light(np.array([0.0, 0.8, -4.0]), (0.0, 0.3, 0.0), 1.5, 25.0),  # hidden by the head
            "env": {"type": "constant", "radiance": {"type": "rgb", "value": [0.04, 0.04, 0.045]}},
        }
    return {  # soft: overcast, a bright diffuse sky and a broad overhead panel
        "sky": area_light(np.array([0.0, 6.0, 1.0]), (0, 0, 0), 8.0, 1.2),
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": [0.42, 0.44, 0.48]}},
    }


def portrait_scene(curve_file: str, bsdf: dict, size: int, env: str = "studio",
                   camera_pose: CameraPose = PORTRAIT_CAMERA, max_depth: int = 16) -> dict:
    """A hairstyle on the head proxy, with the camera in front of the face."""
    position = portrait_camera_position(camera_pose)
    return {
        "type": "scene",
        "integrator": integrator(max_depth),
        "sensor": {**sensor(camera_pose, PORTRAIT_TARGET, size, PORTRAIT_FOV),
                   "to_world": look_at(position, np.asarray(PORTRAIT_TARGET))},
        "head": {"type": "sphere", "radius": 0.985,
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(SKIN_ALBEDO)}}},
        "neck": {"type": "cylinder", "p0": [0, -2.6, -0.1], "p1": [0, -0.6, -0.1], "radius": 0.45,
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(SKIN_ALBEDO)}}},
        "hair": hair_shape(curve_file, bsdf),
        **portrait_lights(env),
    }
