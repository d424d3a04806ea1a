"""The rig profile: declared once in the session, read by ``rig`` (live and ``--still``) and by
``estimate`` with the session's calibration; a flag overrides it for one command and says so."""
import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from hairdigi.render.domain.bounds import StructureMode
from hairdigi.app.cli import main
from hairdigi.app.cli import rig as rig_cli
from hairdigi.app.session.profile import (PROFILE_NAME, ProfileError, RigProfile, merged, read_profile,
                                          write_profile)
from hostile import one_line, snapshot

LAB = RigProfile("nikon-5100", "LED-B4", "family")


@pytest.fixture
def ws(tmp_path, monkeypatch) -> Path:
    from hairdigi.hardware.sim_still import write_raw_still

    monkeypatch.chdir(tmp_path)
    write_raw_still(tmp_path / "grey.dng", np.full((128, 128, 3), 0.3))
    return tmp_path


@pytest.fixture
def stills(monkeypatch) -> list[dict]:
    """``rig --still``'s reading, recorded instead of run: the structure and spectra it is given."""
    calls: list[dict] = []

    def report_still(session, still, say=print, structure="assumed", led=None, sensor=None, instrument=None):
        calls.append({"structure": structure, "led": led, "sensor": sensor, **({"instrument": instrument}
                                                                               if instrument != DEFAULT_READING else {})})
        return 0

    monkeypatch.setattr(rig_cli, "report_still", report_still)
    return calls


@pytest.fixture
def live(monkeypatch) -> list[argparse.Namespace]:
    """The live rig, opened and run as a stub: the arguments it is opened with."""
    opened: list[argparse.Namespace] = []

    class Session:
        def close(self):
            pass

    def open_session(args):
        opened.append(argparse.Namespace(**vars(args)))
        return Session()

    monkeypatch.setattr(rig_cli, "open_session", open_session)
    monkeypatch.setattr(rig_cli, "run_chain", lambda session: {})
    return opened


