"""Mitsuba scene dictionaries: the swatch rig, the white furnace, and portraits of hairstyles.

Every builder returns a plain dict for ``mi.load_dict``. The hair shape is always keyed ``"hair"``,
its BSDF ``"hair.bsdf"``, the camera ``"sensor"`` and the rig lights ``"light0"``–``"light2"``: the
renderer updates those through ``mi.traverse`` without reloading the scene.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hairdigi.render.domain.absorption import albedo_from_sigma_a
from hairdigi.render.domain.rig_geometry import (CHART_BOARD_HALF, CHART_CENTER, CHART_PATCH, HOLDER_CENTER, HOLDER_SIZE, LIGHT_SIZE,
                                                 N_LIGHTS, CameraPose, chart_patch_centres, framing_fov, light_position,
                                                 look_at_matrix, spherical_direction)
from hairdigi.render.head import head_plys
from hairdigi.render.spectra import mitsuba_spectrum
from hairdigi.render.variant import transform

# The rig: a flat holder in the z = 0 plane, its normal along +z, strands along y.
HOLDER_ALBEDO = 0.18          # mid grey, like a photographic grey card
LIGHT_RADIANCE = 16.0

from hairdigi.render.domain.bounds import ENVIRONMENTS, Environment  # noqa: E402  (without Mitsuba, for the command line)
from hairdigi.render.domain.rig_geometry import Framing  # noqa: E402
from hairdigi.render.domain.text_enum import text_of  # noqa: E402
SKIN_ALBEDO = (0.55, 0.38, 0.30)


def look_at(origin, target, up_hint=(0.0, 1.0, 0.0)):
    """``rig_geometry.look_at_matrix`` as a Mitsuba transform."""
    return transform(look_at_matrix(origin, target, up_hint))


def placed(center, half_size, z: float = 0.0):
    """The transform that lays Mitsuba's 2 x 2 ``rectangle`` on the holder: centred at ``center``
    (x, y) and ``z``, ``half_size`` (x, y) half-extents."""
    return transform([[half_size[0], 0, 0, center[0]], [0, half_size[1], 0, center[1]], [0, 0, 1, z], [0, 0, 0, 1]])


def sensor(camera_pose: CameraPose, target, size: int | tuple[int, int], fov_deg: float,
           spp: int = 16, crop: tuple[int, int, int, int] | None = None) -> dict:
    width, height = (size, size) if isinstance(size, int) else size
    film = {"type": "hdrfilm", "width": width, "height": height, "pixel_format": "rgb",
            "rfilter": {"type": "box"}}
    if crop is not None:
        film.update(crop_offset_x=int(crop[0]), crop_offset_y=int(crop[1]), crop_width=int(crop[2]),
                    crop_height=int(crop[3]))
    return {
        "type": "perspective",
        "fov": fov_deg,
        "fov_axis": "x",
        "to_world": look_at(camera_pose.position(target), np.asarray(target, float)),
        "film": film,
        "sampler": {"type": "independent", "sample_count": spp},
    }


def area_light(position: np.ndarray, target, size: float, radiance: float | tuple) -> dict:
    """A square area light (a softbox) at ``position`` facing ``target``."""
    to_world = transform(look_at_matrix(position, target) @ np.diag([size / 2, size / 2, 1.0, 1.0]))
    value = [radiance] * 3 if np.isscalar(radiance) else list(radiance)
    return {"type": "rectangle", "to_world": to_world, "flip_normals": False,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": value}}}


def hair_shape(curve_file: str, bsdf: dict) -> dict:
    return {"type": "bsplinecurve", "filename": curve_file, "bsdf": bsdf}


def integrator(max_depth: int) -> dict:
    """Path tracer; Russian roulette from depth 5 (measured 2.4x faster than none, same mean)."""
    return {"type": "path", "max_depth": int(max_depth), "rr_depth": 5}


def rig_lights(intensities=(1.0,) * N_LIGHTS) -> dict:
    """The bench lights, keyed ``light0``, ``light1``, ...; each faces the holder's centre."""
    return {f"light{i}": area_light(light_position(i), (0, 0, 0), LIGHT_SIZE, LIGHT_RADIANCE * float(intensities[i]))
            for i in range(N_LIGHTS)}


