"""The shipped atlas (``inference.atlas``): any swatch region of the bench camera's frame answered from cells, so
the first estimate in a fresh session renders no table; and the twin rendered on the structure the estimate
was read on."""
import os

import numpy as np
import pytest

from hairdigi.inference import atlas as A
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE, CameraPose, RigRegion, swatch_roi


def _pattern() -> A.Atlas:
    """An atlas whose cell (k, r, c) holds 1000 k + 100 r + c: a region's mean names the cells it took."""
    k, r, c = np.meshgrid(np.arange(12), np.arange(A.BOX[3] // A.CURVE_CELL), np.arange(A.BOX[2] // A.CURVE_CELL),
                          indexing="ij")
    return A.Atlas(np.linspace(0, 1, 12), np.zeros(8), {("layered", 0): 1000.0 * k + 100.0 * r + c}, {}, {})


def test_a_regions_means_are_its_cells_on_any_frame_of_the_bench_camera():
    """A region is snapped to the nearest cell lines of the canonical frame: the feed's frame, a RAW still of
    twice its size and a 16:9 frame of the same field (the horizontal field fixed, the height centred) take
    the same cells; a region leaving the atlas, another camera and an all-hair crop's pose take none."""
    atlas = _pattern()
    live = atlas.curve(RigRegion((400, 300), (30, 56, 130, 189)), "layered", 0)
    # x 30..160 -> cells 4..19 (3.75 rounds to 4); y 56..245 -> 40..229 in the box -> cells 5..28 (28.6 -> 29)
    assert np.allclose(live, 1000.0 * np.arange(12) + 100.0 * (5 + 28) / 2 + (4 + 19) / 2)
    assert np.allclose(atlas.curve(RigRegion((800, 600), (60, 112, 260, 378)), "layered", 0), live)
    assert np.allclose(atlas.curve(RigRegion((800, 450), (60, 37, 260, 378)), "layered", 0), live)
    assert atlas.curve(RigRegion((400, 300), (250, 56, 100, 100)), "layered", 0) is None     # past the atlas
    assert atlas.curve(RigRegion((400, 300), (30, 56, 130, 189), CameraPose(30.0, 0.0)), "layered", 0) is None
    assert atlas.curve(RIG_SWATCH_POSE, "layered", 0) is None
    assert atlas.curve(RigRegion((400, 300), (30, 56, 130, 189)), "spread", 0) is None       # not in it


def test_the_shipped_atlas_is_current_and_covers_the_rigs_region():
    """The shipped atlas was rendered from today's swatch geometry (a structure's revision, the strand count or
    the depth changed without a rebuild fails here: ``python -m hairdigi.inference.atlas_build``) and answers
    the simulated rig's region for every family member's layouts and every read member's shine."""
    from hairdigi.hardware.sim_rig import SIM_SIZE
    from hairdigi.inference.structure import FAMILY, LAYOUTS, READ_MEMBERS
    from hairdigi.render.renderer import default_renderer

    atlas = A.load()
    assert atlas is not None, f"no atlas at {A.ATLAS_PATH}"
    assert atlas.meta["fingerprint"] == A.fingerprint(default_renderer().variant)
    region = RigRegion(SIM_SIZE, swatch_roi(SIM_SIZE))
    for member in FAMILY:
        for layout in range(LAYOUTS):
            curve = atlas.curve(region, member, layout)
            # falling to the fibres' surface reflection, flat within the renders' noise past sigma_a 3
            assert curve is not None and curve[-1] < 0.1 * curve[0], (member, layout)
            assert np.all(np.diff(curve) < 0.05 * curve[:-1]), (member, layout)
    for member in READ_MEMBERS:
        tables = atlas.shine_means(region, member)
        assert tables is not None and tables.shape == (3, len(atlas.betas), len(atlas.levels)), member
        assert np.all(tables > 0), member


def test_an_atlas_curve_is_the_render_of_its_region(tmp_path, monkeypatch):
    """In a fresh cache the rig region's response curve comes from the atlas (no render, nothing written) and
    gives the hard cases' hairs the colours a render of that region gives, within the renders' noise (a render
    with another sampler seed lies 0.1-1.0 ΔE2000 from it at 32 spp: ``hairdigi bench atlas``)."""
    from hairdigi.hardware.sim_rig import SIM_SIZE
    from hairdigi.inference.refine import RefineSettings, response_curve

    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path / "cache"))
    region = RigRegion(SIM_SIZE, swatch_roi(SIM_SIZE))
    shipped = response_curve(region, RefineSettings())
    assert shipped.cached and shipped.seconds == 0.0 and not (tmp_path / "cache").exists()
    rendered = response_curve(region, RefineSettings(), cache=False)
    assert not rendered.cached and rendered.seconds > 0
    from hairdigi.app.evaluation.bench_atlas import HAIRS
    from hairdigi.render.metrics import delta_e2000

    apart = {name: float(delta_e2000(shipped(np.asarray(s)), rendered(np.asarray(s)))) for name, s in HAIRS.items()}
    assert max(apart.values()) < 1.5 and np.median(list(apart.values())) < 0.8, apart
    monkeypatch.setenv("HAIRDIGI_ATLAS", "off")                  # without it, the region is rendered
    assert not response_curve(region, RefineSettings()).cached


