import numpy as np
import pytest

from hairdigi.render.hairfile import HairFileError, read_hair, write_hair
from hairdigi.render.strands import HAIRSTYLES, HEAD_RADIUS, hairstyle_strands, swatch_strands


def test_swatch_is_deterministic_and_lies_on_the_holder():
    a, b, c = swatch_strands(300, seed=1), swatch_strands(300, seed=1), swatch_strands(300, seed=2)
    assert np.array_equal(a.points, b.points) and not np.array_equal(a.points, c.points)
    z = a.points[:, 2]
    assert z.min() >= a.radii.min() and z.max() < 0.1
    assert np.abs(a.points[:, 0]).max() < 0.52 and a.n_strands == 300


@pytest.mark.parametrize("style", HAIRSTYLES)
def test_hairstyles_grow_outside_the_head(style):
    s = hairstyle_strands(style, 200, seed=3)
    assert s.n_strands == 200 and np.all(s.counts >= 4)
    assert np.all(np.isfinite(s.points))
    assert np.linalg.norm(s.points, axis=1).min() >= HEAD_RADIUS  # nothing inside the head proxy
    assert np.array_equal(s.points, hairstyle_strands(style, 200, seed=3).points)


def test_unknown_hairstyle_names_the_choices():
    with pytest.raises(ValueError, match="unknown hairstyle 'mohawk'.*straight"):
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


def test_hair_file_round_trip(tmp_path):
    s = hairstyle_strands("bob", 50, seed=0)
    path = write_hair(tmp_path / "bob.hair", s)
    raw = path.read_bytes()
    assert raw[:4] == b"HAIR" and len(raw) == 128 + 2 * 50 + 16 * len(s.points)
    back = read_hair(path)
    assert np.array_equal(back.counts, s.counts)
    assert np.allclose(back.points, s.points) and np.allclose(back.radii, s.radii)


def test_hair_file_drops_short_strands_and_uses_defaults(tmp_path):
    import struct
    # 2 strands (segments 2 and 4: 3 and 5 points), no thickness array: default diameter 0.02
    header = struct.pack("<4sIIIIff3f88s", b"HAIR", 2, 8, 0b11, 0, 0.02, 0, 0, 0, 0, b"")
    pts = np.arange(24, dtype="<f4")
    (tmp_path / "h.hair").write_bytes(header + np.array([2, 4], "<u2").tobytes() + pts.tobytes())
    s = read_hair(tmp_path / "h.hair")
    assert s.n_strands == 1 and len(s.points) == 5 and np.allclose(s.radii, 0.01)


def test_bad_hair_files(tmp_path):
    (tmp_path / "a.hair").write_bytes(b"NOPE" + bytes(124))
    with pytest.raises(HairFileError, match="not a .hair file"):
        read_hair(tmp_path / "a.hair")
    s = swatch_strands(5, seed=0)
    raw = write_hair(tmp_path / "b.hair", s).read_bytes()
    (tmp_path / "b.hair").write_bytes(raw[:-10])
    with pytest.raises(HairFileError, match="truncated"):
        read_hair(tmp_path / "b.hair")
    (tmp_path / "c.hair").write_bytes(b"HAIR")
    with pytest.raises(HairFileError, match="too short"):
        read_hair(tmp_path / "c.hair")
