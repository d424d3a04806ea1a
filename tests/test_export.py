"""hairdigi export: MaterialX (validated by the materialx package) and the Blender script; with Blender
(HAIRDIGI_BLENDER or blender on the PATH), the script run for real and Cycles against the Mitsuba twin."""
import json
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from hairdigi.app.cli import main
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.appearance import AppearanceEstimate
from hairdigi.render.domain.records import EstimateRecord, RefinementRecord, write_record

mx = pytest.importorskip("MaterialX")

HAIR = HairParams((200.0, 90.0, 40.0), 0.4, 0.35, 0.6)
SIGMA = (0.31, 0.62, 1.23)
#: Every input of Blender 5.0's Principled Hair BSDF a user can set ("Weight" is internal, "Random" a per-strand feed).
BLENDER_INPUTS = {"Color", "Melanin", "Melanin Redness", "Tint", "Absorption Coefficient", "Aspect Ratio", "Roughness",
                  "Radial Roughness", "Coat", "IOR", "Offset", "Random Color", "Random Roughness", "Reflection",
                  "Transmission", "Secondary Reflection"}


def _record(tmp_path, name="auburn.json", refined=True, appearance=None, hair=HAIR) -> Path:
    refinement = RefinementRecord(ran=True, sigma_a=SIGMA, residual_de2000=0.1) if refined else RefinementRecord()
    record = EstimateRecord(hair=hair, refinement=refinement, appearance=appearance)
    return write_record(tmp_path / name, record)


def _document(path: Path):
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    stdlib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), stdlib)
    doc.importLibrary(stdlib)
    return doc


def _input(node, name):
    return node.getInput(name)


