"""Names that carry meaning (scene kinds, environments, framings, swatch models, structure modes, capture
sources) are enums inside and their text at the edges."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from hairdigi.render.domain.bounds import (STRUCTURE_MODES, BoundsError, Environment, SceneKind, StructureMode,
                                           SwatchModel, check_camera, defaults_for)
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import CaptureRecord, CaptureSource
from hairdigi.render.domain.rig_geometry import CameraPose, Framing
from hairdigi.render.renderer import SceneError, SceneSpec, strands_for
from hairdigi.render.strands import hairstyle_strands, swatch_strands
from hairdigi.render.swatch_family import structure_strands


def test_an_enum_is_its_text_in_json_messages_and_lookups() -> None:
    assert json.dumps({"framing": Framing.RIG, "env": Environment.KEY_SKY}) == '{"framing": "rig", "env": "key-sky"}'
    assert f"{SwatchModel.DEPOSITED_COARSE}" == str(SwatchModel.DEPOSITED_COARSE) == "deposited-coarse"
    assert {Framing.CROP: 1}[Framing("crop")] == 1 and Framing("rig") is Framing.RIG
    assert Environment.names() == ("studio", "soft", "key-sky")
    # the command line's choices stay the text they were
    assert STRUCTURE_MODES == ("assumed", "family", "read") and StructureMode("read") is StructureMode.READ


def test_a_capture_records_its_source_as_a_type_and_writes_its_text(tmp_path) -> None:
    capture = CaptureRecord("c1", "c1.png", "0" * 64, "2026-01-01T00:00:00+0000", source="raw still")
    assert capture.source is CaptureSource.RAW_STILL and json.loads(json.dumps(capture.to_json()))["source"] == "raw still"
    assert CaptureRecord.from_json(capture.to_json()) == capture
    assert CaptureRecord("c2", "c2.png", "0" * 64, "").source is CaptureSource.LIVE
    with pytest.raises(RecordError, match="'source' is 'scanner', not one of live, raw still"):
        CaptureRecord.from_json({**capture.to_json(), "source": "scanner"})


def test_a_scene_name_is_parsed_once_into_its_kind() -> None:
    assert SceneKind.of("swatch") is SceneKind.SWATCH and SceneKind.of("afro") is SceneKind.HAIRSTYLE
    assert SceneKind.of("hairfile") is SceneKind.HAIR_FILE and SceneKind.HAIR_FILE.on_head
    assert SceneKind.of("models/Straight.HAIR") is SceneKind.HAIR_FILE and not SceneKind.SWATCH.on_head
    swatch = SceneSpec("swatch", env="key-sky", framing="rig", swatch_model="today")
    assert swatch.kind is SceneKind.SWATCH and swatch.name == "swatch"
    assert swatch.env is Environment.KEY_SKY and swatch.framing is Framing.RIG and swatch.swatch_model is SwatchModel.TODAY
    style = SceneSpec("wavy", env="soft")
    assert style.kind is SceneKind.HAIRSTYLE and style.env is Environment.SOFT and style.swatch_model is None
    # the kind is the scene's type: replace keeps it, and another kind is built by its name
    assert replace(swatch, framing="crop").kind is SceneKind.SWATCH
    assert SceneSpec("curly", env="studio").kind is SceneKind.HAIRSTYLE
    with pytest.raises(SceneError, match="SceneSpec\\('curly'"):
        replace(swatch, name="curly", env="studio", swatch_model=None)
    # the kind is derived: equal specs and their hashes do not depend on how it was reached
    assert SceneSpec("swatch", framing=Framing.RIG) == SceneSpec("swatch", framing="rig")
    assert hash(SceneSpec("swatch", env=Environment.STUDIO)) == hash(SceneSpec("swatch", env="studio"))


def test_the_kind_picks_defaults_camera_and_strands() -> None:
    assert SceneSpec("swatch").n_strands == defaults_for("swatch").strands == 8000
    assert SceneSpec("bob").n_strands == defaults_for(SceneKind.HAIRSTYLE).strands == 6000
    assert SceneSpec("bob").pose != SceneSpec("swatch").pose
    with pytest.raises(BoundsError, match="between 2.5"):
        check_camera(CameraPose(0.0, 0.0, 1.0), SceneKind.HAIRSTYLE)
    check_camera(CameraPose(0.0, 0.0, 1.0), SceneKind.SWATCH)
    # each swatch model builds its own strands; a hairstyle builds the style's
    assert np.array_equal(strands_for(SceneSpec("swatch", strands=50, swatch_model="today")).points,
                          swatch_strands(50, seed=0).points)
    assert np.array_equal(strands_for(SceneSpec("swatch", strands=50, swatch_model="tilted")).points,
                          structure_strands("tilted", 50).points)
    assert np.array_equal(strands_for(SceneSpec("bob", strands=50)).points, hairstyle_strands("bob", 50).points)


@pytest.mark.parametrize("kwargs, match", [
    ({"env": "key-sky", "name": "wavy"}, "unknown environment 'key-sky'"),
    ({"env": "soft"}, "unknown swatch environment 'soft'"),
    ({"framing": "wide"}, "unknown framing 'wide'; choose one of crop, rig"),
    ({"swatch_model": "dense"}, "swatch_model 'dense'"),
])
def test_a_wrong_name_is_refused_in_its_own_words(kwargs, match) -> None:
    with pytest.raises(SceneError, match=match):
        SceneSpec(**kwargs)