@pytest.mark.slow
def test_a_fresh_sessions_first_capture_of_a_deposited_swatch_renders_no_table_and_its_twin_matches(
        tmp_path, monkeypatch):
    """The default mode is the family's. A simulated rig with a deposited swatch, a fresh cache: the capture's
    estimate takes its curves and shine tables from the atlas (nothing rendered into the cache), and the twin,
    rendered as the review shows it (on the structure read, at the sigma_a fitted there), matches the capture
    where the family's answer drawn on hairdigi's layered swatch would not."""
    from hairdigi.app.review.payloads import Shown
    from hairdigi.app.review.previews import Stage, twin_view
    from hairdigi.app.session.rig_session import RigSession
    from hairdigi.inference.refine import fitted_pixels
    from hairdigi.render.domain.bounds import DEFAULT_STRUCTURE, StructureMode
    from hairdigi.render.domain.params import HairParams
    from hairdigi.render.metrics import mean_colour_delta_e
    from hairdigi.render.renderer import default_renderer

    assert DEFAULT_STRUCTURE is StructureMode.FAMILY
    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path / "cache"))
    session = RigSession.simulated_rig(tmp_path / "s", hidden=HairParams((200, 90, 50), 0.6, 0.35, 0.5), spp=16,
                                       swatch_model="deposited")
    try:
        session.calibrate()
        result = session.capture()
    finally:
        session.close()
    record = result.record
    assert record is not None and record.uncertainty.structure.mode is StructureMode.FAMILY
    assert not list((tmp_path / "cache").glob("response/*")), "a table was rendered"
    refinement = record.refinement
    frame = result.corrected
    region = refinement.region.rig
    real = fitted_pixels(frame, region)
    shown = Shown("c", real, region.roi, region.frame_size, record.hair, Stage.REFINED, record, True)
    renderer = default_renderer()
    spec, size = twin_view(region.roi, region.frame_size, True, 1.0, shown.appearance, None, shown.swatch_model)
    twin = renderer.render(shown.twin_hair, spec, size, 64, 3).linear
    assert mean_colour_delta_e(real, twin) <= 0.6, refinement
    if refinement.fitted_sigma_a is not None:          # mapped to the family's mean: the old twin was off
        old = renderer.render(record.hair, twin_view(region.roi, region.frame_size, True, 1.0, shown.appearance)[0],
                              size, 64, 3).linear
        assert mean_colour_delta_e(real, old) > mean_colour_delta_e(real, twin)


def test_a_missing_or_damaged_atlas_is_said_once_and_the_tables_are_rendered(tmp_path, monkeypatch):
    """``HAIRDIGI_ATLAS`` naming a file that is not there, or is not an atlas: nothing is answered from it, and a
    warning names the file and the fix (the estimate still runs, rendering its tables)."""
    bad = tmp_path / "atlas.npz"
    bad.write_bytes(b"not an atlas")
    for path in (tmp_path / "nowhere.npz", bad):
        monkeypatch.setenv("HAIRDIGI_ATLAS", str(path))
        with pytest.warns(UserWarning, match="missing or damaged.*atlas_build"):
            assert A.load() is None
        assert A.curve_means(RigRegion((400, 300), (30, 56, 130, 189)), np.linspace(0, 1, 12), 0, "layered",
                             "llvm_ad_rgb") is None



def _poses() -> A.PoseAtlas:
    """Pose tables whose every mean is exp(polar / 100 + azimuth / 1000) times the level's index + 1."""
    polars, azimuths = np.array(A.POSE_POLARS), np.array(A.POSE_AZIMUTHS)
    grid = np.exp(polars[:, None, None] / 100 + azimuths[None, :, None] / 1000) * np.arange(1, 13)[None, None, :]
    return A.PoseAtlas(np.linspace(0, 1, 12), polars, azimuths, {("layered", 0): grid}, {"distance": 4.0})