# --- the file --------------------------------------------------------------------------------------------
def test_the_profile_round_trips_with_a_csv_stored_absolute(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    profile = RigProfile("camera.csv", "leds.csv", "family")
    write_profile(tmp_path / "s", profile)
    assert read_profile(tmp_path / "s") == profile
    data = json.loads((tmp_path / "s" / PROFILE_NAME).read_text())
    assert data == {"version": 1, "sensitivities": str(tmp_path / "camera.csv"), "led": str(tmp_path / "leds.csv"),
                    "structure": "family"}
    assert read_profile(tmp_path / "none") is None
    assert not list((tmp_path / "s").glob(".*")), "the atomic write left its temporary file"


@pytest.mark.parametrize("text, needle", [
    ("{not json", "not valid JSON"), ("[1, 2]", "JSON object"), ('{"version": 7}', "version 7"),
    ('{"version": 1, "led": "LED-B4"}', "together"), ('{"version": 1, "structure": "guess"}', "structure 'guess'"),
    ('{"version": 1, "led": "moonlight", "sensitivities": "cie"}', "led 'moonlight'"),
    ('{"version": 1, "holder": "black"}', "unknown field(s) holder"),
])
def test_a_damaged_profile_is_one_clear_line(ws, capsys, stills, text, needle):
    (ws / "s").mkdir()
    (ws / "s" / PROFILE_NAME).write_text(text)
    with pytest.raises(ProfileError, match="rig-profile.json"):
        read_profile(ws / "s")
    before = snapshot(ws)
    one_line(main(["rig", "--still", "grey.dng", "--session", "s"]), capsys, PROFILE_NAME, needle, "remove it")
    assert snapshot(ws) == before and not stills


def test_merged_overrides_for_one_command_and_says_so():
    profile, notices = merged(RigProfile("cie", "d65"), {"led": "tungsten.csv", "sensitivities": None,
                                                         "structure": None})
    assert profile.led.endswith("tungsten.csv") and profile.sensitivities == "cie"
    assert notices == ["rig profile: --led tungsten.csv overrides the session's LEDs (d65) for this command"]
    assert merged(None, {"led": "d65"})[1] == [] and merged(LAB, {"led": "LED-B4"})[1] == []


# --- rig, live -------------------------------------------------------------------------------------------
def test_the_live_rig_declares_the_profile_once_and_reads_it_later(ws, capsys, live):
    assert main(["rig", "--sim", "--spectral", "--session", "s", "--structure", "family"]) == 0
    assert read_profile(ws / "s") == RigProfile("nikon-5100", "LED-B4", "family")   # the simulated spectra filled in
    assert main(["rig", "--sim", "--session", "s"]) == 0
    again = live[-1]
    assert (again.spectral, again.led, again.sensor, again.structure) == (True, "LED-B4", "nikon-5100", "family")
    assert "the simulated rig is spectral" in capsys.readouterr().err


def test_a_flag_on_the_live_rig_overrides_for_one_command_and_declare_writes_it(ws, capsys, live):
    write_profile(ws / "s", LAB)
    assert main(["rig", "--sim", "--session", "s", "--structure", "assumed"]) == 0
    assert live[-1].structure == "assumed" and read_profile(ws / "s") == LAB
    err = capsys.readouterr().err
    assert "rig profile: --structure assumed overrides the session's structure mode (family)" in err
    assert main(["rig", "--sim", "--session", "s", "--structure", "assumed", "--declare"]) == 0
    assert read_profile(ws / "s").structure is StructureMode.ASSUMED


def test_a_real_rig_session_without_flags_writes_an_undeclared_profile(ws, live):
    assert main(["rig", "--session", "s"]) == 0
    assert read_profile(ws / "s") == RigProfile(None, None, "family")         # the default mode, declared
    assert live[-1].led is None and live[-1].sensor is None


# --- rig --still -----------------------------------------------------------------------------------------
#: The instrument readings' options a still is read with unless told (D65 is the only light: 10°, 8 mm).
DEFAULT_READING = {"observer": "10", "aperture_mm": 8.0}


def test_a_still_states_its_instrument_readings_as_asked(ws, stills):
    assert main(["rig", "--still", "grey.dng", "--session", "s", "--observer", "2", "--aperture", "20"]) == 0
    assert stills[-1]["instrument"] == {"observer": "2", "aperture_mm": 20.0}


def test_a_still_is_read_with_the_sessions_declared_camera_leds_and_structure(ws, capsys, stills):
    write_profile(ws / "s", LAB)
    assert main(["rig", "--still", "grey.dng", "--session", "s"]) == 0
    assert stills == [{"structure": "family", "led": "LED-B4", "sensor": "nikon-5100"}]
    assert capsys.readouterr().err == ""


def test_a_flag_on_a_still_overrides_the_profile_and_says_so(ws, capsys, stills):
    write_profile(ws / "s", LAB)
    assert main(["rig", "--still", "grey.dng", "--session", "s", "--led", "D65", "--sensor", "cie"]) == 0
    assert stills == [{"structure": "family", "led": "D65", "sensor": "cie"}]
    err = capsys.readouterr().err
    assert "rig profile: --led D65 overrides the session's LEDs (LED-B4) for this command" in err
    assert "rig profile: --sensor cie overrides the session's camera sensitivities (nikon-5100)" in err
    assert read_profile(ws / "s") == LAB


def test_a_still_reads_a_profiles_read_mode_with_family_and_says_so(ws, capsys, stills):
    write_profile(ws / "s", RigProfile(structure="read"))
    assert main(["rig", "--still", "grey.dng", "--session", "s"]) == 0
    assert stills[-1]["structure"] == "family" and "read with family" in capsys.readouterr().err


def test_a_profiles_missing_spectrum_file_is_one_line_naming_the_fix(ws, capsys, stills):
    write_profile(ws / "s", RigProfile("gone-camera.csv", "gone-leds.csv"))
    one_line(main(["rig", "--still", "grey.dng", "--session", "s"]), capsys, PROFILE_NAME, "gone-leds.csv",
             "give --led and --sensor")
    assert not stills


@pytest.mark.parametrize("flags, needle", [(["--sim"], "--sim"), (["--roi", "1,1,8,8"], "--roi"),
                                           (["--structure", "read"], "single-light frames")])
def test_a_flag_that_does_not_apply_to_a_still_is_still_refused_with_a_profile(ws, capsys, stills, flags, needle):
    write_profile(ws / "s", LAB)
    before = snapshot(ws)
    one_line(main(["rig", "--still", "grey.dng", "--session", "s", *flags]), capsys, needle)
    assert snapshot(ws) == before and not stills


@pytest.mark.slow
def test_a_still_imported_with_no_flags_gets_the_declared_cameras_reading(ws, capsys):
    """End to end: the session's profile declares the camera and LEDs; the still's record is read in its RGB."""
    from hairdigi.hardware.sim_rig import SimRig
    from hairdigi.hardware.sim_still import write_raw_still

    write_profile(ws / "s", RigProfile("nikon-5100", "LED-B4"))
    still = write_raw_still(ws / "rig.dng", (SimRig(spp=4).radiance() * 0.8).repeat(2, 0).repeat(2, 1))
    assert main(["rig", "--still", str(still), "--session", "s"]) == 0
    assert "read in the camera's RGB (nikon-5100 under LED-B4" in capsys.readouterr().out
    result = json.loads(next((ws / "s" / "captures").glob("*.result.json")).read_text())
    assert result["spectral"]["camera"] == "nikon-5100" and result["spectral"]["led"] == "LED-B4"


# --- estimate with a session's calibration ---------------------------------------------------------------
def _estimate_args(calibration, **flags) -> argparse.Namespace:
    base = {"calibration": str(calibration), "led": None, "sensor": None, "structure": None, "lights": None}
    return argparse.Namespace(**{**base, **flags})


def test_estimate_with_a_sessions_calibration_reads_its_profile(ws, capsys):
    from hairdigi.app.cli.estimate import session_profile

    write_profile(ws / "s", LAB)
    args = _estimate_args(ws / "s" / "calibration.json")
    session_profile(args)
    assert (args.led, args.sensor, args.structure) == ("LED-B4", "nikon-5100", "family")
    args = _estimate_args(ws / "s" / "calibration.json", structure="assumed")
    session_profile(args)
    assert args.structure == "assumed" and "--structure assumed overrides" in capsys.readouterr().err
    args = _estimate_args(ws / "elsewhere.json")   # a calibration outside a session: no profile
    session_profile(args)
    assert args.led is None and args.structure is None


def test_the_app_runs_as_the_sessions_profile_declares_and_a_flag_overrides_it_for_one_run(tmp_path):
    """``hairdigi app``'s rig (``session_rig``): a session's profile gives the camera, LEDs and structure, a flag
    given overrides it for this run and the status line says so; a session without one keeps what the run
    used; a damaged profile is named and left as it is."""
    from hairdigi.app.gui.main import SETTING_DEFAULTS, session_rig

    settings = dict(SETTING_DEFAULTS, structure="read")
    lab = tmp_path / "lab"
    write_profile(lab, RigProfile("nikon-5100", "LED-B4", "assumed"))
    led, sensor, structure, said = session_rig(lab, settings, False, None, None, None)
    assert (led, sensor, structure) == ("LED-B4", "nikon-5100", StructureMode.ASSUMED) and "rig-profile.json" in said
    led, sensor, structure, said = session_rig(lab, settings, False, None, None, "family")
    assert structure is StructureMode.FAMILY and "--structure family overrides" in said
    assert read_profile(lab).structure is StructureMode.ASSUMED             # for this run only
    fresh = tmp_path / "fresh"
    assert session_rig(fresh, settings, True, None, None, None)[2] is StructureMode.READ
    assert read_profile(fresh) == RigProfile(None, None, "read")          # declared once
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    (damaged / PROFILE_NAME).write_text("{not json")
    led, sensor, structure, said = session_rig(damaged, settings, True, None, None, None)
    assert structure is StructureMode.READ and PROFILE_NAME in said and (damaged / PROFILE_NAME).read_text() == "{not json"
