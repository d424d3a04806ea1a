"""Typed records: every record round-trips through its JSON, and the files today's main
(hairdigi 0.1.0, before these types) wrote are read and upgraded: ``tests/data/legacy-session`` is a
simulated-rig session written by commit cb75f99 (a live capture and a RAW still's records)."""
import json
import shutil
from pathlib import Path

import pytest

from hairdigi.render.domain.estimate_parts import (EncoderReading, ParameterInterval, Provenance, Region,
                                                   SpectralInterval, StructureInterval, Uncertainty)
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import CameraPose, RigRegion
from hairdigi.render.domain.records import (SCHEMA_VERSION, CalibrationProfile, CaptureRecord, EstimateRecord,
                                            EstimateWarning, RecordError, RefinementRecord, WarningKind,
                                            capture_profile, read_record, write_record)

LEGACY = Path(__file__).parent / "data" / "legacy-session"
LIVE, STILL = "20261124-035325-574", "20261124-035444-053"


def _legacy(name: str) -> dict:
    return json.loads((LEGACY / "captures" / name).read_text())


def test_every_record_round_trips_through_its_json():
    profile = CalibrationProfile(id="abc", method="Finlayson 2015", matrix=((1.0, 0.1, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 0.9)),
                                 time=1.7e9, delta_e2000={"before": {"mean": 5.0}, "after": {"mean": 0.4}},
                                 settings={"camera": "sim-rig", "lights": [[1, 255], [1, 255], [1, 255]]},
                                 chart_box=((1.0, 2.0), (3.0, 2.0), (3.0, 4.0), (1.0, 4.0)), detection_cost=0.5)
    capture = CaptureRecord(id="c1", image="c1.png", image_sha256="00", captured="2026-11-24T03:00:00+0000",
                            lights=[[1, 255], [0, 0], [1, 128]], frame_meta={"camera": "sim-rig"}, calibration=profile,
                            swatch_roi=(1, 2, 30, 40), light_images=("c1-l0.png",))
    estimate = EstimateRecord(
        hair=HairParams((190.0, 80.0, 40.0), 0.5, 0.5, 0.6),
        warnings=(EstimateWarning(WarningKind.CALIBRATION, "calibration: stale"),
                  EstimateWarning(WarningKind.OUT_OF_DOMAIN, "out of domain: noise")),
        refinement=RefinementRecord(ran=True, sigma_a=(0.3, 0.6, 1.2), residual_de2000=0.1, iterations=2,
                                    residual_history=(0.3, 0.1), nonfinite=0,
                                    region=Region(rig=RigRegion((320, 240), (1, 2, 30, 40)), swatch_model="layered")),
        uncertainty=Uncertainty(coverage=0.68, method="m", parameters={"dye_r": ParameterInterval(120.0, 80.0, 160.0, 40.0)},
                                mean_colour_de2000_p68=0.5, mean_colour_de2000_p95=0.9, mean_colour_source="chain",
                                structure=StructureInterval("assumed", "layered", 2.0, 2.9, "s"),
                                spectral=SpectralInterval("nikon-5100", "camera", "every light", 1.2, 5.3, "t")),
        encoder=EncoderReading(HairParams(), ("dye_r",), {"dye_r": 0.01}),
        provenance=Provenance(hairdigi_version="0.3", time="t", model={"sha256": "x"}, roi=(1, 2, 30, 40),
                              camera=CameraPose(10.0), view=RigRegion((320, 240), (1, 2, 30, 40)),
                              calibration={"id": "abc"}, domain={"std": 1.0}),
        capture="c1.png", blocked=(), swatch_roi=(1, 2, 30, 40))
    for record in (profile, capture, estimate, RefinementRecord(), EstimateRecord(hair=None, capture="c.png",
                                                                                   blocked=("no chart",))):
        data = json.loads(json.dumps(record.to_json()))
        assert type(record).from_json(data) == record
        if hasattr(record, "schema_version"):
            assert data["schema_version"] == SCHEMA_VERSION
    assert not estimate.reliable and EstimateRecord(hair=HairParams()).reliable