def chart_patches(reflectances: np.ndarray, center=CHART_CENTER) -> dict:
    """A 6 x 4 colour chart of diffuse patches lying on the holder, keyed ``chart00``–``chart23``.

    ``reflectances`` is (24, 3) linear RGB in the renderer's colour space, row by row from the top
    left (brown skin) as on an X-Rite ColorChecker Classic viewed with its dark skin patch top-left.
    """
    reflectances = np.clip(np.asarray(reflectances, float).reshape(24, 3), 0.0, 1.0)
    shapes = {"chart_board": {
        "type": "rectangle",
        "to_world": placed(center, CHART_BOARD_HALF, 0.0005),
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.02, 0.02, 0.02]}},
    }}
    for i, ((x, y), rgb) in enumerate(zip(chart_patch_centres(center), reflectances)):
        shapes[f"chart{i:02d}"] = {
            "type": "rectangle",
            "to_world": placed((x, y), (CHART_PATCH / 2, CHART_PATCH / 2), 0.001),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb.tolist()}},
        }
    return shapes


PORTRAIT_FOV = 36.0


def swatch_scene(curve_file: str, bsdf: dict, camera_pose: CameraPose, size: int, framing: Framing = Framing.CROP,
                 max_depth: int = 16, lights=(1.0,) * N_LIGHTS, chart: np.ndarray | None = None,
                 target=(0.0, 0.0, 0.0), half_width: float | None = None,
                 crop: tuple[int, int, int, int] | None = None, env: Environment = Environment.STUDIO) -> dict:
    """The bench: holder, swatch, its lights and a camera on a sphere around the holder's normal;
    ``env`` ``Environment.KEY_SKY`` adds a key light and a grey sky (set the rig's lights to 0 to see it alone)."""
    fov = framing_fov(framing, camera_pose.distance, half_width)
    scene = {
        "type": "scene",
        "integrator": integrator(max_depth),
        "sensor": sensor(camera_pose, target, size, fov, crop=crop),
        "holder": {
            "type": "rectangle",
            "to_world": placed(HOLDER_CENTER, (HOLDER_SIZE[0] / 2, HOLDER_SIZE[1] / 2)),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [HOLDER_ALBEDO] * 3}},
        },
        "hair": hair_shape(curve_file, bsdf),
        **rig_lights(lights),
    }
    if chart is not None:
        scene.update(chart_patches(chart))
    if env == Environment.KEY_SKY:
        scene.update(key_and_sky())
    return scene


#: The swatch away from the rig (``Environment.KEY_SKY``): one key light and a grey sky; the rig's lights
#: are set to 0 by the scene spec.
KEY_POSITION = (-1.6, -2.2, 2.6)      # low on the root side, across the fibres: unlike any rig light
KEY_RADIANCE = 24.0
KEY_SIZE = 0.6
SKY_RADIANCE = 0.25


def key_and_sky() -> dict:
    return {"key": area_light(np.array(KEY_POSITION), (0, 0, 0), KEY_SIZE, KEY_RADIANCE),
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [SKY_RADIANCE] * 3}}}


def furnace_scene(curve_file: str, bsdf: dict, camera_pose: CameraPose, size: int, max_depth: int = 256) -> dict:
    """Hair alone under a uniform white environment of radiance 1: a lossless fibre must look white."""
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth, "rr_depth": max_depth},
        "sensor": sensor(camera_pose, (0, 0, 0), size, framing_fov(Framing.CROP, camera_pose.distance)),
        "hair": hair_shape(curve_file, bsdf),
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
    }


PORTRAIT_CAMERA = CameraPose(polar_deg=0.0, azimuth_deg=90.0, distance=7.5)
PORTRAIT_TARGET = (0.0, -0.55, 0.0)


def portrait_camera_position(pose: CameraPose) -> np.ndarray:
    """Portrait cameras orbit the head: polar from the face direction (+z), azimuth from +x."""
    return np.asarray(PORTRAIT_TARGET) + pose.distance * spherical_direction(pose.polar_deg, pose.azimuth_deg)


def portrait_lights(env: Environment) -> dict:
    if text_of(env) not in ENVIRONMENTS:
        raise ValueError(f"unknown environment {env!r}; choose one of {', '.join(ENVIRONMENTS)}")
    env = Environment(env)
    if env is Environment.STUDIO:  # three-point: key front-right-high, fill front-left, rim behind
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


