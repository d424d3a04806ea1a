"""Real Mitsuba renders, kept tiny: hard cases, the furnace, reuse, determinism, errors."""
import itertools
import subprocess
import sys

import numpy as np
import pytest

from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.domain.rig_geometry import CameraPose

SIZE, SPP, STRANDS = 32, 4, 300


@pytest.fixture(scope="module")
def renderer():
    return Renderer()


def swatch(**kw):
    return SceneSpec("swatch", strands=STRANDS, **kw)


def mean_rgb(result):
    return result.linear.reshape(-1, 3).mean(0)


def test_no_nan_or_inf_over_extremes_and_grazing_cameras(renderer):
    corners = [HairParams(rgb, dc, mc, mr) for rgb, dc, mc, mr in
               itertools.product([(0, 0, 0), (255, 255, 255), (255, 0, 0)], (0, 1), (0, 1), (0, 1))]
    for p in corners:
        r = renderer.render(p, swatch(), SIZE, SPP, 0)
        assert r.nonfinite == 0 and r.linear.min() >= 0, p   # counted before they are replaced by 0
    for polar in (75.0, 85.0, 89.0):
        r = renderer.render(HairParams((255, 255, 255), 0, 0, 0), swatch(camera=CameraPose(polar, 30)), SIZE, SPP, 0)
        assert r.nonfinite == 0 and r.linear.min() >= 0


def test_nonfinite_values_are_counted_not_hidden(monkeypatch):
    """No scene we could build returns a NaN: Mitsuba's film drops NaN and Inf samples (a NaN
    absorption, forced below, renders as 0), and the inputs that could overflow are refused. So the
    film's output is spiked here with NaN and Inf: the result counts them and its images hold 0."""
    import hairdigi.render.renderer as rr

    monkeypatch.setattr(rr, "hair_sigma_a", lambda params: np.array([np.nan, 0.5, 0.5]))
    assert Renderer().render(HairParams(), swatch(framing="crop"), 16, 1, 0).nonfinite == 0
    monkeypatch.undo()
    real = rr.mi.render

    def spiked(scene, **kw):
        image = np.array(real(scene, **kw), dtype=np.float32)
        image[0, :3] = (np.nan, np.inf, -np.inf)
        return image
    monkeypatch.setattr(rr.mi, "render", spiked)
    r = Renderer().render(HairParams(), swatch(framing="crop"), 16, 1, 0)
    assert r.nonfinite == 9 and np.isfinite(r.linear).all() and (r.linear[0, :3] == 0).all()
    passes = list(Renderer().render_progressive(HairParams(), swatch(framing="crop"), 16, 1, 2))
    assert [p.nonfinite for p in passes] == [9, 18]