def test_files_of_the_previous_layout_are_read_and_upgraded(tmp_path):
    profile = read_record(LEGACY / "calibration.json", CalibrationProfile)
    assert profile.method and len(profile.matrix) == 3 and profile.after_mean < 2.0
    live = read_record(LEGACY / "captures" / f"{LIVE}.json", CaptureRecord)
    assert live.image == f"{LIVE}.png" and live.calibration == profile and live.swatch_roi
    result = read_record(LEGACY / "captures" / f"{LIVE}.result.json", EstimateRecord)
    assert result.hair is not None and result.refinement.ran and len(result.refinement.sigma_a) == 3
    assert result.capture == f"{LIVE}.png" and result.blocked == ()
    # a still kept its profile in its result record; the capture record now holds it
    still_result = _legacy(f"{STILL}.result.json")
    legacy_profile = capture_profile(_legacy(f"{STILL}.json"), still_result)
    still = read_record(LEGACY / "captures" / f"{STILL}.json", CaptureRecord, legacy_profile=legacy_profile)
    assert still.calibration is not None and still.calibration.id == still_result["calibration_profile"]["id"]
    # upgraded on write: today's layout, read back the same
    for record, cls in ((profile, CalibrationProfile), (still, CaptureRecord), (result, EstimateRecord)):
        path = write_record(tmp_path / f"{cls.KIND}.json", record)
        assert json.loads(path.read_text())["schema_version"] == SCHEMA_VERSION
        assert read_record(path, cls) == record


def test_an_estimates_parts_are_typed_and_write_the_json_they_were_read_from():
    """The legacy records' intervals, encoder reading, provenance and refinement read as types, and
    write back exactly the dicts they were read from."""
    for name in (f"{LIVE}.result.json", f"{STILL}.result.json"):
        data = _legacy(name)
        record = EstimateRecord.from_json(data)
        assert record.uncertainty.parameters["dye_b"].determined is False
        assert record.uncertainty.mean_colour_de2000_p68 == data["uncertainty"]["mean_colour_de2000_p68"]
        assert record.encoder.hair == HairParams.from_dict(data["encoder"]["hair"])
        assert record.provenance.camera.polar_deg == data["provenance"]["camera"]["polar_deg"]
        assert record.provenance.calibration_id == data["provenance"]["calibration"]["id"]
        out = record.to_json()
        for key in ("uncertainty", "encoder", "provenance"):
            assert out[key] == data[key], key


def test_the_dicts_that_were_written_before_the_types_read_and_write_alike():
    """What an estimate without a table, a dye prediction and a crop's refinement wrote as plain dicts."""
    untabled = {"note": "no interval table shipped", "values": HairParams().to_dict()}
    prediction = {"method": "Monte Carlo", "coverage": 0.68, "sigma_a_low": [0.1, 0.2, 0.3],
                  "sigma_a_high": [0.2, 0.3, 0.4], "mean_colour_de2000_p68": 0.8}
    for data in (untabled, prediction, {}):
        assert Uncertainty.from_json(data).to_json() == data
    crop = {"crop_pose": {"polar_deg": 10.0, "azimuth_deg": 0.0, "distance": 4.0}, "swatch_model": "layered",
            "structure": "mapped to the family's mean: a, b"}
    rig = {**RigRegion((320, 240), (1, 2, 30, 40)).to_dict(), "swatch_model": "ring"}
    mapped = {**crop, "members": {"a": 1.0, "b": 1.0}, "spreads": {"a": 0.35, "b": 0.0}}
    for data in (crop, rig, {"source": "dye prediction"}, mapped):
        assert Region.from_json(json.loads(json.dumps(data))).to_json() == data
    assert Region.from_json(mapped).spread == 0.35 and Region.from_json(crop).spread is None
    with pytest.raises(RecordError, match="'spreads' must map member names to ΔE2000 values >= 0"):
        Region.from_json({**mapped, "spreads": {"a": -1.0}})
    dyed = {"hairdigi_version": "0.3", "time": "t", "prediction": {"dye": "copper"}, "calibration": None,
            "camera": None}
    later = {"hairdigi_version": "0.3", "time": "t", "written_by_a_later_hairdigi": 1}
    for data in (dyed, later):
        assert Provenance.from_json(data).to_json() == data
    assert Provenance.from_json(dyed).prediction == {"dye": "copper"}
    assert EstimateRecord.from_json({"hair": HairParams().to_dict(), "encoder": {}}).encoder is None


