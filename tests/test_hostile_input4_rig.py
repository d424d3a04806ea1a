"""Careless and hostile input, fourth round: stills, spectra, light frames and the display.

One numbered class of such input per section. Most cases run the command line in this process (``main``);
the races and the display run real processes and real sockets. Every refused case is one stderr line and
exit 2, and leaves the working folder byte for byte as it was. Shared helpers: ``tests/hostile.py``.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hairdigi.app.cli import main
from hostile import one_line, snapshot


def grey_still(path: Path, side: int = 128) -> Path:
    """A readable DNG with no chart in view: imported, kept and blocked (its chart is missing)."""
    from hairdigi.hardware.sim_still import write_raw_still

    return write_raw_still(path, np.full((side, side, 3), 0.3))


@pytest.fixture
def ws(tmp_path, monkeypatch) -> Path:
    monkeypatch.chdir(tmp_path)
    grey_still(tmp_path / "grey.dng")
    return tmp_path


# --- 2. two captures, one id -----------------------------------------------------------------------------
#: A ``rig --still`` whose clock stands still: every capture id it draws is the same millisecond's.
FROZEN_STILL = """
import sys, time, types
import hairdigi.hardware.capture as capture
capture.time = types.SimpleNamespace(time=lambda: 1795000000.5, strftime=time.strftime, localtime=time.localtime)
from hairdigi.app.cli import main
sys.exit(main(["rig", "--still", sys.argv[1], "--session", sys.argv[2]]))
"""


def test_two_processes_importing_stills_in_the_same_millisecond_keep_both(ws):
    env = {**os.environ, "OMP_WAIT_POLICY": "PASSIVE"}
    stills = [grey_still(ws / f"IMG_{i}.dng", 96 + 32 * i) for i in range(2)]
    runs = [subprocess.Popen([sys.executable, "-c", FROZEN_STILL, str(still), str(ws / "s")], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for still in stills]
    outs = [run.communicate(timeout=120) for run in runs]
    assert [run.returncode for run in runs] == [2, 2], outs     # each kept, blocked: no chart in a grey still
    captures = ws / "s" / "captures"
    records = sorted(p for p in captures.glob("*.json") if not p.name.endswith(".result.json"))
    assert len(records) == 2, sorted(p.name for p in captures.iterdir())
    kept = {json.loads(r.read_text())["image"] for r in records}
    assert sorted((captures / name).read_bytes() for name in kept) == sorted(s.read_bytes() for s in stills)
    assert len(list(captures.glob("*.result.json"))) == 2
    assert not list(captures.glob(".*")), "a capture id's reservation was left behind"


# --- 5. rig --still: an option that does not apply is refused, one that does is honoured ----------------
@pytest.mark.parametrize("flags, needle", [
    (["--sim"], "--sim"), (["--sim", "--spectral"], "--sim --spectral"), (["--genicam"], "--genicam"),
    (["--genicam", "fake-1"], "--genicam"), (["--roi", "1,1,8,8"], "--roi"), (["--port", "/dev/null"], "--port"),
    (["--camera", "2"], "--camera"), (["--dead", "1"], "--dead"), (["--spp", "4"], "--spp"),
    (["--structure", "read"], "--structure read"),
])
def test_rig_still_refuses_what_does_not_apply_to_a_still(ws, capsys, flags, needle):
    before = snapshot(ws)
    code = main(["rig", "--still", "grey.dng", "--session", "s", *flags])
    one_line(code, capsys, needle, "--still" if needle != "--structure read" else "single-light frames")
    assert snapshot(ws) == before and not (ws / "s").exists()


@pytest.mark.slow
def test_rig_still_reads_a_declared_camera_and_leds(ws, capsys):
    """``--led`` and ``--sensor`` with ``--still``: the still's record is read in the declared camera's RGB."""
    from hairdigi.hardware.sim_rig import SimRig
    from hairdigi.hardware.sim_still import write_raw_still

    still = write_raw_still(ws / "rig.dng", (SimRig(spp=4).radiance() * 0.8).repeat(2, 0).repeat(2, 1))
    assert main(["rig", "--still", str(still), "--session", "s", "--led", "LED-B4", "--sensor", "nikon-5100"]) == 0
    assert "read in the camera's RGB (nikon-5100 under LED-B4" in capsys.readouterr().out
    result = json.loads(next((ws / "s" / "captures").glob("*.result.json")).read_text())
    assert result["spectral"]["camera"] == "nikon-5100" and result["spectral"]["led"] == "LED-B4"


# --- 10. a still fills the disk; an unreadable still leaves nothing behind ------------------------------
def test_a_huge_sparse_file_given_as_a_still_is_refused_before_the_copy(ws, capsys):
    before = snapshot(ws)   # (not of the huge file: a snapshot would read its 20 GB)
    huge = ws / "big" / "huge.dng"
    huge.parent.mkdir()
    with open(huge, "wb") as f:
        f.truncate(20 * 10 ** 9)   # 20 GB, sparse: no disk used until something copies it
    one_line(main(["rig", "--still", str(huge), "--session", "s"]), capsys, "huge.dng", "20000 MB", "nothing was copied")
    huge.unlink()
    huge.parent.rmdir()
    assert snapshot(ws) == before and not (ws / "s").exists()


def _unreadable_stills(ws: Path) -> dict[str, Path]:
    import cv2

    from hairdigi.hardware.sim_still import write_raw_still

    picture = np.random.default_rng(0).integers(0, 255, (96, 96, 3), np.uint8)
    cv2.imwrite(str(ws / "p.jpg"), picture)
    cv2.imwrite(str(ws / "p.png"), picture)
    grey = (ws / "grey.dng").read_bytes()
    files = {"jpeg.dng": (ws / "p.jpg").read_bytes(), "png.nef": (ws / "p.png").read_bytes(),
             "truncated.dng": grey[:len(grey) // 3], "empty.dng": b""}
    out = {name: ws / name for name in files}
    for name, data in files.items():
        out[name].write_bytes(data)
    out["tiny.dng"] = write_raw_still(ws / "tiny.dng", np.full((2, 2, 3), 0.3))
    out["small.dng"] = write_raw_still(ws / "small.dng", np.full((32, 32, 3), 0.3))
    return out


def test_a_still_that_cannot_be_read_leaves_nothing_in_the_session(ws, capsys):
    main(["rig", "--still", "grey.dng", "--session", "s"])   # a session with one capture already
    capsys.readouterr()
    for name, still in _unreadable_stills(ws).items():
        for session in ("s", "new"):
            before = snapshot(ws)
            one_line(main(["rig", "--still", str(still), "--session", session]), capsys, name, "nothing was kept")
            assert snapshot(ws) == before, (name, session)
            assert not (ws / "new").exists(), name


# --- 11. spectral inputs checked for what the physics needs (and 4: a light that is not visible) -------------
NM = np.arange(300, 905, 5)


def spectrum_csv(path: Path, *columns: np.ndarray, header: str | None = "nm,value") -> Path:
    rows = [",".join(f"{v:g}" for v in row) for row in zip(NM, *columns)]
    path.write_text("\n".join(([header] if header else []) + rows) + "\n")
    return path


def bump(centre: float, width: float = 30.0) -> np.ndarray:
    return np.exp(-0.5 * ((NM - centre) / width) ** 2)


def where(mask) -> np.ndarray:
    return np.asarray(mask, float)


@pytest.fixture
def spectra_files(ws) -> dict[str, Path]:
    """Lights and cameras a careless user might declare, and a sound pair."""
    r, g, b = bump(600), bump(540), bump(460)
    return {
        "infrared.csv": spectrum_csv(ws / "infrared.csv", where(NM >= 820)),
        "ir780.csv": spectrum_csv(ws / "ir780.csv", where(NM >= 780)),
        "uv.csv": spectrum_csv(ws / "uv.csv", where(NM <= 365)),
        "mono.csv": spectrum_csv(ws / "mono.csv", bump(590, 3)),
        "white.csv": spectrum_csv(ws / "white.csv", bump(450, 12) + 0.8 * bump(570, 60)),
        "red-ir.csv": spectrum_csv(ws / "red-ir.csv", where(NM > 830), g, b),
        "red-uv.csv": spectrum_csv(ws / "red-uv.csv", where(NM < 360), g, b),
        "alike.csv": spectrum_csv(ws / "alike.csv", g, g, g * 0.9),
        "bgr.csv": spectrum_csv(ws / "bgr.csv", b, g, r),
        "camera.csv": spectrum_csv(ws / "camera.csv", r, g, b),
    }


@pytest.mark.parametrize("argv, needle", [
    (["rig", "--sim", "--spectral", "--sensor", "red-ir.csv"], "channel r"),
    (["rig", "--sim", "--spectral", "--sensor", "red-uv.csv"], "channel r"),
    (["rig", "--sim", "--spectral", "--sensor", "alike.csv"], "respond alike"),
    (["rig", "--sim", "--spectral", "--sensor", "bgr.csv"], "wavelength, r, g, b"),
    (["rig", "--sim", "--spectral", "--led", "ir780.csv"], "where the eye sees"),
    (["rig", "--sim", "--spectral", "--led", "uv.csv"], "where the eye sees"),
    (["rig", "--sim", "--spectral", "--led", "mono.csv"], "not a white light"),
    (["rig", "--led", "mono.csv", "--sensor", "camera.csv"], "not a white light"),
    (["estimate", "grey.dng", "--out", "o.json", "--calibration", "cal.json", "--led", "white.csv", "--sensor",
      "red-ir.csv"], "channel r"),
    (["render", "--params", "p.json", "--out", "o.png", "--size", "16", "--spp", "1", "--illuminant", "infrared.csv"],
     "where the eye sees"),
    (["render", "--params", "p.json", "--out", "o.png", "--size", "16", "--spp", "1", "--illuminant", "uv.csv"],
     "where the eye sees"),
])
def test_spectra_the_physics_cannot_use_are_refused_in_one_line(ws, spectra_files, capsys, argv, needle):
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.records import CalibrationProfile, write_record

    (ws / "p.json").write_text(json.dumps(HairParams((190.0, 70.0, 40.0), 0.5, 0.3, 0.4).to_dict()))
    write_record(ws / "cal.json", CalibrationProfile("c", "Finlayson 2015", tuple(map(tuple, np.eye(3))), 1.7e9))
    before = snapshot(ws)
    one_line(main([*argv, "--session", "s"] if argv[0] == "rig" else argv), capsys, needle)
    assert snapshot(ws) == before and not (ws / "s").exists()


def test_sound_spectra_and_every_named_light_and_camera_still_pass(spectra_files):
    from hairdigi.app.session.declared_spectra import spectra_problem
    from hairdigi.render import spectra
    from hairdigi.render.domain.bounds import CAMERAS, ILLUMINANTS

    assert spectra_problem(str(spectra_files["white.csv"]), str(spectra_files["camera.csv"])) is None
    for camera in CAMERAS:
        assert spectra_problem("LED-B4", camera) is None
    for light in ILLUMINANTS:
        assert np.all(np.isfinite(spectra.illuminant_spd(light))), light
        assert light.startswith(("FL", "LED", "D", "A", "tungsten", "shop", "day")) and \
            spectra.white_light_problem(light) is None, light


# --- 6. a spectral CSV's malformed first row is an error, not a header ------------------------------------
def test_a_malformed_first_row_of_a_headerless_csv_is_named_not_dropped(ws):
    from hairdigi.render.spectra import SpectrumError, illuminant_spd

    good = [f"{w},{1.0 + w / 1000:.3f}" for w in range(360, 835, 5)]
    (ws / "bad-first.csv").write_text("\n".join(["360,1.2x", *good[1:]]) + "\n")
    with pytest.raises(SpectrumError, match=r"line 1: '360,1.2x'"):
        illuminant_spd(str(ws / "bad-first.csv"))
    (ws / "header.csv").write_text("\n".join(["wavelength (nm),power", *good]) + "\n")
    (ws / "bare.csv").write_text("\n".join(good) + "\n")
    assert np.allclose(illuminant_spd(str(ws / "header.csv")), illuminant_spd(str(ws / "bare.csv")))


# --- 4. a camera reading the declared spectra cannot explain is unreliable, with its cause ----------------
def test_a_camera_reading_far_beyond_the_held_out_residuals_makes_the_record_unreliable():
    from media import chart_profile

    from hairdigi.inference.refine import RefineSettings, response_curve
    from hairdigi.inference.spectral_reading import RigSpectra, spectral_record
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.domain.records import EstimateRecord, RefinementRecord, WarningKind
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE

    curve = response_curve(RIG_SWATCH_POSE, RefineSettings())
    spectra, profile = RigSpectra("LED-B4", "nikon-5100"), chart_profile(np.eye(3))

    def read(target):
        record = EstimateRecord(hair=HairParams(), refinement=RefinementRecord(ran=True, sigma_a=(0.6, 0.9, 1.4),
                                                                               target_linear_rgb=target))
        return spectral_record(record, spectra, profile, curve)

    brown = read((0.1, 0.06, 0.04))
    assert brown.reliable and brown.spectral.residual < 0.41 and not brown.warnings
    green = read((0.02, 0.3, 0.02))    # no hair is this colour: the declared spectra cannot explain it
    assert green.spectral.residual > 10 and not green.reliable
    (warning,) = [w for w in green.warnings if w.kind is WarningKind.UNREACHABLE]
    assert "LEDs that are not white" in warning.message and "camera CSV" in warning.message


# --- 3. light frames in the wrong order, or that fit no shine, make the record unreliable ------------------
def test_light_frames_in_the_wrong_order_or_fitting_no_shine_are_named():
    from hairdigi.inference.appearance_reading import read_appearance
    from hairdigi.inference.refine import RefineSettings
    from hairdigi.inference.shine import shine_tables
    from hairdigi.render.domain.records import UNRELIABLE
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE

    settings = RefineSettings(size=16, spp=4)     # small real tables: the reading is the same at any size
    tables = shine_tables(RIG_SWATCH_POSE, settings)
    noise = np.exp(np.random.default_rng(1).normal(0, 0.01, (3, 3)))
    means = tables.predict(np.array([0.6, 0.9, 1.4]), 0.2) * noise     # glossy brown hair, in light order

    def unreliable(frames) -> list[str]:
        reading = read_appearance(frames, RIG_SWATCH_POSE, settings)
        return [w.message for w in reading.warnings if w.kind in UNRELIABLE]

    assert unreliable(means) == []
    (wrong,) = unreliable(means[[2, 0, 1]])     # estimate --lights L2,L0,L1
    assert "wrong order" in wrong and "L1,L2,L0" in wrong
    off = means.copy()
    off[2] *= 0.05                              # light 2 far too weak in its frame
    (weak,) = unreliable(off)
    assert "fit no shine" in weak and "a light off" in weak


# --- 6. render --params renders a record's measured shine, as export does -----------------------------------
def test_render_params_uses_the_records_measured_shine(ws, capsys):
    from hairdigi.render.domain.appearance import Appearance, AppearanceEstimate
    from hairdigi.render.domain.records import write_record
    from hostile import estimate_record

    for name, shine in (("glossy", 0.15), ("rough", 0.5)):
        look = AppearanceEstimate(Appearance(longitudinal_roughness=shine), measured=("longitudinal_roughness",))
        write_record(ws / f"{name}.json", estimate_record(appearance=look))
        assert main(["render", "--params", f"{name}.json", "--out", f"{name}.png", "--size", "24", "--spp", "2",
                     "--strands", "60"]) == 0
    assert (ws / "glossy.png").read_bytes() != (ws / "rough.png").read_bytes()
    (ws / "bad.json").write_text(json.dumps({**json.loads((ws / "glossy.json").read_text()), "appearance": [0.2]}))
    capsys.readouterr()
    one_line(main(["render", "--params", "bad.json", "--out", "bad.png", "--size", "24", "--spp", "2"]), capsys,
             "bad.json", "appearance")
    assert not (ws / "bad.png").exists()


# --- 13. a display that answers but is not X ------------------------------------------------------------------
class FakeXPort:
    """A TCP server on an X display's port (6000 + N) that accepts, then sends ``reply`` (None: never answers)."""

    def __init__(self, reply: bytes | None):
        import socket
        import threading

        self.server, self.number = None, None
        for number in range(150, 400):
            candidate = socket.socket()
            try:
                candidate.bind(("127.0.0.1", 6000 + number))
            except OSError:
                candidate.close()
                continue
            self.server, self.number = candidate, number
            break
        assert self.server is not None, "no free port for a fake X display"
        self.server.listen(4)
        self.reply, self.held = reply, []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.server.accept()
            except OSError:
                return
            self.held.append(conn)
            if self.reply is not None:
                conn.sendall(self.reply)

    def close(self) -> None:
        self.server.close()
        for conn in self.held:
            conn.close()


