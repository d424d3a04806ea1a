"""Strand geometry: the swatch, the procedural hairstyles on the head, and the head itself."""
from dataclasses import replace

import numpy as np
import pytest

from hairdigi.render import head
from hairdigi.render.strands import HAIRSTYLES, STYLES, Strands, grow, hairstyle_strands, swatch_strands

N = 300


@pytest.fixture(scope="module")
def styles():
    return {style: hairstyle_strands(style, N, seed=3) for style in HAIRSTYLES}


def test_swatch_is_deterministic_and_lies_on_the_holder():
    a, b, c = swatch_strands(300, seed=1), swatch_strands(300, seed=1), swatch_strands(300, seed=2)
    assert np.array_equal(a.points, b.points) and not np.array_equal(a.points, c.points)
    z = a.points[:, 2]
    assert z.min() >= a.radii.min() and z.max() < 0.1
    assert np.abs(a.points[:, 0]).max() < 0.52 and a.n_strands == 300


@pytest.mark.parametrize("style", HAIRSTYLES)
def test_hairstyles_root_on_the_scalp_and_stay_out_of_the_head(style, styles):
    s = styles[style]
    assert s.n_strands == N and np.all(s.counts >= 4) and np.all(np.isfinite(s.points))
    assert np.array_equal(s.points, hairstyle_strands(style, N, seed=3).points)          # deterministic
    # the curve Mitsuba draws starts on the scalp, above the hairline
    roots = s.curves(1).points[s.curves(1).starts()]
    assert np.abs(head.sdf(roots)).max() < 0.01
    assert head.hairline_margin(roots).min() > 0
    # its centre line never enters the bust, and past the first 0.1 units the tube clears it
    curves = s.curves(3)
    d = head.sdf(curves.points)
    seg = np.r_[0.0, np.linalg.norm(np.diff(curves.points, axis=0), axis=1)]
    seg[curves.starts()] = 0.0
    arc = np.cumsum(seg) - np.repeat(np.cumsum(seg)[curves.starts()], curves.counts)
    assert d.min() > 0
    assert np.quantile(d[arc > 0.1], 0.999) > 0 and (d[arc > 0.1] < 0.5 * s.radii[0]).mean() < 1e-3


def test_the_part_is_bare(styles):
    for style in ("straight", "wavy", "bob", "curly"):
        part_x = STYLES[style].part_x
        roots = styles[style].curves(1).points[styles[style].curves(1).starts()]
        assert not head.in_parting(roots, part_x).any(), style
        # roots crowd both sides of the part
        near = (np.abs(roots[:, 0] - part_x) < 0.15) & (roots[:, 2] > 0) & (roots[:, 1] > 0.5)
        assert (roots[near, 0] < part_x).sum() > 2 and (roots[near, 0] > part_x).sum() > 2, style


def _tip_spacing(strands: Strands) -> float:
    tips = strands.points[strands.starts() + strands.counts - 2]   # the last point before the mirrored end
    d = np.linalg.norm(tips[:, None] - tips[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    return float(d.min(axis=1).mean())


@pytest.mark.parametrize("style, ratio", [("straight", 0.9), ("curly", 0.92)])
def test_clumping_gathers_the_tips(style, ratio):
    clumped = grow(STYLES[style], 600, seed=1)
    loose = grow(replace(STYLES[style], clump=0.0), 600, seed=1)
    assert _tip_spacing(clumped) < ratio * _tip_spacing(loose)


def test_lengths_vary_per_strand(styles):
    for style in ("straight", "curly"):
        curves = styles[style].curves(2)
        seg = np.r_[0.0, np.linalg.norm(np.diff(curves.points, axis=0), axis=1)]
        seg[curves.starts()] = 0.0
        lengths = np.add.reduceat(seg, curves.starts())
        assert lengths.std() / lengths.mean() > 0.04, style


def test_the_afro_has_volume(styles):
    afro, straight = styles["afro"].points, styles["straight"].points
    assert np.ptp(afro[:, 0]) > np.ptp(straight[:, 0]) + 0.4
    assert afro[:, 1].max() > straight[:, 1].max() + 0.4          # it stands up off the crown


def test_curls_coil(styles):
    """Curly and afro strands turn round and round: their path is much longer than root-to-tip."""
    for style, ratio in (("curly", 1.3), ("afro", 1.6), ("straight", 0.0)):
        curves = styles[style].curves(2)
        seg = np.r_[0.0, np.linalg.norm(np.diff(curves.points, axis=0), axis=1)]
        seg[curves.starts()] = 0.0
        path = np.add.reduceat(seg, curves.starts())
        ends = curves.starts() + curves.counts - 1
        chord = np.linalg.norm(curves.points[ends] - curves.points[curves.starts()], axis=1)
        if ratio:
            assert np.median(path / chord) > ratio, style
        else:
            assert np.median(path / chord) < 1.3


def test_unknown_hairstyle_names_the_choices():
    with pytest.raises(ValueError, match="unknown hairstyle 'mohawk'.*straight.*afro"):
        hairstyle_strands("mohawk")


def test_segments_and_dummy_strand():
    s = swatch_strands(10, seed=0, points_per_strand=6)
    assert len(s.segment_indices()) == 10 * 3
    assert s.segment_indices()[3] == 6  # second strand's first segment starts at its first point
    d = s.with_dummy()
    assert d.n_strands == 11 and d.points[-1, 2] < -1000 and d.radii[-1] < 1e-4
    assert d.control_points().shape == (4 * len(d.points),)


def test_curve_text_has_a_blank_line_between_strands():
    text = swatch_strands(3, seed=0, points_per_strand=5).to_curve_text()
    blocks = [b for b in text.split("\n\n") if b.strip()]
    assert len(blocks) == 3 and all(len(b.strip().splitlines()) == 5 for b in blocks)


def test_through_ends_makes_the_curve_start_and_end_on_the_polyline():
    lines = Strands(np.random.default_rng(0).normal(size=(9, 3)).astype(np.float32), np.ones(9, np.float32),
                    np.array([2, 3, 4]))
    curves = lines.through_ends().curves(4)
    for line, curve in zip(lines.polylines(), curves.polylines()):
        assert np.allclose(curve[0], line[0], atol=1e-5) and np.allclose(curve[-1], line[-1], atol=1e-5)
    subset = lines.subset([2, 0])
    assert np.array_equal(subset.counts, [4, 2]) and np.array_equal(subset.polylines()[1], lines.polylines()[0])


def test_the_head_is_a_closed_outward_mesh_with_ears_neck_and_shoulders():
    mesh = head.head_mesh()
    faces = mesh.faces.astype(np.int64)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert (uses == 2).mean() > 0.999                                        # closed
    tri = mesh.vertices[faces].astype(float)
    assert np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6 > 5   # outward, bust-sized
    off = np.abs(head.sdf(mesh.vertices))
    assert np.quantile(off, 0.999) < 1e-3 and off.max() < 0.01                 # on the surface (bar the cut)
    v = mesh.vertices
    ears = (np.abs(v[:, 0]) > 0.85) & (np.abs(v[:, 1] + 0.3) < 0.2)
    assert ears.sum() > 20                                                   # ears stick out of the skull
    assert np.ptp(v[:, 0]) > 3.5 and v[:, 1].min() < -3.0                    # shoulders
    skin, scalp = head.split_scalp(mesh, part_x=0.3)
    assert len(skin.faces) + len(scalp.faces) == len(mesh.faces) and len(scalp.faces) > 1000
    assert len(head.ply_bytes(mesh)) < 2_000_000
