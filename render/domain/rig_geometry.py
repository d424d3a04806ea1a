"""The rig's geometry, numpy only: the holder, the three lights, the bench camera, the chart's layout,
camera poses, and the mapping between rig-view pixels and the holder plane, both ways.

What places a thing on the rig reads it here: the scene builders (``render.scenes``), the simulated
rig, the chart targets' patch boxes (``render.chart``) and the twin's view (``app.session.rig_session``). The
chart and swatch finders work from the image alone. Importing it loads no Mitsuba.

Coordinates: the holder is the z = 0 plane, its normal +z, strands along y; scene units are
arbitrary (the swatch is 1 x 1.4). Camera frames follow Mitsuba's ``look_at``: camera +x is the
image's left, +y its up, +z the viewing direction.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.text_enum import TextEnum


class GeometryError(HairdigiError, ValueError):
    """A camera pose or a frame's region the rig cannot have; the message names it and what would work."""


# --- the holder and the lights -------------------------------------------------------------
HOLDER_SIZE = (3.8, 4.0)      # the 1 x 1.4 swatch, with room for the chart on its right
HOLDER_CENTER = (0.6, -0.75)
#: Bench light positions: (polar°, azimuth°) around the holder normal, at LIGHT_DISTANCE.
LIGHT_POSITIONS = ((50.0, 90.0), (50.0, 210.0), (50.0, 330.0))
#: The number of lights on the rig; the light board's protocol and the firmware have as many channels.
N_LIGHTS = len(LIGHT_POSITIONS)
LIGHT_DISTANCE = 3.0
LIGHT_SIZE = 0.8

# --- cameras ---------------------------------------------------------------------------------
CAMERA_DISTANCE = 4.0


class Framing(TextEnum):
    """What a swatch render shows: "crop", only hair (as the training set); "rig", the whole swatch on its holder."""

    CROP = "crop"
    RIG = "rig"


#: Half-width of the view at the holder for each framing. "crop" sees only hair, even at the
#: steepest training camera (45°: 0.28 / cos 45° = 0.40 < 0.5, the swatch half-width);
#: "rig" sees the whole swatch on its holder.
FRAMING_HALF_WIDTH = {Framing.CROP: 0.28, Framing.RIG: 0.95}


