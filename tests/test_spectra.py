"""The spectral world (render.spectra): hair absorption as spectra, lights and cameras, and spectral
renders through the same Renderer and scenes."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hairdigi.render import spectra
from hairdigi.render.domain.absorption import EUMELANIN_SIGMA_A, PHEOMELANIN_SIGMA_A, hair_sigma_a
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE

ROOT = Path(__file__).resolve().parents[1]
N = len(spectra.WAVELENGTHS)


# -- science ------------------------------------------------------------------------------------
def test_a_flat_spectrum_projects_to_itself_and_d65_is_white():
    assert np.allclose(spectra.rgb_projection(np.full(N, 0.7)), 0.7)
    assert np.allclose(spectra.light_rgb("D65"), 1.0, atol=2e-3)
    assert spectra.spectrum_to_xyz(spectra.illuminant_spd("tungsten"))[1] == pytest.approx(1.0)


def test_the_melanin_spectra_reproduce_the_published_rgb_coefficients_within_the_stated_error():
    eu = spectra.rgb_projection(spectra.eumelanin_spectrum())
    pheo = spectra.rgb_projection(spectra.pheomelanin_spectrum())
    assert np.max(np.abs(eu / EUMELANIN_SIGMA_A - 1)) < 0.066       # the module's docstring: 6.5%
    assert np.max(np.abs(pheo / PHEOMELANIN_SIGMA_A - 1)) < 0.083   # 8.2%
    # power laws with Donner & Jensen's exponents: absorption falls with wavelength, faster for pheomelanin
    wl = spectra.WAVELENGTHS
    slope = lambda s: np.polyfit(np.log(wl), np.log(s), 1)[0]
    assert slope(spectra.eumelanin_spectrum()) == pytest.approx(-3.33) and \
        slope(spectra.pheomelanin_spectrum()) == pytest.approx(-4.75)
    # a Table 1 melanin hair's spectrum projects near its RGB mapping
    p = HairParams(melanin_concentration=0.6, melanin_ratio=0.4, dye_concentration=0.0)
    assert np.allclose(spectra.rgb_projection(spectra.hair_sigma_a_spectrum(p)), hair_sigma_a(p), rtol=0.09)


def test_a_dye_spectrum_keeps_its_colour_and_nothing_absorbs_without_dye():
    albedo = spectra.albedo_spectrum(np.array([0.8, 0.3, 0.1]))
    assert albedo.min() > 0 and albedo.max() <= 1
    assert np.allclose(spectra.rgb_projection(albedo), [0.8, 0.3, 0.1], atol=0.03)   # D65 recovers the colour
    assert not spectra.dye_sigma_a_spectrum((40, 200, 90), 0.0).any()
    assert not spectra.dye_sigma_a_spectrum((255, 255, 255), 1.0).any()
    assert np.all(spectra.hair_sigma_a_spectrum(HairParams(dye_rgb=(0, 0, 0), dye_concentration=1.0)) >= 0)


def test_the_dye_spectrum_is_mitsubas_upsampling_and_colour_sciences_solve_of_one_model():
    """Mitsuba's coefficient table (what its spectral variants do with an RGB albedo) against
    colour-science's Jakob & Hanika 2019 solve, on saturated, dark, pale and grey dyes."""
    import colour

    observer = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(observer.shape)
    for rgb in ([0.42, 0.028, 0.95], [0.9, 0.08, 0.12], [0.05, 0.3, 0.1], [0.7, 0.55, 0.35], [0.5, 0.5, 0.5]):
        xyz = colour.RGB_to_XYZ(np.array(rgb), colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=False)
        sd = colour.XYZ_to_sd(xyz, method="Jakob 2019", cmfs=observer, illuminant=d65)
        solved = np.interp(spectra.WAVELENGTHS, sd.wavelengths, sd.values)
        table = spectra.albedo_spectrum(np.array(rgb))
        assert np.max(np.abs(table - solved)) < 0.003, rgb        # measured: 0.0003-0.0023
        assert np.allclose(spectra.rgb_projection(table), rgb, atol=0.002), rgb


