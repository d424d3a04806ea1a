"""The lab's instrument: its geometries as Mitsuba scenes (a white diffuser and a black glass tile read as their
known values), colour from a reflectance spectrum, a record's reading through the instrument curves, the
import of an instrument's CSV and CxF3 exports (and bad ones refused, the library unchanged), and the comparison
of the lab's readings with hairdigi's (Bland-Altman)."""
import csv

import colour
import numpy as np
import pytest

from hairdigi.app.evaluation.readings_comparison import compare_readings, paired
from hairdigi.app.library.lab_readings import ReadingsError, import_readings, parse_columns, read_readings
from hairdigi.app.library.store import Library, SwatchRow
from hairdigi.inference.instrument_reading import InstrumentCurves, read_instrument
from hairdigi.inference.refine import SIGMA_LEVELS
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord, InstrumentReading
from hairdigi.render.instrument_geometry import (GEOMETRIES, InstrumentError, geometry, lab_of_reflectance, lab_of_tristimulus,
                                        spectral_tristimulus, tile_reflectance)
from hairdigi.render.metrics import bland_altman
from hairdigi.render.spectra import WAVELENGTHS

#: Black glass (index 1.5): Fresnel's normal reflectance ((n - 1) / (n + 1))^2 = 0.04, L* 23.7, seen only where
#: the specular component reaches the view.
BLACK_GLASS_Y = 0.04


@pytest.mark.parametrize("geom", list(GEOMETRIES))
def test_a_white_diffuser_and_black_glass_read_their_known_values_in_rgb(geom):
    white = tile_reflectance("white", geom)
    black = tile_reflectance("black glass", geom)
    trap = GEOMETRIES[geom].trap
    # the trap hides a 5° cone of the sphere: a Lambertian white loses sin²5° cos8° = 0.75% of its light
    assert white == pytest.approx([0.9925 if trap else 1.0] * 3, abs=0.004)
    expected = BLACK_GLASS_Y if GEOMETRIES[geom].diffuse and not trap else 0.0
    assert black == pytest.approx([expected] * 3, abs=0.002)


@pytest.mark.parametrize("geom", list(GEOMETRIES))
def test_the_spectral_virtual_instrument_reads_the_tiles_as_cielab(geom):
    white = lab_of_tristimulus(spectral_tristimulus(None, None, geom, tile="white", size=24, spp=32))
    black = lab_of_tristimulus(spectral_tristimulus(None, None, geom, tile="black glass", size=24, spp=32))
    assert white[0] == pytest.approx(99.7 if GEOMETRIES[geom].trap else 100.0, abs=0.3)
    assert np.abs(white[1:]).max() < 0.3
    sci = GEOMETRIES[geom].diffuse and GEOMETRIES[geom].specular_included
    assert black[0] == pytest.approx(23.7 if sci else 0.0, abs=0.5)