@pytest.mark.parametrize("kwargs, message", [
    (dict(max_depth=0), "max_depth must be"),
    (dict(max_depth=1), "max_depth must be"),
    (dict(strands=0), "strands must be"),
    (dict(camera=CameraPose(20, float("nan"))), "must be finite"),
    (dict(camera=CameraPose(20, 30, float("inf"))), "must be finite"),
    (dict(camera=CameraPose(20, 30, 1e9)), "camera distance"),
    (dict(camera=CameraPose(0, 0, 0.01)), "camera distance"),
    (dict(lights=(1.0, float("nan"), 1.0)), "lights"),
])
def test_renders_that_would_be_black_are_refused_up_front(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SceneSpec("swatch", **kwargs)


def test_size_and_spp_are_checked_not_defaulted(renderer):
    for size, spp in ((0, 4), (16, 0), (True, 4), (16.0, 4), (5000, 1), (4096, 65536)):
        with pytest.raises(ValueError, match="size|spp"):
            renderer.render(HairParams(), swatch(), size, spp)
    with pytest.raises(ValueError, match="camera distance"):
        SceneSpec("bob", camera=CameraPose(0, 90, 1.0))   # inside the head


def test_darker_with_more_melanin_and_hue_follows_the_dye(renderer):
    lum = [mean_rgb(renderer.render(HairParams((255, 255, 255), 0, m, 0.8), swatch(), SIZE, 16, 0)).mean()
           for m in (0.05, 0.4, 0.8, 1.0)]
    assert all(a > b for a, b in zip(lum, lum[1:])), lum
    for channel in range(3):
        rgb = [20, 20, 20]
        rgb[channel] = 240
        m = mean_rgb(renderer.render(HairParams(tuple(rgb), 1.0, 0.0, 0.5), swatch(), SIZE, 16, 0))
        assert np.argmax(m) == channel, (rgb, m)


def test_white_furnace_at_zero_absorption():
    """A lossless fibre under a white environment must come out white; absorption must not."""
    from hairdigi.render.scenes import furnace_scene
    from hairdigi.render.strands import swatch_strands
    from hairdigi.render.domain.absorption import hair_bsdf
    from hairdigi.render.variant import load_scene, mi
    import tempfile, os

    strands = swatch_strands(150, seed=0).with_dummy()
    with tempfile.TemporaryDirectory() as tmp:
        curves = os.path.join(tmp, "c.txt")
        with open(curves, "w") as f:
            f.write(strands.to_curve_text())
        means = {}
        for name, params in {"lossless": HairParams((255, 255, 255), 0, 0, 0),
                             "absorbing": HairParams((255, 255, 255), 0, 0.6, 1)}.items():
            scene = load_scene(furnace_scene(curves, hair_bsdf(params), CameraPose(0, 0, 0.8), 24))
            means[name] = float(np.asarray(mi.render(scene, spp=64, seed=0)).mean())
    assert abs(means["lossless"] - 1.0) < 0.03, means
    assert means["absorbing"] < 0.9, means


def test_same_seed_same_image_other_seed_expected_noise(renderer):
    """Same seed: identical. Other seed: Monte Carlo noise, which halves when spp is 4x (1/sqrt(spp))."""
    p = HairParams((180, 90, 40), 0.5, 0.3, 0.6)
    a = renderer.render(p, swatch(), SIZE, SPP, seed=7).linear
    assert np.array_equal(a, renderer.render(p, swatch(), SIZE, SPP, seed=7).linear)

    def seed_noise(spp):
        return np.mean([np.sqrt(np.mean((renderer.render(p, swatch(), SIZE, spp, 2 * k).linear
                                         - renderer.render(p, swatch(), SIZE, spp, 2 * k + 1).linear) ** 2))
                        for k in range(3)])

    low, high = seed_noise(4), seed_noise(16)
    assert low > 0.01  # different seeds do differ
    assert 0.4 < high / low < 0.6, (low, high)  # measured 0.49


def test_two_builds_of_one_scene_render_the_same_image():
    """Mitsuba 3.9.1 orders a scene dict's shapes at random on each load, which changes which light
    a random number samples; ``load_scene`` keeps the dict's order, so one seed gives one image."""
    p = HairParams((180, 90, 40), 0.5, 0.3, 0.6)
    for spec in (swatch(), SceneSpec("bob", strands=100)):
        images = [Renderer().render(p, spec, SIZE, SPP, 1).linear for _ in range(4)]
        assert all(np.array_equal(images[0], image) for image in images[1:]), spec.name


def test_updating_a_loaded_scene_matches_a_fresh_one():
    """Hair, camera (with its FOV) and strand layout changed through mi.traverse give the image a
    new scene gives, bit for bit; a wrong camera does not."""
    first = HairParams((255, 255, 255), 0, 0.2, 0.5)
    second = HairParams((30, 200, 90), 0.9, 0.6, 0.2)
    spec = swatch(camera=CameraPose(25, 60, 3.5), strand_seed=5)   # another distance: the FOV must follow
    wrong = swatch(camera=CameraPose(25, 60, 4.0), strand_seed=5)

    r = Renderer()
    r.render(first, swatch(), SIZE, SPP, 0)   # load with other hair, camera and layout
    updated = r.render(second, spec, SIZE, SPP, 3).linear
    fresh = Renderer().render(second, spec, SIZE, SPP, 3).linear
    assert np.abs(updated - fresh).max() <= 1e-5
    assert np.abs(updated - Renderer().render(second, wrong, SIZE, SPP, 3).linear).max() > 1e-2


def test_strands_set_in_memory_render_what_a_curve_file_renders(monkeypatch):
    """A JIT variant's scene is loaded from a one-strand curve file and its strands set through mi.traverse
    (``render.renderer._set_strands``): the image is the one a scene read whole from its curve file gives, bit
    for bit, on a swatch, a swatch of fibre groups (greys) and a hairstyle under its environment."""
    import hairdigi.render.renderer as renderer_module
    from hairdigi.render.domain.appearance import Appearance
    from hairdigi.render.variant import is_jit

    if not is_jit():
        pytest.skip("scalar_rgb reads its strands from the curve file only")
    p = HairParams((180, 90, 40), 0.5, 0.3, 0.6)
    specs = (swatch(), swatch(appearance=Appearance(fibre_spread=0.3, grey_fraction=0.2)),
             SceneSpec("bob", strands=100, env="soft"))
    in_memory = [Renderer().render(p, spec, SIZE, SPP, 1).linear for spec in specs]
    monkeypatch.setattr(renderer_module, "is_jit", lambda: False)     # the whole curve file, as scalar_rgb reads it
    from_file = [Renderer().render(p, spec, SIZE, SPP, 1).linear for spec in specs]
    for spec, a, b in zip(specs, in_memory, from_file):
        assert np.array_equal(a, b), spec.name


def test_lights_scale_the_image(renderer):
    p = HairParams((255, 255, 255), 0, 0.3, 0.5)
    full = mean_rgb(renderer.render(p, swatch(), SIZE, 16, 0)).mean()
    off = mean_rgb(renderer.render(p, swatch(lights=(0, 0, 0)), SIZE, 16, 0)).mean()
    one = mean_rgb(renderer.render(p, swatch(lights=(1, 0, 0)), SIZE, 16, 0)).mean()
    assert off == 0 and 0.15 * full < one < 0.6 * full


def test_hairstyle_progressive_passes_converge(renderer):
    p = HairParams((255, 255, 255), 0, 0.5, 0.8)
    passes = list(renderer.render_progressive(p, SceneSpec("bob", strands=200), 32, 1, 3))
    assert [r.spp for r in passes] == [1, 2, 3]
    assert np.all(np.isfinite(passes[-1].linear)) and passes[-1].srgb.dtype == np.uint8
    stop = iter([False, True])
    assert len(list(renderer.render_progressive(p, SceneSpec("bob", strands=200), 32, 1, 5,
                                                cancelled=lambda: next(stop)))) == 1


def test_invalid_scene_and_size_are_clear(renderer):
    with pytest.raises(ValueError, match="unknown scene 'beehive'"):
        SceneSpec("beehive")
    with pytest.raises(ValueError, match="unknown environment"):
        SceneSpec("bob", env="disco")
    with pytest.raises(ValueError, match="size must be"):
        renderer.render(HairParams(), swatch(), 2, 1)
    with pytest.raises(ValueError, match="polar angle"):
        CameraPose(95, 0)


def test_no_eumelanin_bspline_crash_case():
    """The case that segfaulted Mitsuba 3.9.1 without the dummy strand: eumelanin 0, 64 spp."""
    code = ("from hairdigi.render.renderer import render, SceneSpec; from hairdigi.render.domain.params import HairParams;"
            "import numpy as np;"
            "r = render(HairParams((255,255,255), 0, 0.7, 0.0), SceneSpec('swatch'), 96, 64, 0);"
            "assert np.isfinite(r.linear).all(); print('ok')")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "ok" in run.stdout, run.stderr[-2000:]


def test_uniform_parameters_span_platinum_to_black_and_many_hues(renderer):
    import colorsys
    from hairdigi.render.domain.params import sample_params

    rng = np.random.default_rng(0)
    means = np.array([mean_rgb(renderer.render(sample_params(rng), swatch(), SIZE, 4, i)) for i in range(24)])
    lum = means @ np.array([0.2126, 0.7152, 0.0722])
    assert lum.min() < 0.02 and lum.max() > 8 * lum.min()          # near-black to light
    hues = {int(colorsys.rgb_to_hsv(*m)[0] * 6) for m in means if np.ptp(m) > 0.3 * m.max()}
    assert len(hues) >= 3, hues                                      # dyed swatches spread over hues


def test_scalar_fallback_renders_the_same_scene():
    """HAIRDIGI_VARIANT=scalar_rgb (what a machine without libLLVM 19 gets) gives the same mean colour."""
    import os
    code = ("import numpy as np; from hairdigi.render.renderer import render, SceneSpec; from hairdigi.render.domain.params import HairParams;"
            "from hairdigi.render.variant import mi;"
            "r = render(HairParams((200,90,40), 0.6, 0.3, 0.5), SceneSpec('swatch', strands=300), 24, 16, 0);"
            "print(mi.variant(), *r.linear.reshape(-1, 3).mean(0))")
    outs = {}
    for variant in ("scalar_rgb", "llvm_ad_rgb"):
        run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                             env={**os.environ, "HAIRDIGI_VARIANT": variant})
        assert run.returncode == 0, run.stderr[-2000:]
        name, *values = run.stdout.split()
        assert name == variant
        outs[variant] = np.array([float(v) for v in values])
    assert np.allclose(outs["scalar_rgb"], outs["llvm_ad_rgb"], rtol=0.1), outs