@dataclass(frozen=True)
class CameraPose:
    """A camera on a sphere around a target: polar angle from the normal (+z), azimuth, distance."""

    polar_deg: float = 0.0
    azimuth_deg: float = 0.0
    distance: float = CAMERA_DISTANCE

    def __post_init__(self) -> None:
        if not 0.0 <= self.polar_deg < 90.0:
            raise GeometryError(f"camera polar angle {self.polar_deg}° must be in [0, 90)")
        if not self.distance > 0.0:
            raise GeometryError(f"camera distance {self.distance} must be positive")

    def position(self, target: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        return np.asarray(target, float) + self.distance * spherical_direction(self.polar_deg, self.azimuth_deg)

    @classmethod
    def parse(cls, text: str, default_distance: float = CAMERA_DISTANCE) -> "CameraPose":
        """From ``"POLAR,AZIMUTH[,DIST]"`` in degrees and scene units."""
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise GeometryError(f"camera {text!r} must be POLAR,AZIMUTH[,DIST] numbers, e.g. 20,45") from None
        if len(values) not in (2, 3):
            raise GeometryError(f"camera {text!r} must be POLAR,AZIMUTH[,DIST], e.g. 20,45 or 20,45,4")
        return cls(*values) if len(values) == 3 else cls(*values, distance=default_distance)


def spherical_direction(polar_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector at ``polar`` from +z and ``azimuth`` from +x."""
    t, p = np.radians(polar_deg), np.radians(azimuth_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def look_at_matrix(origin, target, up_hint=(0.0, 1.0, 0.0)) -> np.ndarray:
    """The 4 x 4 camera-to-world matrix of Mitsuba's ``look_at`` (columns: left, up, forward,
    origin); an up hint parallel to the view is replaced by +x."""
    origin, target = np.asarray(origin, float), np.asarray(target, float)
    forward = target - origin
    forward /= np.linalg.norm(forward)
    up = np.asarray(up_hint, float)
    if abs(np.dot(up, forward)) > 0.999:
        up = np.array([1.0, 0.0, 0.0])
    left = np.cross(up, forward)
    left /= np.linalg.norm(left)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = left, np.cross(forward, left), forward, origin
    return matrix


def framing_fov(framing: str, distance: float, half_width: float | None = None) -> float:
    """Horizontal field of view (degrees) showing ``half_width`` (default: the framing's) at the
    holder from ``distance``."""
    if half_width is None:
        if framing not in FRAMING_HALF_WIDTH:
            raise ValueError(f"unknown framing {framing!r}; choose one of {', '.join(FRAMING_HALF_WIDTH)}")
        half_width = FRAMING_HALF_WIDTH[framing]
    return float(np.degrees(2 * np.arctan(half_width / distance)))


def project(points: np.ndarray, pose: CameraPose, target, half_width: float, size: tuple[int, int]) -> np.ndarray:
    """Pixel coordinates (u, v) of world points seen by the swatch camera at ``pose`` around ``target``,
    whose horizontal field of view shows ``half_width`` at the target. For the bench camera (polar 0)
    on the holder plane it equals ``rig_pixel``."""
    width, height = size
    m = look_at_matrix(pose.position(target), target)
    rel = np.atleast_2d(np.asarray(points, float)) - m[:3, 3]
    x, y, z = rel @ m[:3, 0], rel @ m[:3, 1], rel @ m[:3, 2]
    focal = (width / 2) / (half_width / pose.distance)
    return np.column_stack([width / 2 - focal * x / z, height / 2 - focal * y / z])


# --- lights as obstacles ---------------------------------------------------------------------
def light_position(index: int) -> np.ndarray:
    """Centre of rig light ``index`` (it faces the holder's centre)."""
    return LIGHT_DISTANCE * spherical_direction(*LIGHT_POSITIONS[index])


def square_corners(position, size: float, target=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(4, 3) corners of a ``size`` square at ``position`` facing ``target`` (an area light)."""
    m = look_at_matrix(np.asarray(position, float), np.asarray(target, float))
    half = size / 2
    return np.array([m[:3, 3] + half * (sx * m[:3, 0] + sy * m[:3, 1]) for sx, sy in
                     ((-1, -1), (1, -1), (1, 1), (-1, 1))])


@functools.lru_cache(maxsize=None)
def light_corners(index: int) -> np.ndarray:
    """(4, 3) corners of rig light ``index``, a LIGHT_SIZE square facing the holder (read-only, cached)."""
    corners = square_corners(light_position(index), LIGHT_SIZE)
    corners.setflags(write=False)
    return corners


def light_blocks_view(pose: CameraPose, half_width: float = FRAMING_HALF_WIDTH[Framing.CROP],
                      target=(0.0, 0.0, 0.0), samples: int = 5) -> bool:
    """Whether a rig light stands between the camera and the framed square of the holder.

    The lights are one-sided softboxes at 50° from the normal: a camera behind one sees its dark
    back (a black or part-black image). Rays go to a ``samples`` x ``samples`` grid over the square.
    """
    camera = pose.position(target)
    grid = np.linspace(-half_width, half_width, samples)
    ends = np.array([(target[0] + x, target[1] + y, target[2]) for x in grid for y in grid])
    for i in range(N_LIGHTS):
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


# --- the colour chart ------------------------------------------------------------------------
CHART_CENTER = (1.35, 0.0)
CHART_PATCH = 0.17
CHART_GAP = 0.03
CHART_ROWS, CHART_COLS = 4, 6
CHART_PITCH = CHART_PATCH + CHART_GAP
#: Half-size (x, y) of the chart's black board: the patches and a gap around them.
CHART_BOARD_HALF = (CHART_COLS / 2 * CHART_PITCH + CHART_GAP, CHART_ROWS / 2 * CHART_PITCH + CHART_GAP)


def chart_patch_centres(center=CHART_CENTER) -> np.ndarray:
    """(24, 2) holder-plane centres of the chart's patches, row by row from the top left."""
    return np.array([(center[0] + (col - (CHART_COLS - 1) / 2) * CHART_PITCH,
                      center[1] + ((CHART_ROWS - 1) / 2 - row) * CHART_PITCH)
                     for row in range(CHART_ROWS) for col in range(CHART_COLS)])


# --- the bench camera's view -----------------------------------------------------------------
# Straight down on the holder, the swatch on the left and the chart on its right, in a 4:3 frame.
RIG_TARGET = (0.725, 0.0, 0.0)
RIG_HALF_WIDTH = 1.375
#: The bench camera as the swatch's centre sees it: above RIG_TARGET at CAMERA_DISTANCE, so 10.3°
#: off the swatch's normal towards the chart. Refinement renders the swatch from this pose.
RIG_SWATCH_POSE = CameraPose(float(np.degrees(np.arctan2(RIG_TARGET[0], CAMERA_DISTANCE))), 0.0,
                             float(np.hypot(RIG_TARGET[0], CAMERA_DISTANCE)))
#: Away from the rig (the transfer check): another camera over the swatch, all hair in view; lit by
#: ``Environment.KEY_SKY``'s key light and grey sky.
TRANSFER_POSE = CameraPose(40.0, 30.0)


def rig_scale(size: tuple[int, int]) -> float:
    """Pixels per holder unit in a rig-view frame of ``size`` (width, height)."""
    return size[0] / (2 * RIG_HALF_WIDTH)


def rig_pixel(x, y, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates of holder-plane points (z = 0) in the rig view (the bench camera looks
    straight at the plane, so the map is linear; the image's up is +y)."""
    width, height = size
    scale = rig_scale(size)
    return ((np.asarray(x) - RIG_TARGET[0]) * scale + width / 2,
            (RIG_TARGET[1] - np.asarray(y)) * scale + height / 2)


# --- a region of a rig-view frame --------------------------------------------------------------
@dataclass(frozen=True)
class RigRegion:
    """A region (``roi``: x, y, w, h pixels) of a frame of ``frame_size`` taken by the rig camera at
    ``pose`` around ``target``, whose field of view shows ``half_width`` at the target.

    The refinement fits the capture's mean colour over exactly this region and renders exactly this
    region (the same camera, its film cropped), so the rig's light fall-off and the view's angles
    across the swatch are in both. The twin shows it too.
    """

    frame_size: tuple[int, int]
    roi: tuple[int, int, int, int]
    pose: CameraPose = CameraPose()
    target: tuple[float, float, float] = RIG_TARGET
    half_width: float = RIG_HALF_WIDTH

    def __post_init__(self) -> None:
        x, y, w, h = self.roi
        width, height = self.frame_size
        if w < 1 or h < 1 or x < 0 or y < 0 or x + w > width or y + h > height:
            raise GeometryError(f"region {self.roi} is not inside the {width}x{height} frame")

    def render_plan(self, pixels: int = 48 * 48) -> tuple[tuple[int, int], tuple[int, int, int, int],
                                                          tuple[int, int, int, int]]:
        """A render of about ``pixels`` pixels over the region: (film size, crop x, y, w, h in film
        pixels, and the frame's region that crop shows exactly, x, y, w, h in frame pixels)."""
        x, y, w, h = self.roi
        width, height = self.frame_size
        scale = min(1.0, float(np.sqrt(pixels / (w * h))))
        film = (max(1, int(round(width * scale))), max(1, int(round(height * scale))))
        sx, sy = film[0] / width, film[1] / height
        cx0, cy0 = int(np.floor(x * sx + 1e-9)), int(np.floor(y * sy + 1e-9))
        cx1 = min(film[0], max(cx0 + 1, int(np.ceil((x + w) * sx - 1e-9))))
        cy1 = min(film[1], max(cy0 + 1, int(np.ceil((y + h) * sy - 1e-9))))
        fx0, fy0 = int(round(cx0 / sx)), int(round(cy0 / sy))
        fx1, fy1 = min(width, int(round(cx1 / sx))), min(height, int(round(cy1 / sy)))
        return film, (cx0, cy0, cx1 - cx0, cy1 - cy0), (fx0, fy0, fx1 - fx0, fy1 - fy0)

    def to_dict(self) -> dict:
        return {"frame_size": list(self.frame_size), "roi": list(self.roi),
                "pose": [self.pose.polar_deg, self.pose.azimuth_deg, self.pose.distance],
                "target": list(self.target), "half_width": self.half_width}


#: The swatch's extent on the holder (x and y half-sizes): 1 x 1.4 scene units, centred at the origin.
SWATCH_HALF = (0.5, 0.7)


#: How much of its 0.7 half-length the default (layered) swatch shows: all of it, as its strands
#: pass through their ends. The first swatch ("today") showed about 0.58: Mitsuba's B-spline stops
#: short of its end points.
SWATCH_VISIBLE_HALF_LENGTH = 0.7


def swatch_roi(size: tuple[int, int], margin: float = 0.05, visible_half_length: float = SWATCH_VISIBLE_HALF_LENGTH,
               pose: CameraPose = CameraPose(), half_width: float = RIG_HALF_WIDTH) -> tuple[int, int, int, int]:
    """The swatch's visible area in a rig-view frame of ``size``, as x, y, w, h pixels, inset by
    ``margin`` units (``visible_half_length``: how much of its half-length the swatch shows, as
    ``SWATCH_VISIBLE_HALF_LENGTH``). ``pose`` (around ``RIG_TARGET``) and
    ``half_width`` are the camera's; the default is the bench camera. A tilted camera sees the swatch
    as a quadrilateral: the box is the largest one inside it."""
    half_w, half_l = SWATCH_HALF[0] - margin, visible_half_length - margin
    if pose == CameraPose() and half_width == RIG_HALF_WIDTH:
        (x0, x1), (y0, y1) = rig_pixel(np.array([-half_w, half_w]), np.array([half_l, -half_l]), size)
        return int(np.ceil(x0)), int(np.ceil(y0)), int(x1 - x0), int(y1 - y0)
    corners = np.array([(x, y, 0.0) for x in (-half_w, half_w) for y in (half_l, -half_l)])
    uv = project(corners, pose, RIG_TARGET, half_width, size)   # (-,+) (-,-) (+,+) (+,-)
    xs_a, xs_b = uv[[0, 1], 0], uv[[2, 3], 0]          # the two long edges (x = -half_w and x = +half_w)
    ys_a, ys_b = uv[[0, 2], 1], uv[[1, 3], 1]          # the two ends (y = +half_l and y = -half_l)
    lo_x, hi_x = (xs_a.max(), xs_b.min()) if xs_a.mean() < xs_b.mean() else (xs_b.max(), xs_a.min())
    lo_y, hi_y = (ys_a.max(), ys_b.min()) if ys_a.mean() < ys_b.mean() else (ys_b.max(), ys_a.min())
    x0, y0 = int(np.ceil(lo_x)), int(np.ceil(lo_y))
    return x0, y0, int(np.floor(hi_x)) - x0, int(np.floor(hi_y)) - y0

