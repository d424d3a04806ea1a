"""Each kind of scene is a type that owns its fields, its scene dict and its update; the renderer draws any
of them alike, so a new kind is one new type and no change to the renderer."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from hairdigi.render import scenes
from hairdigi.render.domain.absorption import hair_bsdf
from hairdigi.render.domain.bounds import SceneKind
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import CameraPose, Framing, framing_fov
from hairdigi.render.renderer import Renderer
from hairdigi.render.scene_kinds import (SCENE_TYPES, HairstyleScene, Scene, SceneError, SceneSpec, SwatchScene,
                                         _set)
from hairdigi.render.strands import Strands, swatch_strands

CALLS: list[tuple[str, str]] = []   # (method, type) of each call the renderer made on a FurnaceScene


@dataclass(frozen=True)
class FurnaceScene(Scene):
    """A kind the renderer does not know: the swatch's fibres alone under a white sky (the furnace test)."""

    name: str = "furnace"
    sky: float = 1.0   # its own field: the sky's radiance

    kind: ClassVar[SceneKind] = SceneKind.SWATCH   # the swatch's defaults and camera limits
    default_camera: ClassVar[CameraPose] = CameraPose(0.0, 0.0, 0.8)

    def _settle(self) -> None:
        if not 0 < float(self.sky) < 100:
            raise SceneError(f"sky {self.sky!r}: give a radiance between 0 and 100")
        _set(self, "sky", float(self.sky))

    def make_strands(self) -> Strands:
        return swatch_strands(self.n_strands, seed=self.strand_seed)

    def shape_key(self) -> tuple:
        return super().shape_key() + (self.sky,)

    def scene_dict(self, curve_file: str, bsdf: dict, size) -> dict:
        CALLS.append(("scene_dict", type(self).__name__))
        scene = scenes.furnace_scene(curve_file, bsdf, self.pose, size, self.depth)
        scene["env"]["radiance"]["value"] = [self.sky] * 3
        return scene

    def view(self):
        return self.pose.position((0, 0, 0)), (0.0, 0.0, 0.0), framing_fov(Framing.CROP, self.pose.distance)

    def update(self, params, sigma_a, moved: bool) -> None:
        CALLS.append(("update", type(self).__name__))
        super().update(params, sigma_a, moved)


def test_scene_spec_builds_each_kind_as_its_type() -> None:
    assert set(SCENE_TYPES) == set(SceneKind)
    swatch, style = SceneSpec("swatch", framing="rig"), SceneSpec("bob", framing="rig", crop=(0, 0, 4, 4))
    assert type(swatch) is SwatchScene and type(style) is HairstyleScene   # a head ignores the swatch's fields
    assert not hasattr(style, "framing") and style.swatch_model is None and style.hair_file is None
    assert dataclasses.replace(swatch, lights=(0.0, 1.0, 0.0)) == SwatchScene(framing="rig", lights=(0, 1, 0))
    with pytest.raises(TypeError):
        SceneSpec("swatch", sky=2.0)      # a field no kind named "swatch" has


def test_each_kind_makes_its_own_scene_dict(tmp_path) -> None:
    bsdf, curves = hair_bsdf(HairParams()), str(tmp_path / "c.txt")   # the head's meshes are written beside it
    swatch = SceneSpec("swatch", framing="rig", lights=(1.0, 0.0, 0.5)).scene_dict(curves, bsdf, 16)
    style = SceneSpec("bob", env="soft").scene_dict(curves, bsdf, 16)
    assert {"holder", "light0", "light2"} <= set(swatch) and "scalp" not in swatch
    assert {"head", "scalp", "sky"} <= set(style) and "holder" not in style
    assert swatch["hair"]["filename"] == style["hair"]["filename"] == curves


def test_a_new_kind_is_one_type_and_the_renderer_draws_it() -> None:
    """The renderer asks the scene for its strands, scene dict and update: FurnaceScene, unknown to it, renders,
    and a new camera updates the loaded scene rather than building another."""
    CALLS.clear()
    renderer, hair = Renderer(), HairParams((255, 255, 255), 0, 0, 0)
    white = renderer.render(hair, FurnaceScene(strands=150), 16, 8, 0)
    assert np.isfinite(white.linear).all() and 0.8 < white.linear.mean() < 1.2   # lossless hair under a white sky
    moved = renderer.render(hair, FurnaceScene(strands=150, camera=CameraPose(30.0, 40.0, 0.9)), 16, 8, 0)
    assert renderer.builds == 1 and not np.array_equal(white.linear, moved.linear)
    assert CALLS == [("scene_dict", "FurnaceScene"), ("update", "FurnaceScene"), ("update", "FurnaceScene")]
    dimmer = renderer.render(hair, FurnaceScene(strands=150, sky=0.5), 16, 8, 0)   # its own field: a new scene
    assert renderer.builds == 2 and dimmer.linear.mean() < 0.75 * white.linear.mean()
    with pytest.raises(SceneError, match="sky"):
        FurnaceScene(sky=-1)


def test_what_is_not_a_scene_kind_is_refused() -> None:
    with pytest.raises(SceneError, match="render.scene_kinds.Scene"):
        Renderer().render(HairParams(), {"name": "swatch"}, 16, 1)

    @dataclass(frozen=True)
    class Half(Scene):   # no scene dict, strands or view: not a kind yet
        def _settle(self) -> None:
            pass

    with pytest.raises(TypeError, match="abstract"):
        Half("half")