# -- lights and cameras -----------------------------------------------------------------------
def test_named_lights_and_cameras_and_csv_files_are_read(tmp_path):
    for name in ("daylight", "tungsten", "shop-led", "FL11", "LED-B1"):
        spd = spectra.illuminant_spd(name)
        assert spd.shape == (N,) and np.all(spd >= 0)
    wl = np.arange(380, 781, 10)
    (tmp_path / "led.csv").write_text("wavelength,power\n" + "\n".join(
        f"{w},{np.exp(-0.5 * ((w - 450) / 12) ** 2) + 0.6 * np.exp(-0.5 * ((w - 570) / 60) ** 2):.5f}" for w in wl))
    led = spectra.illuminant_spd(str(tmp_path / "led.csv"))
    assert spectra.WAVELENGTHS[np.argmax(led)] == pytest.approx(450, abs=5)   # its blue spike
    (tmp_path / "cam.csv").write_text("\n".join(f"{w},{np.exp(-0.5 * ((w - 600) / 30) ** 2):.4f},"
                                                f"{np.exp(-0.5 * ((w - 530) / 35) ** 2):.4f},"
                                                f"{np.exp(-0.5 * ((w - 460) / 25) ** 2):.4f}" for w in wl))
    cam = spectra.camera_sensitivities(str(tmp_path / "cam.csv"))
    assert cam.shape == (N, 3) and np.allclose(cam.max(0), 1)
    assert list(spectra.WAVELENGTHS[np.argmax(cam, 0)]) == [600, 530, 460]
    assert not cam[spectra.WAVELENGTHS > 780].any()                        # zero outside the file's range
    for name in spectra.CAMERAS:
        assert spectra.camera_sensitivities(name).shape == (N, 3)


@pytest.mark.parametrize("text, says", [
    ("400,1\n500,2\n", "need at least 4"),
    ("400,1\n450,x\n500,2\n600,1\n700,1\n", "line 2"),
    ("400,1\n500,1\n450,1\n600,1\n700,1\n", "do not rise"),
    ("0.40,1\n0.50,1\n0.60,1\n0.70,1\n", "in µm? give nm"),
    ("400,1\n500,-1\n600,1\n700,1\n", "negative"),
    ("400,1,2\n500,1,2\n600,1,2\n700,1,2\n", "3 columns, expected 2"),
    ("400,nan\n500,1\n600,1\n700,1\n", "NaN"),
    ("400,0\n500,0\n600,0\n700,0\n", "all zero"),
])
def test_a_bad_spd_csv_is_refused_in_one_line_naming_the_fix(tmp_path, text, says):
    path = tmp_path / "light.csv"
    path.write_text(text)
    with pytest.raises(spectra.SpectrumError) as err:
        spectra.illuminant_spd(str(path))
    message = str(err.value)
    assert says in message and "\n" not in message and "give a CSV of wavelength, power" in message


def test_unknown_lights_cameras_and_unreadable_files_are_refused(tmp_path):
    with pytest.raises(spectra.SpectrumError, match="unknown illuminant 'candle'"):
        spectra.illuminant_spd("candle")
    with pytest.raises(spectra.SpectrumError, match="1000K to 25000K"):
        spectra.illuminant_spd("900K")                 # a temperature out of range is named as such
    warm, cool = spectra.light_rgb("3200K"), spectra.light_rgb("6500 K")   # Planckian radiators by temperature
    assert warm[0] / warm[2] > 2.0 and 0.8 < cool[0] / cool[2] < 1.3
    with pytest.raises(spectra.SpectrumError, match="unknown camera 'canon'"):
        spectra.camera_sensitivities("canon")
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00\x01" * 10)
    with pytest.raises(spectra.SpectrumError, match="not a text CSV"):
        spectra.illuminant_spd(str(tmp_path / "bin.csv"))
    with pytest.raises(spectra.SpectrumError, match="no such file"):
        spectra.camera_sensitivities(str(tmp_path / "missing.csv"))
    with pytest.raises(spectra.SpectrumError, match="not a regular file"):
        spectra.illuminant_spd("/dev/zero.csv" if Path("/dev/zero.csv").exists() else str(_fifo(tmp_path)))


def _fifo(tmp_path: Path) -> Path:
    import os

    path = tmp_path / "pipe.csv"
    os.mkfifo(path)
    return path


# -- spectral renders --------------------------------------------------------------------------
def _mean(hair, illuminant=None, size=32, spp=64, seed=3):
    from hairdigi.render.renderer import SceneSpec, default_renderer

    spec = SceneSpec("swatch", camera=RIG_SWATCH_POSE, illuminant=illuminant)
    return default_renderer().render(hair, spec, size, spp, seed=seed).linear.reshape(-1, 3).mean(0)


def test_a_flat_absorption_spectrum_renders_as_its_rgb():
    from hairdigi.render.metrics import delta_e2000

    for sigma in (0.1, 0.8):
        rgb = _mean(np.full(3, sigma))
        spectral = _mean(np.full(N, sigma), "D65")
        assert delta_e2000(rgb, spectral) < 0.8, (sigma, rgb, spectral)   # sampling noise at 32², 64 spp: ~0.4