@pytest.mark.parametrize("part, data, field", [
    ("uncertainty", {"mean_colour_de2000_p68": "wide"}, "mean_colour_de2000_p68"),
    ("uncertainty", {"parameters": {"dye_r": {"value": 1, "low": 3, "high": 2, "half_width": 1}}}, "inverted"),
    ("uncertainty", {"spectral": {"camera": "nikon-5100", "answer": "camera"}}, "holds_for"),
    ("encoder", {"at_range_edge": []}, "'hair' is missing"),
    ("provenance", {"roi": [1, 2, "x", 4]}, "'roi'"),
    ("provenance", {"camera": {"polar_deg": 95.0, "azimuth_deg": 0.0, "distance": 4.0}}, "camera pose"),
    ("refinement", {"ran": True, "region": {"roi": [300, 2, 30, 40], "frame_size": [320, 240], "pose": [0, 0, 4],
                                            "target": [0, 0, 0], "half_width": 1.0}}, "region"),
])
def test_a_bad_part_of_an_estimate_is_refused_in_one_line_naming_it(part, data, field):
    with pytest.raises(RecordError, match=field) as exc:
        EstimateRecord.from_json({"hair": HairParams().to_dict(), part: data})
    assert "\n" not in str(exc.value) and part in str(exc.value)


def test_a_legacy_session_opens_and_reviews_with_its_own_calibration(tmp_path):
    """A session folder written by the previous layout opens, lists its captures, and loads the live
    capture with the profile it was taken with."""
    from hairdigi.app.session.rig_session import RigSession, load_results
    from hairdigi.hardware.cameras import FileCamera

    folder = tmp_path / "s"
    shutil.copytree(LEGACY, folder)
    (folder / "captures" / f"{STILL}.json").unlink()    # the still's DNG is not kept in the repository
    session = RigSession(FileCamera(folder / "captures" / f"{LIVE}.png"), None, folder)
    try:
        assert session.profile is not None and session.notices == []
        entries = dict(load_results(folder))
        assert isinstance(entries[LIVE], EstimateRecord)
        loaded = session.load_capture(LIVE)
        assert loaded.profile.id == session.profile.id and loaded.record.hair == entries[LIVE].hair
        assert loaded.problems == []
    finally:
        session.close()


@pytest.mark.parametrize("text, field", [
    ("[1, 2]", "JSON object"),
    ('{"hair": {"dye_rgb": [1, 2]}}', "hair"),
    ('{"hair": null, "refinement": {"ran": true, "sigma_a": [1, "x", 3]}}', "sigma_a"),
    ('{"hair": null, "warnings": [{"kind": "nonsense", "message": "m"}]}', "kind"),
    ('{"schema_version": 99}', "newer"),
])
def test_a_bad_record_names_its_problem(tmp_path, text, field):
    path = tmp_path / "r.json"
    path.write_text(text)
    with pytest.raises(RecordError, match=field) as exc:
        read_record(path, EstimateRecord)
    assert str(path) in str(exc.value)


def test_one_bad_file_in_a_session_hides_nothing_else(tmp_path):
    """A result holding ``[1,2]``, a non-UTF-8 one, and a corrupt calibration: the session opens (the
    calibration set aside and said so), the good capture lists, the bad ones are named."""
    from hairdigi.app.session.rig_session import RigSession, load_results
    from hairdigi.hardware.cameras import FileCamera

    folder = tmp_path / "s"
    shutil.copytree(LEGACY, folder)
    (folder / "captures" / f"{STILL}.json").unlink()
    (folder / "captures" / f"{STILL}.result.json").write_text("[1,2]")
    (folder / "captures" / "20261124-000000-000.result.json").write_bytes(b"\xff\xfe{")
    (folder / "calibration.json").write_text('{"method": "Finlayson 2015", "matrix": "no"}')
    before = {p.name: p.read_bytes() for p in (folder / "captures").iterdir()}
    session = RigSession(FileCamera(folder / "captures" / f"{LIVE}.png"), None, folder)
    try:
        assert session.profile is None and "set aside" in session.notices[0]
        assert len(list(folder.glob("calibration.unreadable-*.json"))) == 1
        entries = dict(load_results(folder))
        assert isinstance(entries[LIVE], EstimateRecord)
        assert "JSON object" in entries[STILL] and "UTF-8" in entries["20261124-000000-000"]
    finally:
        session.close()
    assert {p.name: p.read_bytes() for p in (folder / "captures").iterdir()} == before   # nothing changed