def test_colour_of_a_reflectance_spectrum_matches_colour_science():
    flat = np.ones(len(WAVELENGTHS))
    assert lab_of_reflectance(flat) == pytest.approx([100.0, 0.0, 0.0], abs=1e-6)
    patch = colour.SDS_COLOURCHECKERS["BabelColor Average"]["dark skin"].copy().align(
        colour.SpectralShape(360, 830, 5))
    cmfs = colour.MSDS_CMFS["CIE 1964 10 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    xyz = colour.sd_to_XYZ(patch, cmfs, d65) / 100
    white = colour.sd_to_XYZ(colour.sd_ones(colour.SpectralShape(360, 830, 5)), cmfs, d65) / 100
    expected = colour.XYZ_to_Lab(xyz, colour.XYZ_to_xy(white))
    assert lab_of_reflectance(patch.values) == pytest.approx(expected, abs=0.15)
    two = lab_of_reflectance(patch.values, observer="2")
    assert not np.allclose(two, expected, atol=0.05)        # the observer matters, and is used


def test_geometries_are_named_loosely_and_refused_with_the_choices():
    assert geometry("di:8°").name == "d/8 SCI" and geometry("de:8").name == "d/8 SCE"
    assert geometry("45a:0").name == "45/0"
    with pytest.raises(InstrumentError, match="choose one of d/8 SCI"):
        geometry("0/45 gloss")
    with pytest.raises(InstrumentError, match="between 3 and 25 mm"):
        read_instrument(HairParams(), curves=_curves(), aperture_mm=40.0, intervals={})


def _curves(scale: float = 1.0) -> InstrumentCurves:
    """Two members' curves in every geometry: a darker and a lighter structure."""
    levels = np.asarray(SIGMA_LEVELS)
    base = 0.02 + 0.56 * np.exp(-1.3 * levels)
    means = np.stack([np.stack([base * 0.9 * scale, base * 1.1 * scale]) for _ in GEOMETRIES])
    return InstrumentCurves(levels, tuple(GEOMETRIES), ("deposited", "layered"), means)


def test_a_records_reading_orders_hair_by_lightness_and_carries_its_spread_and_interval():
    curves = _curves()
    intervals = {"d/8 SCI": {"p68": 0.7, "p95": 1.4, "source": "measured"}}
    black = read_instrument(HairParams((20, 20, 20), 0.2, 0.97, 0.95), curves=curves, intervals=intervals)
    blonde = read_instrument(HairParams((245, 240, 225), 0.15, 0.04, 0.2), curves=curves, intervals=intervals)
    assert [r.geometry for r in black] == list(GEOMETRIES)
    assert black[0].lab[0] < 30 < 60 < blonde[0].lab[0]
    assert black[0].p68 == 0.7 and black[1].p68 is None     # SCE: not measured in this table
    assert black[0].spread > 0.5                            # the two members read 20% apart
    only = read_instrument(HairParams((20, 20, 20), 0.2, 0.97, 0.95), {"layered": 1.0}, curves=curves, intervals={})
    assert only[0].lab[0] > black[0].lab[0] and only[0].spread == 0.0   # the lighter member alone
    record = EstimateRecord(hair=HairParams(), instrument=black)
    back = EstimateRecord.from_json(record.to_json())
    assert back.instrument_reading("d/8 SCI").lab == pytest.approx(black[0].lab, abs=1e-3)
    assert isinstance(back.instrument[2], InstrumentReading) and back.instrument[2].geometry == "45/0"


# -- the lab's readings ----------------------------------------------------------------------------
def _library(tmp_path, ids=("T-001", "T-002", "T-003")) -> Library:
    lib = Library(str(tmp_path / "library.sqlite"))
    rows = [SwatchRow(id=f"c{i:015d}", kind="capture", capture_id=tid,
                      labs={"d/8 SCI": (30.0 + 10 * i, 8.0, 12.0), "daylight": (31.0 + 10 * i, 8.0, 12.0)})
            for i, tid in enumerate(ids)]
    lib.add(rows)
    return lib


def _write(path, text: str, encoding: str = "utf-8"):
    path.write_text(text, encoding=encoding)
    return path


def test_a_csv_export_imports_with_its_columns_found_by_name(tmp_path):
    lib = _library(tmp_path)
    f = _write(tmp_path / "spectro.csv", "Sample Name;L*;a*;b*;Mode\nT-001;30,5;8,2;11,9;SCI\nT-001;30,9;8,0;12,1;SCE\n"
                                          "T-002;40,2;7,8;12,4;SCI\n", encoding="latin-1")
    readings = import_readings(lib, f)
    assert [(r.tress, r.geometry) for r in readings] == [("T-001", "d/8 SCI"), ("T-001", "d/8 SCE"), ("T-002", "d/8 SCI")]
    assert readings[0].lab == (30.5, 8.2, 11.9)
    assert len(lib.readings("T-001")) == 2
    again = import_readings(lib, f)                     # the same file again replaces its readings
    assert len(again) == 3 and len(lib.readings()) == 3
    mapped = _write(tmp_path / "other.csv", "Tress no.,Light,Red-green,Yellow-blue\nT-003,50,1,2\n")
    with pytest.raises(ReadingsError, match="no column for id"):
        read_readings(mapped)
    out = read_readings(mapped, columns=parse_columns("id=Tress no.,L=Light,a=Red-green,b=Yellow-blue"))
    assert out[0].lab == (50.0, 1.0, 2.0) and out[0].geometry == "d/8 SCI"


def test_a_cxf3_export_imports_with_its_geometry_observer_and_illuminant(tmp_path):
    from colour_cxf import cxf3, write_cxf

    def spec(sid, sphere, observer):
        return cxf3.ColorSpecification(
            id=sid, tristimulus_spec=cxf3.TristimulusSpec(illuminant_or_custom_illuminant=cxf3.Illuminant(
                value=cxf3.EilluminantType.D65), observer=cxf3.Observer(value=observer)),
            measurement_spec=cxf3.MeasurementSpec(geometry_choice=cxf3.GeometryChoice(choice=sphere)))

    objects = [cxf3.Object(name=tid, id=str(k), object_type="Target", color_values=cxf3.ColorValues(choice=[
        cxf3.ColorCielab(l=30.0 + k, a=8.0, b=12.0, color_specification="sci"),
        cxf3.ColorCielab(l=29.6 + k, a=8.0, b=12.0, color_specification="sce")])) for k, tid in enumerate(("T-001", "T-002"))]
    doc = cxf3.CxF(resources=cxf3.Resources(
        object_collection=cxf3.ObjectCollection(object_value=objects),
        color_specification_collection=cxf3.ColorSpecificationCollection(color_specification=[
            spec("sci", cxf3.EsphereType.SPECULAR_INCLUDED, cxf3.EobserverType.VALUE_10_DEGREE),
            spec("sce", cxf3.EsphereType.SPECULAR_EXCLUDED, cxf3.EobserverType.VALUE_2_DEGREE)])))
    path = tmp_path / "tresses.cxf"
    path.write_bytes(write_cxf(doc))
    lib = _library(tmp_path)
    readings = import_readings(lib, path)
    assert [(r.tress, r.geometry, r.observer, r.lab[0]) for r in readings] == [
        ("T-001", "d/8 SCI", "10", 30.0), ("T-001", "d/8 SCE", "2", 29.6),
        ("T-002", "d/8 SCI", "10", 31.0), ("T-002", "d/8 SCE", "2", 30.6)]
    with pytest.raises(ReadingsError, match="not a CxF3 file"):
        read_readings(_write(tmp_path / "broken.cxf", "<cc:CxF><unclosed>"))


@pytest.mark.parametrize("text, problem", [
    ("Name,X,Y,Z\nT-001,20.1,21.0,18.3\n", "no column for L"),
    ("id,L*,a*,b*\nT-001,=A1*2,8,12\n", "formula"),
    ("id,L*,a*,b*\nT-001,0.21,0.05,0.02\nT-002,0.3,0.01,0.02\nT-003,0.4,0.02,0.01\n", "0-1"),
    ("id,L*,a*,b*\nT-001,210,8,12\n", "other units"),
    ("id,L*,a*,b*\nT-001,thirty,8,12\n", "not a number"),
    ("id,L*,a*,b*\nT-404,30,8,12\nT-001,30,8,12\n", "name no swatch"),
    ("id,L*,a*,b*,geometry\nT-001,30,8,12,0/45 gloss\n", "geometry '0/45 gloss'"),
    ("", "empty"),
])
def test_a_bad_file_gets_one_line_naming_the_fix_and_changes_nothing(tmp_path, text, problem):
    lib = _library(tmp_path)
    import_readings(lib, _write(tmp_path / "good.csv", "id,L*,a*,b*\nT-002,40,8,12\n"))
    before = lib.readings()
    with pytest.raises(ReadingsError, match=problem) as info:
        import_readings(lib, _write(tmp_path / "bad.csv", text))
    assert "\n" not in str(info.value)
    assert lib.readings() == before


def test_unknown_tresses_may_be_kept_for_later(tmp_path):
    lib = _library(tmp_path)
    readings = import_readings(lib, _write(tmp_path / "r.csv", "id,L*,a*,b*\nT-404,30,8,12\n"), allow_unknown=True)
    assert len(readings) == 1 and lib.readings("T-404")[0][4] == 30.0


def test_the_comparison_pairs_tresses_and_measures_agreement(tmp_path):
    lib = _library(tmp_path)
    # the instrument reads each tress three times, 0.5 L* darker on average than hairdigi's reading
    rows = ["id,L*,a*,b*"] + [f"{tid},{30 + 10 * i - 0.5 + d},{8.0 + d / 2},12.0" for i, tid in
                              enumerate(("T-001", "T-002", "T-003")) for d in (-0.3, 0.0, 0.3)]
    import_readings(lib, _write(tmp_path / "r.csv", "\n".join(rows) + "\n"))
    pairs = paired(lib)
    assert [p["tress"] for p in pairs] == ["T-001", "T-002", "T-003"]
    assert all(p["instrument_readings"] == 3 and p["dL"] == pytest.approx(0.5) for p in pairs)
    summary = compare_readings(lib, tmp_path / "out")
    ba = summary["by_geometry"]["d/8 SCI"]["bland_altman_L"]
    assert ba["bias"] == pytest.approx(0.5) and ba["sd"] == pytest.approx(0.0, abs=1e-9)
    assert (tmp_path / "out" / "readings_comparison.png").stat().st_size > 5000
    with open(tmp_path / "out" / "readings_comparison.csv") as f:
        assert len(list(csv.DictReader(f))) == 3


def test_bland_altman_limits():
    ba = bland_altman([1.0, 2.0, 3.0, 4.0], [0.0, 2.0, 2.0, 4.0])
    assert ba["bias"] == 0.5 and ba["sd"] == pytest.approx(np.std([1, 0, 1, 0], ddof=1), abs=1e-3)
    assert ba["lower"] == pytest.approx(0.5 - 1.96 * ba["sd"], abs=2e-3)


@pytest.mark.slow
def test_a_rig_capture_reads_as_the_virtual_instrument_reads_the_same_swatch(tmp_path):
    """The whole chain in the default mode on a deposited swatch in a layout no table saw: the record's d/8 SCI and
    SCE readings lie within 2.0 ΔE2000 (the goal's p95) of a spectral render of the truth in the sphere, and the
    record on disk carries them."""
    from hairdigi.app.session.rig_session import RigSession
    from hairdigi.render.domain.records import read_record
    from hairdigi.render.spectra import hair_sigma_a_spectrum
    from hairdigi.render.swatch_family import structure_strands

    hidden = HairParams((190, 80, 40), 0.5, 0.5, 0.6)
    session = RigSession.simulated_rig(tmp_path / "s", hidden=hidden, spp=16, swatch_model="deposited", strand_seed=5)
    try:
        session.calibrate()
        result = session.capture()
    finally:
        session.close()
    saved = read_record(result.image_path.with_suffix(".result.json"), EstimateRecord)
    assert [r.geometry for r in saved.instrument] == list(GEOMETRIES)
    strands = structure_strands("deposited", 8000, seed=5)
    for geom in ("d/8 SCI", "d/8 SCE"):
        truth = lab_of_tristimulus(spectral_tristimulus(strands, hair_sigma_a_spectrum(hidden), geom, spp=64, size=32,
                                                        spots=3))
        from hairdigi.render.metrics import delta_e2000_lab

        assert float(delta_e2000_lab(saved.instrument_reading(geom).lab, truth)) < 2.0, (geom, saved.instrument_reading(geom), truth)


def test_the_command_line_imports_readings_and_refuses_a_bad_file_in_one_line(tmp_path, monkeypatch, capsys):
    from hairdigi.app.cli import main

    monkeypatch.setenv("HAIRDIGI_LIBRARY", str(tmp_path / "library.sqlite"))
    monkeypatch.setenv("HAIRDIGI_SESSIONS", str(tmp_path / "no-sessions"))
    _library(tmp_path).close()
    good = _write(tmp_path / "good.csv", "Sample Name,Mode,L*,a*,b*\nT-001,SCI,30.1,8,12\nT-001,SCE,29.8,8,12\n")
    assert main(["library", "readings", str(good)]) == 0
    assert "imported 2 readings of 1 tresses" in capsys.readouterr().out
    bad = _write(tmp_path / "bad.csv", "Sample Name,X,Y,Z\nT-001,20,21,18\n")
    assert main(["library", "readings", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--columns L=HEADER" in err
    with Library(str(tmp_path / "library.sqlite")) as lib:
        assert len(lib.readings()) == 2


def test_each_structure_reads_the_colour_the_capture_showed():
    """Two structures, one 20% darker than the other at equal absorption at the rig and in the sphere: read
    through the rig's curves, both give one reading of the colour a capture showed (the transfer), where read
    at the answer's absorption they part by the 20%."""
    from hairdigi.inference.instrument_reading import answer_curve, measured_ratio, member_reflectances
    from hairdigi.inference.refine import ResponseCurve
    from hairdigi.inference.structure import FamilyCurves

    levels = np.asarray(SIGMA_LEVELS)
    base = 0.01 + 0.4 * np.exp(-1.1 * levels)
    rig = FamilyCurves(ResponseCurve(levels, base * 1.1),
                       {"deposited": ResponseCurve(levels, base * 0.9), "layered": ResponseCurve(levels, base * 1.1)})
    sphere = np.stack([np.stack([1.4 * base * 0.9, 1.4 * base * 1.1]) for _ in GEOMETRIES])
    curves = InstrumentCurves(levels, tuple(GEOMETRIES), ("deposited", "layered"), sphere)
    sigma = np.full(len(WAVELENGTHS), 0.4)
    direct = member_reflectances(sigma, "d/8 SCI", curves, ("deposited", "layered"))
    assert direct["layered"][0] / direct["deposited"][0] == pytest.approx(1.1 / 0.9, rel=1e-6)
    reference = answer_curve(rig, None, "layered")               # the answer was read on the layered swatch
    moved = member_reflectances(sigma, "d/8 SCI", curves, ("deposited", "layered"), rig, reference)
    assert moved["deposited"] == pytest.approx(moved["layered"], rel=0.005)
    # a capture 10% darker than the answer renders (a black below the floor): every reading 10% darker
    ratio = measured_ratio(0.9 * reference(np.full(3, 0.4)), np.full(3, 0.4), reference)
    assert ratio == pytest.approx(np.full(len(WAVELENGTHS), 0.9), rel=1e-6)
    darker = member_reflectances(sigma, "d/8 SCI", curves, ("deposited", "layered"), rig, reference, ratio)
    assert darker["layered"] == pytest.approx(0.9 * moved["layered"], rel=0.03)


def test_a_record_reads_through_the_structures_its_estimate_was_read_on():
    from hairdigi.inference.instrument_reading import reading_members
    from hairdigi.render.domain.estimate_parts import Region
    from hairdigi.render.domain.records import RefinementRecord

    def record(**region):
        return EstimateRecord(hair=HairParams(), refinement=RefinementRecord(ran=True, region=Region(**region)))

    assert reading_members(record(swatch_model="layered")) is None                   # assumed: any of the family
    assert reading_members(record(swatch_model="deposited")) == {"deposited": 1.0}   # the frames read it
    mapped = {"layered": 1.0, "tilted": 1.0, "loose": 0.85}
    assert reading_members(record(swatch_model="layered", members=mapped)) == mapped
    back = EstimateRecord.from_json(record(swatch_model="layered", members=mapped).to_json())
    assert back.refinement.region.members == mapped


def test_the_record_panel_and_the_library_show_the_instrument_reading(tmp_path):
    from hairdigi.app.library.model import near_lab
    from hairdigi.app.library.swatch_colour import ColourError
    from hairdigi.app.library.view import compare
    from hairdigi.app.review.text import instrument_lines

    readings = read_instrument(HairParams(), curves=_curves(), intervals={"d/8 SCI": {"p68": 1.9, "p95": 2.2}})
    lines = instrument_lines(EstimateRecord(hair=HairParams(), instrument=readings))
    assert len(lines) == 3 and lines[0].startswith("instrument d/8 SCI D65/10°, 8 mm: L* ")
    assert "within ΔE2000 1.90 in 68%" in lines[0] and "within" not in lines[2]
    lib = _library(tmp_path)
    swatches = lib.all()
    assert near_lab(lib, "T-002", "d/8 SCI") == pytest.approx((40.0, 8.0, 12.0))       # a reference tress
    with pytest.raises(ColourError, match="no d/8 SCE colour"):
        near_lab(lib, "T-002", "d/8 SCE")
    with pytest.raises(ColourError, match="neither #RRGGBB nor a swatch"):
        near_lab(lib, "T-999", "d/8 SCI")
    found = lib.find(np.array(near_lab(lib, "T-002", "d/8 SCI")), "d/8 SCI", k=3)
    assert [s.capture_id for s, _ in found][0] == "T-002" and found[1][1] > 5
    side = compare(swatches[0], swatches[1]).delta_e
    assert set(side) == {"daylight", "studio", "d/8 SCI"} and side["d/8 SCI"] > 5


def test_estimate_states_its_instrument_readings_for_the_observer_and_aperture_asked(tmp_path, capsys):
    from hairdigi.app.cli import main
    from hairdigi.render.domain.records import read_record
    from hairdigi.resources import ROOT

    image = ROOT / "samples" / "auburn-swatch.png"
    ten, two = tmp_path / "ten.json", tmp_path / "two.json"
    assert main(["estimate", str(image), "--no-refine", "--out", str(ten)]) == 0
    assert capsys.readouterr().out.count("as an instrument reads it: ") == 3
    assert main(["estimate", str(image), "--no-refine", "--observer", "2", "--aperture", "25", "--out", str(two)]) == 0
    a, b = read_record(ten, EstimateRecord).instrument[0], read_record(two, EstimateRecord).instrument[0]
    assert (a.observer, a.aperture_mm, b.observer, b.aperture_mm) == ("10", 8.0, "2", 25.0)
    assert a.lab != b.lab and abs(a.lab[0] - b.lab[0]) < 2.0      # another observer, nearly the same lightness
    with pytest.raises(SystemExit) as refused:        # argparse refuses it, naming the range
        main(["estimate", str(image), "--no-refine", "--aperture", "40", "--out", str(two)])
    assert refused.value.code == 2 and "outside [3, 25]" in capsys.readouterr().err


def test_a_missing_or_endless_export_is_one_line(tmp_path):
    with pytest.raises(ReadingsError, match="no such file; check its name"):
        read_readings(tmp_path / "nowhere.csv")
    with pytest.raises(ReadingsError, match="not an instrument's export|device|regular file"):
        read_readings("/dev/zero")
