"""The spectral world beyond ``hairdigi rig``: the desktop app declares a rig's spectra, a photo's
estimate carries an undeclared camera's metamerism, and a chart correction that cannot carry the
camera answer is named in the record."""
import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from media import chart_profile

from hairdigi.render.domain.estimate_parts import Uncertainty
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord, WarningKind, read_record

ROOT = Path(__file__).resolve().parents[1]


def hairdigi(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hairdigi.app.cli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT), "OMP_WAIT_POLICY": "PASSIVE",
                                            "QT_QPA_PLATFORM": "offscreen"})


def test_the_app_declares_a_real_rigs_spectra_both_together_and_refuses_half_in_one_line(tmp_path):
    for args, says in ((("--led", "A"), "--led and --sensor together"),
                       (("--sensor", "nikon-5100"), "--led and --sensor together"),
                       (("--spectral",), "add --sim"),
                       (("--sim", "--sensor", "nikon-5100"), "--sensor goes with --spectral"),
                       (("--led", "A", "--sensor", str(tmp_path / "none.csv")), "--sensor")):
        done = hairdigi("app", "--session", str(tmp_path / "s"), *args, cwd=tmp_path)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and says in lines[0], (args, done.stderr)
    assert not (tmp_path / "s").exists()


def test_the_app_and_the_rig_read_their_spectra_alike():
    """One reading of --sim, --spectral, --led and --sensor for both commands."""
    from hairdigi.app.session.declared_spectra import rig_spectra
    from hairdigi.inference.spectral_reading import RigSpectra

    assert rig_spectra(True, False, None, None) == ({}, None)
    assert rig_spectra(True, True, None, None) == ({"illuminant": "LED-B4", "sensitivities": "nikon-5100"}, None)
    assert rig_spectra(True, True, "A", "cie") == ({"illuminant": "A", "sensitivities": None}, None)
    assert rig_spectra(False, False, None, None) == ({}, None)
    assert rig_spectra(False, False, "A", "sigma-sdmerill") == ({}, RigSpectra("A", "sigma-sdmerill"))


def test_a_declared_rig_whose_correction_is_not_3x3_is_warned_of_and_keeps_the_wide_interval():
    from hairdigi.inference.spectral_reading import RigSpectra, spectral_record

    table = {"source": "test", "cameras": {
        "nikon-5100": {"answer": "camera", "holds_for": "every light", "p68": 1.2, "p95": 5.3},
        "unknown": {"answer": "rgb", "holds_for": "daylight", "p68": 2.7, "p95": 7.2}}}
    record = EstimateRecord(hair=HairParams(), uncertainty=Uncertainty(mean_colour_de2000_p68=0.5,
                                                                       mean_colour_de2000_p95=6.0))
    root_polynomial = spectral_record(record, RigSpectra("LED-B4", "nikon-5100"), chart_profile(np.eye(3, 6)), table=table)
    assert root_polynomial.spectral is None and root_polynomial.uncertainty.spectral.camera == "unknown"
    assert root_polynomial.uncertainty.mean_colour_de2000_p95 == 7.2
    [warning] = root_polynomial.warnings
    assert warning.kind is WarningKind.OTHER
    assert warning.message.startswith("spectral: the camera answer needs a linear 3x3 chart correction")
    assert "degree 1" in warning.message
    undeclared = spectral_record(record, None, chart_profile(np.eye(3, 6)), table=table)   # nothing declared: nothing to warn of
    assert undeclared.warnings == () and undeclared.uncertainty.spectral.camera == "unknown"


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    """A simulated rig frame with the chart in view, and its calibration profile (Finlayson 2015, degree 1)."""
    from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN
    from hairdigi.inference.calibration import calibrate
    from hairdigi.render.camera_model import CameraModel, sensor_response, spread_glints
    from hairdigi.render.chart import colorchecker_reflectances
    from hairdigi.render.domain import rig_geometry
    from hairdigi.render.renderer import Renderer, SceneSpec

    root = tmp_path_factory.mktemp("photo")
    spec = SceneSpec("swatch", framing="rig", chart=tuple(map(tuple, colorchecker_reflectances())),
                     target=rig_geometry.RIG_TARGET, half_width=rig_geometry.RIG_HALF_WIDTH, strands=1000)
    linear = spread_glints(Renderer(max_cached=1).render(DEFAULT_HIDDEN, spec, (200, 150), 4, seed=1).linear)
    frame = sensor_response(linear, CameraModel(), np.random.default_rng(0))
    cv2.imwrite(str(root / "photo.png"), frame[..., ::-1])
    profile = calibrate(frame, settings={"camera": "sim-rig", "exposure_ev": 0.0, "gain": 1.0})
    (root / "cal.json").write_text(json.dumps(profile.to_json()))
    return root