def test_materialx_validates_and_carries_the_estimate(tmp_path, capsys):
    record = _record(tmp_path)
    out = tmp_path / "auburn.mtlx"
    assert main(["export", str(record), "--format", "materialx", "--out", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    doc = _document(out)
    ok, message = doc.validate()
    assert ok, message
    assert doc.getColorSpace() == "lin_rec709"
    (bsdf,) = [n for n in doc.getNodes() if n.getCategory() == "chiang_hair_bsdf"]
    assert np.allclose(list(_input(bsdf, "absorption_coefficient").getValue()), SIGMA)
    assert _input(bsdf, "cuticle_angle").getValue() == pytest.approx(0.5 + 2.0 / 180.0)
    assert _input(bsdf, "ior").getValue() == pytest.approx(1.55)
    assert "linear Rec.709" in bsdf.getAttribute("doc")
    (rough,) = [n for n in doc.getNodes() if n.getCategory() == "chiang_hair_roughness"]
    assert _input(rough, "longitudinal").getValue() == pytest.approx(0.3)
    assert _input(rough, "azimuthal").getValue() == pytest.approx(0.3)
    for lobe in ("roughness_R", "roughness_TT", "roughness_TRT"):
        assert _input(bsdf, lobe).getNodeName() == rough.getName() and _input(bsdf, lobe).getOutputString() == lobe
    (material,) = doc.getMaterialNodes()
    assert material.getName() == "auburn"


def test_materialx_validation_can_fail(tmp_path):
    """The check is real: a document with a wrong input type does not validate."""
    out = tmp_path / "bad.mtlx"
    main(["export", str(_record(tmp_path)), "--format", "materialx", "--out", str(out)])
    out.write_text(out.read_text().replace('name="ior" type="float"', 'name="ior" type="color3"'))
    ok, message = _document(out).validate()
    assert not ok and "ior" in message


def test_unrefined_record_uses_table1_and_shine_is_exported(tmp_path):
    out = tmp_path / "plain.mtlx"
    main(["export", str(_record(tmp_path, refined=False, appearance=AppearanceEstimate.from_json({"longitudinal_roughness": 0.42}))),
          "--format", "materialx", "--out", str(out)])
    doc = _document(out)
    assert doc.validate()[0]
    (bsdf,) = [n for n in doc.getNodes() if n.getCategory() == "chiang_hair_bsdf"]
    assert np.allclose(list(_input(bsdf, "absorption_coefficient").getValue()), hair_sigma_a(HAIR))
    (rough,) = [n for n in doc.getNodes() if n.getCategory() == "chiang_hair_roughness"]
    assert _input(rough, "longitudinal").getValue() == pytest.approx(0.42)
    assert "shine: measured" in bsdf.getAttribute("doc")


def test_blocked_record_is_one_line_and_exit_2(tmp_path, capsys):
    path = write_record(tmp_path / "blocked.json", EstimateRecord(hair=None, capture="x.png", blocked=("too dark",)))
    assert main(["export", str(path), "--format", "materialx", "--out", str(tmp_path / "x.mtlx")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no estimate" in err and "too dark" in err
    assert not (tmp_path / "x.mtlx").exists()


def test_blender_script_sets_every_input(tmp_path):
    out = tmp_path / "auburn.py"
    assert main(["export", str(_record(tmp_path)), "--format", "blender", "--out", str(out)]) == 0
    text = out.read_text()
    compile(text, str(out), "exec")
    namespace = {"__name__": "hairdigi_test"}
    exec(text, namespace)   # defines functions only: bpy is imported inside them
    look = namespace["LOOK"]
    assert look["model"] == "CHIANG" and look["parametrization"] == "ABSORPTION"
    assert set(look["inputs"]) == BLENDER_INPUTS
    assert look["inputs"]["Absorption Coefficient"] == pytest.approx(list(SIGMA))
    assert look["inputs"]["Offset"] == pytest.approx(math.radians(-2.0))   # Cycles tilts the other way
    assert look["inputs"]["Roughness"] == pytest.approx(0.3) and look["inputs"]["Coat"] == 0.0
    assert namespace["script_args"](["blender", "-b", "-P", "x.py"]) == []
    assert namespace["script_args"](["python", "x.py", "--", "--blend", "a.blend"]) == ["--blend", "a.blend"]


def _blender() -> str | None:
    return os.environ.get("HAIRDIGI_BLENDER") or shutil.which("blender")


needs_blender = pytest.mark.skipif(_blender() is None, reason="no Blender: set HAIRDIGI_BLENDER to a Python with "
                                   "bpy 5.0.1 (bpy pins numpy<2, so it cannot share hairdigi's venv) or install blender")


@needs_blender
def test_blend_file_holds_the_material_and_groom(tmp_path):
    import subprocess

    blend = tmp_path / "swatch.blend"
    script = tmp_path / "auburn.py"
    assert main(["export", str(_record(tmp_path)), "--format", "blender", "--out", str(script),
                 "--blend", str(blend)]) == 0
    assert blend.stat().st_size > 10_000
    probe = tmp_path / "probe.py"
    probe.write_text(f"""import bpy, json, sys
bpy.ops.wm.open_mainfile(filepath={str(blend)!r})
mat = bpy.data.materials["auburn"]
node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfHairPrincipled")
groom = bpy.data.objects["swatch"]
print(json.dumps({{"model": node.model, "param": node.parametrization,
    "sigma": list(node.inputs["Absorption Coefficient"].default_value),
    "offset": next(s for s in node.inputs if s.name == "Offset").default_value,
    "curves": len(groom.data.curves), "material": groom.data.materials[0].name,
    "engine": bpy.context.scene.render.engine, "camera": bpy.context.scene.camera.name}}))
""")
    command = [_blender()] if "blender" not in Path(_blender()).name else [_blender(), "-b", "--python"]
    proc = subprocess.run([*command, str(probe)], capture_output=True, text=True, timeout=600, check=True)
    got = json.loads(next(line for line in proc.stdout.splitlines() if line.startswith("{")))
    assert got["model"] == "CHIANG" and got["param"] == "ABSORPTION" and got["material"] == "auburn"
    assert np.allclose(got["sigma"], SIGMA, rtol=1e-6) and got["offset"] == pytest.approx(math.radians(-2))
    assert got["curves"] > 100 and got["engine"] == "CYCLES" and got["camera"] == "camera"


#: Six colours from platinum to black (Table 1, eumelanin ratio 0.7, no dye).
LADDER = [HairParams(melanin_concentration=m, melanin_ratio=0.7) for m in (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)]


@needs_blender
@pytest.mark.slow
def test_cycles_renders_the_export_like_the_twin(tmp_path, test_output):
    """The exported script rendered in Cycles on the rig's swatch at the rig's pose against hairdigi's Mitsuba
    twin, same strands: mean-colour ΔE2000 <= 1.0 for six colours, platinum to black."""
    from hairdigi.render.blender_run import cycles_check
    from hairdigi.render.interchange import look_from_record

    rows = []
    for i, hair in enumerate(LADDER):
        look = look_from_record(EstimateRecord(hair=hair), f"ladder{i}")
        check = cycles_check(look, size=48, spp=64, mitsuba_spp=256)
        rows.append({"melanin": hair.melanin_concentration, "sigma_a": list(look.sigma_a),
                     "cycles": list(check.cycles_linear), "mitsuba": list(check.mitsuba_linear),
                     "delta_e2000": check.delta_e2000, "cycles_s": check.cycles_seconds})
    (test_output / "cycles_check.json").write_text(json.dumps(rows, indent=2))
    worst = max(r["delta_e2000"] for r in rows)
    assert worst <= 1.0, rows


def test_blend_without_blender_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HAIRDIGI_BLENDER", str(tmp_path / "no-such-blender"))
    assert main(["export", str(_record(tmp_path)), "--format", "blender", "--out", str(tmp_path / "a.py"),
                 "--blend", str(tmp_path / "a.blend")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "HAIRDIGI_BLENDER" in err
    assert not (tmp_path / "a.blend").exists()
    assert main(["export", str(_record(tmp_path)), "--format", "materialx", "--out", str(tmp_path / "a.mtlx"),
                 "--blend", str(tmp_path / "a.blend")]) == 2
    assert "--blend goes with --format blender" in capsys.readouterr().err