def test_renders_from_two_threads_take_turns(renderer):
    """Two threads render one scene with different hair at once (the app's twin and hairstyle workers
    share a Renderer): each must get exactly the image a lone render of its own hair gives."""
    import threading
    hairs = {"red": HairParams((230, 30, 30), 1.0, 0.0, 0.5), "dark": HairParams((255, 255, 255), 0.0, 0.9, 0.9)}
    spec = swatch()
    results, errors = {}, []

    def job(name):
        try:
            results[name] = [renderer.render(hairs[name], spec, 48, 4, k).linear for k in range(6)]
        except Exception as exc:  # noqa: BLE001 — collected and asserted below
            errors.append(exc)

    threads = [threading.Thread(target=job, args=(name,)) for name in hairs]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    assert not errors
    for name, images in results.items():
        for k, image in enumerate(images):
            assert np.array_equal(image, renderer.render(hairs[name], spec, 48, 4, k).linear), (name, k)


def test_two_renderers_render_from_two_threads():
    """Every Renderer takes the one process-wide lock: two threads rendering through two Renderers
    (Dr.Jit's LLVM backend crashes on two renders at once) both finish, and never overlap."""
    import threading

    import hairdigi.render.renderer as rr

    inside, overlaps, results = [0], [], {}
    real = rr.mi.render

    def counted(scene, **kw):
        inside[0] += 1
        overlaps.append(inside[0])
        try:
            return real(scene, **kw)
        finally:
            inside[0] -= 1

    def work(name, spec):
        renderer = Renderer(max_cached=1)
        results[name] = [renderer.render(HairParams(), spec, 24, 2, seed).nonfinite for seed in range(3)]

    rr.mi.render = counted
    try:
        threads = [threading.Thread(target=work, args=("swatch", swatch(framing="crop"))),
                   threading.Thread(target=work, args=("bob", SceneSpec("bob", strands=100)))]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
    finally:
        rr.mi.render = real
    assert results == {"swatch": [0, 0, 0], "bob": [0, 0, 0]} and max(overlaps) == 1


