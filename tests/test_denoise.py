"""The preview denoiser (OIDN through pyoidn) on real renders: it keeps the raw pass's colour, it
removes noise, and without pyoidn it says how to install it."""
import subprocess
import sys

import numpy as np
import pytest

from hairdigi.render import denoise as dn
from hairdigi.render.metrics import mean_colour_delta_e, pixel_delta_e
from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import Renderer, SceneSpec

needs_oidn = pytest.mark.skipif(not dn.available(), reason="pyoidn is not installed")
BROWN = HairParams((190, 80, 40), 0.5, 0.5, 0.6)


@pytest.fixture(scope="module")
def renders():
    """A small hairstyle and swatch: two 1-spp passes (seeds differ) and a 2-spp pass."""
    renderer = Renderer(max_cached=2)
    style, swatch = SceneSpec("straight", strands=300), SceneSpec("swatch", strands=400)
    return {"style": [renderer.render(BROWN, style, 64, spp, seed=s).linear for spp, s in ((1, 1), (1, 2), (2, 3))],
            "swatch": [renderer.render(BROWN, swatch, 48, spp, seed=s).linear for spp, s in ((1, 4), (1, 5), (2, 6))]}


@needs_oidn
@pytest.mark.parametrize("scene", ["style", "swatch"])
def test_the_denoised_pass_keeps_the_raw_pass_mean_colour(renders, scene):
    for raw in renders[scene]:
        clean = dn.denoise(raw)
        assert clean.shape == raw.shape and clean.dtype == np.float32 and np.isfinite(clean).all()
        assert mean_colour_delta_e(clean, raw) <= 0.5
        assert not np.shares_memory(clean, raw)


@needs_oidn
@pytest.mark.parametrize("scene", ["style", "swatch"])
def test_the_denoiser_removes_noise(renders, scene):
    """Two 1-spp passes with different seeds: denoised, they agree far better than raw."""
    a, b = renders[scene][:2]
    assert pixel_delta_e(dn.denoise(a), dn.denoise(b)) < 0.4 * pixel_delta_e(a, b)


def test_restore_mean_gives_back_the_removed_energy_where_it_was():
    raw = np.full((160, 160, 3), 0.04, np.float32)
    raw[64:96, 64:96] = np.random.default_rng(1).uniform(0, 0.4, (32, 32, 3))    # a noisy patch on a clean ground
    lossy = raw.copy()
    lossy[64:96, 64:96] = 0.15                                               # smooth, and too dark
    out = dn.restore_mean(lossy, raw)
    np.testing.assert_allclose(out.reshape(-1, 3).mean(0), raw.reshape(-1, 3).mean(0), rtol=1e-3)
    np.testing.assert_allclose(out[:4, :4], 0.04, atol=1e-3)                 # the far ground stays as it was


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="H, W, 3"):
        dn.denoise(np.zeros((4, 4)))


def test_without_pyoidn_the_error_says_how_to_install_it():
    code = ("import sys; sys.modules['pyoidn'] = None\n"
            "from hairdigi.render import denoise as dn\n"
            "assert not dn.available() and dn.name() == 'none'\n"
            "try:\n    dn.denoise(__import__('numpy').zeros((4, 4, 3), 'float32'))\n"
            "except dn.DenoiserMissing as exc:\n    print(exc)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert "pip install pyoidn" in out.stdout


@needs_oidn
def test_denoising_loads_no_torch():
    """pyoidn imports torch when it is installed; the runtime path must not (and need not) load it."""
    code = ("import sys, numpy as np\n"
            "from hairdigi.render import denoise as dn\n"
            "dn.denoise(np.full((8, 8, 3), 0.2, np.float32))\n"
            "print('torch' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "False"


def test_nonfinite_input_is_refused_with_its_count():
    """The renderer counts and replaces NaN and Inf (RenderResult.nonfinite); denoise never hides them."""
    image = np.full((8, 8, 3), 0.2, np.float32)
    image[0, 0] = (np.nan, np.inf, 0.2)
    with pytest.raises(ValueError, match="2 NaN or Inf"):
        dn.denoise(image)