def app_under(display: str, tmp_path: Path, timeout: float = 40) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    env.update(DISPLAY=display, OMP_WAIT_POLICY="PASSIVE", HOME=str(tmp_path))
    return subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "app", "--sim", "--session", str(tmp_path / "s")],
                          capture_output=True, text=True, timeout=timeout, env=env, cwd=tmp_path)


@pytest.mark.parametrize("reply, needle", [(b"SSH-2.0-OpenSSH_9.6\r\n", "not an X server"),
                                           (None, "does not answer as an X server")])
def test_a_display_port_that_is_not_x_is_one_line_not_an_abort_or_a_hang(tmp_path, reply, needle):
    fake = FakeXPort(reply)
    try:
        run = app_under(f"127.0.0.1:{fake.number}", tmp_path)
    finally:
        fake.close()
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1 and needle in lines[0] and "xvfb-run" in lines[0], run.stderr[-2000:]
    assert not (tmp_path / "s").exists()


def test_the_x_handshake_tells_a_real_x_server_from_an_unroutable_address(xvfb):
    import time

    from hairdigi.app.cli.display import x_handshake_problem

    start = time.monotonic()   # unroutable: no connection, or (behind a proxy that takes every port) not X
    problem = x_handshake_problem("10.255.255.1:0", timeout=0.5)
    assert problem is not None and ("no X server accepts" in problem or "not an X server" in problem), problem
    assert time.monotonic() - start < 3
    assert "not a display name" in x_handshake_problem("nonsense")
    # the run's own Xvfb, on a display it chose itself once it listened (a fixed :97 collided with other servers)
    assert x_handshake_problem(xvfb) is None


# --- 14b. an empty session folder -----------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [["rig", "--sim", "--spp", "1"], ["rig", "--still", "grey.dng"], ["app", "--sim"]])
def test_an_empty_session_path_is_refused(ws, capsys, monkeypatch, argv):
    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    before = snapshot(ws)
    one_line(main([*argv, "--session", ""]), capsys, "--session ''")
    assert snapshot(ws) == before and not (ws / "captures").exists()