def test_a_table_and_the_sim_rig_render_on_the_one_path(tmp_path, monkeypatch):
    """A response curve (the refinement's table) and the simulated rig's light images render through
    ``renderer.trace``: while this thread holds the render lock neither renders (the process's tally stands
    still while both wait at the lock), and once it lets go every one of their renders is counted there, NaN
    count included, which the curve and the rig report as the tally saw it. A render of another thread (one an
    earlier test left running) is told apart by the thread that traced it."""
    import threading
    import time

    import hairdigi.render.renderer as rr
    from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN, render_light_images
    from hairdigi.inference.refine import RefineSettings, response_curve

    class Arrivals:
        """The render lock, noting each thread that comes to it."""

        def __init__(self, lock):
            self.lock, self.threads = lock, set()

        def __enter__(self):
            self.threads.add(threading.get_ident())
            return self.lock.__enter__()

        def __exit__(self, *exc):
            return self.lock.__exit__(*exc)

    traced = []                                   # (thread, NaN count) of each render trace counts
    finite_image = rr.finite_image

    def counted(image):
        linear, nonfinite = finite_image(image)
        traced.append((threading.get_ident(), nonfinite))
        return linear, nonfinite
    monkeypatch.setattr(rr, "finite_image", counted)
    monkeypatch.setattr(rr, "RENDER_LOCK", Arrivals(rr.RENDER_LOCK))
    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path))
    settings = RefineSettings(size=8, spp=1)   # 12 levels: 4 renders
    jobs = {"curve": lambda: response_curve(CameraPose(20, 30), settings, Renderer(max_cached=1), cache=False),
            "rig": lambda: render_light_images(DEFAULT_HIDDEN, (16, 12), 1, cache=False)}   # one render a light
    done = {}
    threads = [threading.Thread(target=lambda k=k, job=job: done.__setitem__(k, job())) for k, job in jobs.items()]
    with rr.RENDER_LOCK:
        renders, nonfinite = rr.TALLY.renders, rr.TALLY.nonfinite
        for t in threads:
            t.start()
        deadline = time.monotonic() + 120
        while not {t.ident for t in threads} <= rr.RENDER_LOCK.threads and time.monotonic() < deadline:
            time.sleep(0.01)
        assert {t.ident for t in threads} <= rr.RENDER_LOCK.threads       # both wait at the lock
        assert rr.TALLY.renders == renders and not done and all(t.is_alive() for t in threads)
    for t in threads:
        t.join(300)
    assert set(done) == {"curve", "rig"}
    with rr.RENDER_LOCK:                          # the tally and the traces read together
        grown, nonfinite_grown, traced = rr.TALLY.renders - renders, rr.TALLY.nonfinite - nonfinite, list(traced)
    ours = [n for thread, n in traced if thread in {t.ident for t in threads}]
    assert len(ours) == 4 + 3 and grown == len(traced)
    images, rig_nonfinite = done["rig"]
    assert images.shape == (3, 12, 16, 3) and np.isfinite(images).all()
    assert done["curve"].nonfinite + rig_nonfinite == sum(ours)
    assert nonfinite_grown == sum(n for _, n in traced)