def scalp_albedo(sigma_a) -> list[float]:
    """The scalp under the hair, as the fibre's albedo darkened by the hair's own shadow."""
    return (SCALP_SHADE * albedo_from_sigma_a(np.asarray(sigma_a, float))).tolist()


SCALP_SHADE = 0.5


def portrait_scene(curve_file: str, bsdf: dict, size: int, env: Environment = Environment.STUDIO,
                   camera_pose: CameraPose = PORTRAIT_CAMERA, max_depth: int = 16,
                   part_x: float | None = None) -> dict:
    """A hairstyle on the head (``head.py``'s bust), with the camera in front of the face.

    The bust is two PLYs written once beside ``curve_file``: the skin, and the scalp (keyed
    ``"scalp"``) whose colour the renderer sets from the hair's (``scalp_albedo``), so that the few
    thousand strands a preview can afford read as a full head of hair; a parting at ``part_x`` stays skin.
    """
    position = portrait_camera_position(camera_pose)
    skin_file, scalp_file = head_plys(Path(curve_file).parent, part_x)
    return {
        "type": "scene",
        "integrator": integrator(max_depth),
        "sensor": {**sensor(camera_pose, PORTRAIT_TARGET, size, PORTRAIT_FOV),
                   "to_world": look_at(position, np.asarray(PORTRAIT_TARGET))},
        "head": {"type": "ply", "filename": str(skin_file), "face_normals": False,
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(SKIN_ALBEDO)}}},
        "scalp": {"type": "ply", "filename": str(scalp_file), "face_normals": False,
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.05, 0.03, 0.02]}}},
        "hair": hair_shape(curve_file, bsdf),
        **portrait_lights(env),
    }


def spectralise(scene: dict, sigma_a: dict[str, np.ndarray], spd: np.ndarray,
                chart: np.ndarray | None = None) -> dict:
    """The RGB scene ``scene`` for a spectral variant, in place: each hair shape ``key`` of ``sigma_a``
    absorbs its spectrum, and every light emits ``spd`` (``render.spectra``: luminance 1) at its RGB
    radiance's luminance (a tint, such as a portrait sky's blue, gives way to the light's own colour).
    ``chart``: (24, n) spectral reflectances of the chart's patches. Other diffuse RGB albedos are left
    to Mitsuba's spectral upsampling."""
    def light(radiance: dict) -> dict:
        if radiance.get("type") != "rgb":
            raise ValueError(f"a light of the RGB scene is not an RGB radiance: {radiance}")
        luminance = float(np.dot(radiance["value"], (0.2126, 0.7152, 0.0722)))   # linear sRGB's Y
        return mitsuba_spectrum(np.asarray(spd, float) * luminance)

    for key, item in scene.items():
        if not isinstance(item, dict):
            continue
        if key in sigma_a:
            item["bsdf"]["sigma_a"] = mitsuba_spectrum(sigma_a[key])
        elif "emitter" in item:
            item["emitter"]["radiance"] = light(item["emitter"]["radiance"])
        elif item.get("type") == "constant":
            item["radiance"] = light(item["radiance"])
    missing = set(sigma_a) - set(scene)
    if missing:
        raise ValueError(f"no hair shape {sorted(missing)} in the scene")
    if chart is not None:
        for i, reflectance in enumerate(np.asarray(chart, float)):
            scene[f"chart{i:02d}"]["bsdf"]["reflectance"] = mitsuba_spectrum(np.clip(reflectance, 0.0, 1.0))
    return scene


def camera_film(sensor: dict, bands: np.ndarray) -> dict:
    """A sensor dict's film, in place, made Mitsuba's ``specfilm`` with a camera's (n, 3) R, G, B bands on
    ``render.spectra.WAVELENGTHS`` (``render.spectra.camera_bands``: unit area, so an equal-energy
    radiance of 1 reads 1 in every channel), its size, crop and filter kept: raw camera RGB."""
    bands = np.asarray(bands, float)
    film = sensor["film"]
    film["type"] = "specfilm"
    film.pop("pixel_format", None)
    film["component_format"] = "float32"
    for k, band in enumerate(("band1_r", "band2_g", "band3_b")):   # specfilm orders channels by name
        film[band] = mitsuba_spectrum(bands[:, k])
    return sensor