def test_a_change_of_light_moves_a_banded_dye_and_not_a_grey():
    from hairdigi.render.metrics import delta_e2000

    def shift(sigma: np.ndarray) -> float:
        """ΔE2000 between D65 and tungsten, each seen by an eye adapted to its light."""
        daylight = spectra.balanced(_mean(sigma, "D65"), "D65")
        tungsten = spectra.balanced(_mean(sigma, "A"), "A")
        return float(delta_e2000(daylight, tungsten))

    grey = np.full(N, 0.25)
    banded = spectra.hair_sigma_a_spectrum(HairParams(melanin_concentration=0.15, dye_concentration=0.0)) \
        + spectra.band_dye(590.0, 25.0, 0.25)
    assert shift(grey) < 1.0
    assert shift(banded) > 3.0


def test_a_spectral_render_takes_table1_parameters_and_refuses_an_rgb_absorption():
    from hairdigi.render.renderer import SceneSpec, default_renderer

    colour = _mean(HairParams(dye_rgb=(230, 40, 30), dye_concentration=0.9, melanin_concentration=0.1), "D65",
                   size=16, spp=8)
    assert colour[0] > 1.5 * colour[1]                                     # a red dye renders red
    with pytest.raises(ValueError, match="Table 1 parameters or sigma_a as 95"):
        default_renderer().render(np.ones(3), SceneSpec("swatch", illuminant="A"), 16, 1)
    with pytest.raises(spectra.SpectrumError, match="unknown illuminant"):
        SceneSpec("swatch", illuminant="candle")


def test_the_render_command_renders_under_a_light_and_refuses_a_bad_one_in_one_line(tmp_path):
    (tmp_path / "p.json").write_text('{"dye_rgb": [150, 110, 220], "dye_concentration": 0.6, '
                                     '"melanin_concentration": 0.15, "melanin_ratio": 0.7}')
    (tmp_path / "bad.csv").write_text("400,1\n500,1\n")

    def run(*extra):
        return subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "render", "--params", "p.json", "--size", "16",
                               "--spp", "4", *extra], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                              env={**__import__("os").environ, "PYTHONPATH": str(ROOT)})

    import cv2

    for balance in ("light", "daylight"):
        done = run("--illuminant", "tungsten", "--balance", balance, "--out", f"{balance}.png")
        assert done.returncode == 0, done.stderr[-2000:]
    seen = {b: cv2.imread(str(tmp_path / f"{b}.png"))[..., ::-1].reshape(-1, 3).mean(0) for b in ("light", "daylight")}
    assert seen["daylight"][0] > 1.4 * seen["daylight"][2]                 # a daylight photograph of tungsten: orange
    assert seen["light"][0] < 1.2 * seen["light"][2]                       # the adapted eye: the grey holder is grey
    for extra, says in ((("--illuminant", "candle"), "is not a light"), (("--illuminant", "bad.csv"), "need at least 4")):
        done = run(*extra, "--out", "x.png")
        assert done.returncode == 2 and says in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert not (tmp_path / "x.png").exists()


def test_a_camera_sees_a_spectrally_flat_grey_under_an_equal_energy_light_as_equal_channels(tmp_path):
    (tmp_path / "flat.csv").write_text("wavelength,power\n360,1\n500,1\n700,1\n830,1\n")
    flat_light, grey = str(tmp_path / "flat.csv"), np.full(N, 0.2)
    for camera in spectra.CAMERAS:
        from hairdigi.render.renderer import SceneSpec, default_renderer

        spec = SceneSpec("swatch", camera=RIG_SWATCH_POSE, illuminant=flat_light, sensitivities=camera)
        raw = default_renderer().render(grey, spec, 24, 32, seed=3).linear.reshape(-1, 3).mean(0)
        assert np.ptp(raw) / raw.mean() < 0.02, (camera, raw)      # each band has unit area (scenes.camera_film)
        tungsten = default_renderer().render(grey, SceneSpec("swatch", camera=RIG_SWATCH_POSE, illuminant="A",
                                                             sensitivities=camera), 24, 32, seed=3)
        r, _, b = tungsten.linear.reshape(-1, 3).mean(0)
        assert r > 1.4 * b                                           # raw: no white balance
    observer = _mean(grey, flat_light, size=24, spp=32)
    assert observer[0] > 1.2 * observer[2]                           # equal energy is pink in sRGB (D65 white)
    from hairdigi.render.renderer import SceneSpec

    with pytest.raises(ValueError, match="need a spectral render"):
        SceneSpec("swatch", sensitivities="nikon-5100")