def test_a_cycles_render_is_checked_as_the_renderer_checks_its_own(tmp_path, monkeypatch):
    """``blender_run.render_cycles``, the one Cycles path, gives Blender the seed and counts and zeroes the NaN
    and Inf values of the image Blender returns, its mean then that image's. Blender is not needed: a stand-in
    program answers as the exported script does, with an image holding a NaN and an Inf."""
    import os
    import sys

    from hairdigi.render.blender_run import layered_swatch, render_cycles, rig_for_blender
    from hairdigi.render.interchange import HairLook

    stand_in = tmp_path / "python"
    stand_in.write_text(f"""#!{sys.executable}
import json, sys
args = sys.argv[sys.argv.index("--") + 1:]
out = args[args.index("--render") + 1]
pixels = [[[float("nan"), 0.5, 0.5], [0.25, float("inf"), 0.5]], [[0.25, 0.5, 0.5], [0.25, 0.5, 0.5]]]
mean = [sum(p[c] for row in pixels for p in row) / 4 for c in range(3)]
json.dump({{"mean_linear": mean, "seconds": 0.1, "spp": int(args[args.index("--spp") + 1]), "exr": out + ".exr",
           "blender": "seed " + args[args.index("--seed") + 1], **({{"pixels": pixels}} if "--pixels" in args else {{}})}},
          open(out, "w"))
""")
    os.chmod(stand_in, 0o755)
    monkeypatch.setenv("HAIRDIGI_BLENDER", str(stand_in))
    look = HairLook("test", (0.3, 0.6, 1.2))
    out = render_cycles(look, rig_for_blender(layered_swatch(), size=2), spp=4, seed=11, pixels=True)
    assert out.nonfinite == 2 and out.blender == "seed 11" and out.spp == 4
    assert np.isfinite(out.pixels).all() and out.pixels[0, 0, 0] == 0 and out.pixels[0, 1, 1] == 0
    assert np.allclose(out.mean_linear, [0.1875, 0.375, 0.5])
    assert render_cycles(look, rig_for_blender(layered_swatch(), size=2), spp=4, seed=11).pixels is None


def test_aov_render_and_build_count():
    r = Renderer(max_cached=2)
    spec = swatch(framing="crop")
    r.render(HairParams(), spec, 16, 1)
    r.render(HairParams((255, 0, 0), 0.5, 0.3, 0.5), spec, 16, 1, seed=2)     # an update, not a build
    aov = r.render_aov(HairParams(), spec, "albedo:albedo,nn:sh_normal", 16, 1)
    assert r.builds == 1 and aov.linear.shape == (16, 16, 6) and aov.nonfinite == 0
    assert aov.linear[..., :3].max() <= 1.0 + 1e-6 and np.abs(aov.linear[..., 3:]).max() > 0.1