def test_a_calibrated_photos_estimate_is_widened_for_an_undeclared_cameras_metamerism(photo, tmp_path):
    from hairdigi.inference.spectral_reading import SPECTRAL_TABLE
    from hairdigi.inference.uncertainty import load_table

    done = hairdigi("estimate", str(photo / "photo.png"), "--calibration", str(photo / "cal.json"), "--no-refine",
                    "--out", str(tmp_path / "e.json"), cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    record = read_record(tmp_path / "e.json", EstimateRecord)
    unknown = load_table(SPECTRAL_TABLE)["cameras"]["unknown"]
    assert record.uncertainty.spectral.camera == "unknown" and record.spectral is None
    assert record.uncertainty.mean_colour_de2000_p95 >= unknown["p95"]
    assert "in the spectral world (unknown camera)" in done.stdout
    plain = hairdigi("estimate", str(photo / "photo.png"), "--no-refine", "--out", str(tmp_path / "p.json"),
                     cwd=tmp_path)   # uncalibrated: no chart correction, whose metamerism the table measured
    assert plain.returncode == 0 and read_record(tmp_path / "p.json", EstimateRecord).uncertainty.spectral is None
    half = hairdigi("estimate", str(photo / "photo.png"), "--led", "A", "--out", str(tmp_path / "h.json"),
                    cwd=tmp_path)
    lines = half.stderr.strip().splitlines()
    assert half.returncode == 2 and len(lines) == 1 and "add --calibration" in lines[0], half.stderr


def test_a_photo_of_a_declared_camera_is_read_in_its_rgb(photo, tmp_path):
    done = hairdigi("estimate", str(photo / "photo.png"), "--calibration", str(photo / "cal.json"), "--no-refine",
                    "--led", "LED-B4", "--sensor", "nikon-5100", "--out", str(tmp_path / "e.json"), cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    record = read_record(tmp_path / "e.json", EstimateRecord)
    assert record.spectral is not None and record.spectral.camera == "nikon-5100" and record.spectral.led == "LED-B4"
    assert set(record.spectral.under) == {"D65", "A", "shop-led"}
    assert record.uncertainty.spectral.camera == "nikon-5100"
    assert "read in the camera's RGB (nikon-5100 under LED-B4" in done.stdout


def _with_own_settings(probe: str, home) -> list[str]:
    """The lines ``probe`` prints, run in a process whose app settings live in ``home`` (QSettings are per user)."""
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "XDG_CONFIG_HOME": str(home),
                               "HOME": str(home), "QT_QPA_PLATFORM": "offscreen"})
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip().splitlines()


def test_the_app_remembers_a_real_rigs_spectra_and_names_a_bad_setting(tmp_path):
    """``hairdigi app --led --sensor`` is declared once: the settings keep it for the next start; a half
    or unknown pair in the settings is named, and the rig declares nothing."""
    probe = ("from hairdigi.app.gui.main import declared_spectra, read_settings, write_settings\n"
             "print(declared_spectra(read_settings(), 'A', 'nikon-5100'))\n"
             "print(declared_spectra(read_settings(), None, None))\n"
             "write_settings({'sensor': ''})\n"
             "print(declared_spectra(read_settings(), None, None))\n"
             "write_settings({'sensor': 'canon'})\n"
             "print(declared_spectra(read_settings(), None, None))\n")
    given, remembered, half, unknown = _with_own_settings(probe, tmp_path)
    assert given == remembered == "('A', 'nikon-5100', None)"
    assert half.startswith("(None, None, \"the settings' led and sensor are not used: a real rig declares its spectra "
                           "with --led and --sensor together")
    assert "unknown camera 'canon'" in unknown and unknown.startswith("(None, None,")


def test_the_app_remembers_how_estimates_treat_the_structure_and_names_a_bad_setting(tmp_path):
    """``hairdigi app --structure assumed`` is kept for the next start (the default is family); a setting that is
    not a mode is named and the default used; the settings dialog offers the modes as a list, and saves the one picked."""
    probe = ("from PySide6.QtWidgets import QApplication\n"
             "app = QApplication([])\n"
             "from hairdigi.app.gui.main import SettingsDialog, chosen_structure, read_settings, write_settings\n"
             "print(chosen_structure(read_settings(), None))\n"
             "print(chosen_structure(read_settings(), 'assumed'))\n"
             "print(chosen_structure(read_settings(), None))\n"
             "write_settings({'structure': 'guessed'})\n"
             "print(chosen_structure(read_settings(), None))\n"
             "shown = SettingsDialog()\n"
             "box = shown.fields['structure']\n"
             "print(box.currentText(), [box.itemText(i) for i in range(box.count())])\n"
             "dialog = SettingsDialog()\n"
             "dialog.fields['structure'].setCurrentText('read')\n"
             "dialog._save()\n"
             "print(chosen_structure(read_settings(), None))\n")
    first, given, remembered, bad, shown, saved = _with_own_settings(probe, tmp_path)
    assert first == "('family', None)" and given == remembered == "('assumed', None)"
    assert bad.startswith("('family', \"the settings' structure 'guessed' is not one of assumed, family, read")
    assert shown == "family ['assumed', 'family', 'read']"
    assert saved == "('read', None)"