def test_a_crops_pose_reads_the_pose_tables_interpolated_and_mirrored():
    """A pose on a node reads it; between nodes the logs interpolate (so exp(polar / 100 + azimuth / 1000) comes
    back exactly); an azimuth past ±90° reads its mirror image across the holder's x = 0 plane (φ -> 180° - φ);
    steeper than the grid, at another distance, or a curve the tables lack: nothing (the caller renders)."""
    poses, k = _poses(), np.arange(1, 13)
    assert np.allclose(poses.curve(CameraPose(30.0, 45.0), "layered", 0), np.exp(0.3 + 0.045) * k)
    assert np.allclose(poses.curve(CameraPose(37.5, 22.5), "layered", 0), np.exp(0.375 + 0.0225) * k)
    assert np.allclose(poses.curve(CameraPose(30.0, 135.0), "layered", 0), poses.curve(CameraPose(30.0, 45.0),
                                                                                       "layered", 0))
    assert [A.mirrored_azimuth(a) for a in (135.0, -135.0, 180.0, 270.0, 90.0, -30.0, 390.0)] == \
        [45.0, -45.0, 0.0, -90.0, 90.0, -30.0, 30.0]
    assert poses.curve(CameraPose(80.0, 0.0), "layered", 0) is None
    assert poses.curve(CameraPose(30.0, 0.0, 6.0), "layered", 0) is None
    assert poses.curve(CameraPose(30.0, 0.0, 4.1), "layered", 0) is not None
    assert poses.curve(CameraPose(30.0, 0.0), "spread", 0) is None


def test_the_shipped_pose_tables_are_current_and_answer_a_crop_between_nodes_as_a_render_does(tmp_path,
                                                                                               monkeypatch):
    """The shipped pose tables were rendered from today's swatch geometry and settings (``python -m
    hairdigi.inference.atlas_build --poses-only`` rebuilds them); in a fresh cache a crop at a pose between their
    nodes reads its curve from them (no render, nothing written) and gives the hard cases the colours a render at
    that pose gives, within the renders' noise; other render settings, or ``HAIRDIGI_ATLAS=off``, render."""
    from dataclasses import replace

    from hairdigi.app.evaluation.bench_atlas import HAIRS
    from hairdigi.inference import atlas_build
    from hairdigi.inference.refine import RefineSettings, response_curve
    from hairdigi.inference.structure import FAMILY, LAYOUTS
    from hairdigi.render.metrics import delta_e2000
    from hairdigi.render.renderer import default_renderer

    poses = A.load_poses()
    assert poses is not None, f"no pose tables at {A.POSES_PATH}"
    assert poses.meta["fingerprint"] == A.fingerprint(default_renderer().variant)
    assert {(m, s) for m in FAMILY for s in range(LAYOUTS)} <= set(poses.curves)
    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("HAIRDIGI_ATLAS", raising=False)
    pose = CameraPose(52.5, -67.5)
    shipped = response_curve(pose, RefineSettings())
    assert shipped.cached and shipped.seconds == 0.0 and not (tmp_path / "cache").exists()
    with atlas_build.atlases_off():            # what a build ships is rendered, never read back from the tables
        rendered = response_curve(pose, RefineSettings())
    assert not rendered.cached and rendered.seconds > 0 and "HAIRDIGI_ATLAS" not in os.environ
    assert response_curve(pose, RefineSettings()).cached          # the render, now in the cache
    apart = {name: float(delta_e2000(shipped(np.asarray(s)), rendered(np.asarray(s)))) for name, s in HAIRS.items()}
    assert max(apart.values()) < 1.5 and np.median(list(apart.values())) < 0.8, apart
    assert A.curve_means(pose, shipped.sigma, 0, "layered", default_renderer().variant,
                         {**replace(RefineSettings(), size=32).__dict__}) is None
    monkeypatch.setenv("HAIRDIGI_ATLAS", "off")
    assert A.load_poses() is None


def test_estimate_says_when_a_pose_is_off_the_tables_before_the_wait(capsys):
    """``hairdigi estimate --camera``: a pose the tables answer starts at once, silently; a steeper one says that its
    curves render first (about a minute) before it starts."""
    from hairdigi.app.cli.estimate import say_pose_tables

    say_pose_tables(CameraPose(40.0, 30.0))
    assert capsys.readouterr().err == ""
    say_pose_tables(CameraPose(82.0, 30.0))
    said = capsys.readouterr().err
    assert "82°, 30°" in said and "up to 75°" in said and "render first" in said


def test_a_bench_session_is_fresh_and_leaves_the_environment_as_it_was(tmp_path, monkeypatch):
    """The atlas bench's end to end runs each estimate in a fresh cache with the atlas on or off, and puts the
    process's environment back after, even when the estimate fails."""
    from hairdigi.app.evaluation.bench_atlas import fresh_session

    monkeypatch.setenv("HAIRDIGI_CACHE", "/kept")
    monkeypatch.delenv("HAIRDIGI_ATLAS", raising=False)
    with pytest.raises(RuntimeError):
        with fresh_session(tmp_path / "c", "off"):
            assert (os.environ["HAIRDIGI_CACHE"], os.environ["HAIRDIGI_ATLAS"]) == (str(tmp_path / "c"), "off")
            assert A.load_poses() is None and A.load() is None
            raise RuntimeError("an estimate failed")
    assert os.environ["HAIRDIGI_CACHE"] == "/kept" and "HAIRDIGI_ATLAS" not in os.environ
