"""The layered swatch: fibres that never meet, optically thick, full length, and darker
than today's interpenetrating swatch at equal sigma_a (resources/models/swatch-structure.md)."""
from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest
from scipy.spatial import cKDTree

from hairdigi.render.domain.bounds import SwatchModel
from hairdigi.render.strands import SWATCH_LENGTH, SWATCH_WIDTH, Strands, layered_swatch_strands, swatch_strands
from deadlines import within


def closest_fibres(strands: Strands, per_segment: int = 16) -> float:
    """Least distance between points of two different fibres' centre lines, the curves sampled as
    Mitsuba draws them (16 samples a segment: closer than a fibre's diameter along y); a diameter
    (2 radii) when no two are closer than that."""
    curves = strands.curves(per_segment)
    owner = np.repeat(np.arange(curves.n_strands), curves.counts)
    tree = cKDTree(curves.points.astype(float))
    reach = 2 * float(strands.radii.max())   # pairs closer than a diameter: none means the fibres never meet
    pairs = tree.query_pairs(reach, output_type="ndarray")
    pairs = pairs[owner[pairs[:, 0]] != owner[pairs[:, 1]]]
    if len(pairs) == 0:
        return reach
    p = curves.points.astype(float)
    return float(np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=1).min())


@pytest.mark.parametrize("n, seed", [(2000, 0), (4000, 3)])
def test_layered_fibres_never_meet(n: int, seed: int) -> None:
    strands = layered_swatch_strands(n, seed=seed)
    radius = float(strands.radii.max())
    assert closest_fibres(strands) >= 2 * radius * 0.999


def test_the_check_finds_todays_interpenetration() -> None:
    """The same check fails on today's swatch, whose fibres pass through one another."""
    strands = swatch_strands(2000, seed=0)
    assert closest_fibres(strands) < 0.5 * float(strands.radii.max())


def test_layered_swatch_spans_the_holder_and_builds_fast() -> None:
    start = time.perf_counter()
    strands = layered_swatch_strands(8000, seed=1)
    assert time.perf_counter() - start < within(1.0)
    assert strands.n_strands == 8000
    drawn = strands.curves(4).points   # what Mitsuba draws, through_ends honoured
    assert drawn[:, 1].min() == pytest.approx(-SWATCH_LENGTH / 2, abs=1e-4)
    assert drawn[:, 1].max() == pytest.approx(SWATCH_LENGTH / 2, abs=1e-4)
    assert drawn[:, 0].min() < -SWATCH_WIDTH / 2 + 0.02 and drawn[:, 0].max() > SWATCH_WIDTH / 2 - 0.02
    assert drawn[:, 2].min() >= strands.radii.max()   # on the holder, not in it


def test_layered_swatch_covers_the_holder() -> None:
    """Optically thick: seen straight down, no holder shows between the fibres (a single layer does)."""
    from hairdigi.app.evaluation.bench_structure import uncovered_fraction

    assert uncovered_fraction(layered_swatch_strands(2000, seed=0)) == 0.0
    assert uncovered_fraction(layered_swatch_strands(100, seed=0)) > 0.1


def test_too_few_layers_is_refused() -> None:
    with pytest.raises(ValueError, match="layers"):
        layered_swatch_strands(2000, layers=5)


def test_swatch_model_is_validated() -> None:
    from hairdigi.render.renderer import SceneSpec

    with pytest.raises(ValueError, match="swatch_model"):
        SceneSpec("swatch", swatch_model="dense")
    assert SceneSpec("swatch").swatch_model is SwatchModel.LAYERED          # the default since the layered swatch
    assert SceneSpec("wavy").swatch_model is None                   # a hairstyle has no swatch model
    with pytest.raises(ValueError, match="swatch scene only"):
        SceneSpec("wavy", swatch_model="layered")


def test_layered_swatch_renders_darker_than_todays_at_equal_sigma_a() -> None:
    """At the rig's swatch region and brown sigma_a, today's interpenetrating swatch lets light out
    through its fibres: the layered swatch is measured about 2.5 L* darker (the bench), far beyond
    the noise at these settings (about 0.1)."""
    from hairdigi.app.evaluation.bench_structure import rig_spec
    from hairdigi.render.metrics import linear_rgb_to_lab
    from hairdigi.render.renderer import Renderer

    spec, film = rig_spec(size=32)
    renderer = Renderer(max_cached=2)
    sigma = np.array([0.35, 0.6, 1.2])
    lightness = {}
    for model, strands in (("today", 2000), ("layered", None)):   # each at its own strand count
        image = renderer.render(sigma, dataclasses.replace(spec, swatch_model=model, strands=strands), film, 32,
                                seed=5).linear
        lightness[model] = float(linear_rgb_to_lab(image.reshape(-1, 3).mean(0))[0])
    # 32² at 32 spp reads about 6 L* (the bench's 48² at 64 spp: 2.6); either way far beyond noise
    assert 1.0 < lightness["today"] - lightness["layered"] < 8.0