def test_a_capture_image_that_is_a_fifo_is_refused_not_waited_on(tmp_path):
    """An image path that names a FIFO (or a device) gives one clear error at once."""
    import os
    import threading

    from hairdigi.app.session.rig_session import RigSession
    from hairdigi.hardware.cameras import FileCamera

    folder = tmp_path / "s"
    shutil.copytree(LEGACY, folder)
    (folder / "captures" / f"{STILL}.json").unlink()
    frame = folder / "frame.png"
    shutil.copy(folder / "captures" / f"{LIVE}.png", frame)
    (folder / "captures" / f"{LIVE}.png").unlink()
    os.mkfifo(folder / "captures" / f"{LIVE}.png")
    session = RigSession(FileCamera(frame), None, folder)
    outcome = []
    try:
        worker = threading.Thread(target=lambda: outcome.append(_raises(session.load_capture, LIVE)), daemon=True)
        worker.start()
        worker.join(10)
        assert outcome and "not a regular file" in outcome[0], outcome
    finally:
        session.close()


def _raises(call, *args) -> str:
    try:
        call(*args)
    except FileNotFoundError as exc:
        return str(exc)
    return "returned"


def test_a_table_with_a_failed_row_is_written_whole(tmp_path):
    """An evaluation's rows differ in shape (a failed case holds its error, not the figures): the CSV's
    header is every key, in the order first met, and a row without one leaves it empty."""
    import csv

    from hairdigi.render.domain.files import write_csv_atomic

    rows = [{"hidden": "copper", "fit": 0.4}, {"hidden": "random 0", "error": "ImageError: too small"}]
    path = write_csv_atomic(tmp_path / "t.csv", rows)
    with open(path, newline="", encoding="utf-8") as f:
        read = list(csv.DictReader(f))
    assert list(read[0]) == ["hidden", "fit", "error"]
    assert read[0]["error"] == "" and read[1]["fit"] == "" and read[1]["error"] == "ImageError: too small"


def test_a_session_folder_names_every_file_of_its_layout_and_reads_a_capture_back(tmp_path):
    """One place knows the layout: a capture's two records, its image, the calibration and the dyes; a
    result record names its capture record; a written session's captures folder is known as one."""
    from hairdigi.render.domain.records import read_session_capture
    from hairdigi.render.domain.session_folder import SessionFolder, capture_id_of, capture_record_beside

    shutil.copytree(LEGACY, tmp_path / "s")
    session = SessionFolder(tmp_path / "s")
    assert session.result_record(LIVE) == tmp_path / "s" / "captures" / f"{LIVE}.result.json"
    assert session.capture_record(LIVE).name == f"{LIVE}.json" and session.calibration.name == "calibration.json"
    assert [capture_id_of(p) for p in session.result_records()] == [LIVE, STILL]
    assert [capture_id_of(p) for p in session.capture_records()] == [LIVE, STILL]
    assert capture_record_beside(session.result_record(STILL)) == session.capture_record(STILL)
    assert SessionFolder.of_captures(session.captures) == session and SessionFolder.of_captures(tmp_path) is None
    still = read_session_capture(session, STILL)     # a first-layout still: its profile in its result record
    assert still.problems == () and still.capture.calibration == still.profile is not None
    assert still.result.capture == f"{STILL}.dng" and still.capture.image == f"{STILL}.dng"
    session.result_record(LIVE).write_text("[1, 2]")
    live = read_session_capture(session, LIVE)
    assert live.result is None and live.capture is not None and "JSON object" in live.problems[0]
