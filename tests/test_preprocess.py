"""Finding the swatch beside the chart, large frames, and images refused from their header."""
import struct
import time
import zlib

import cv2
import numpy as np
import pytest

from hairdigi.inference.preprocess import (MAX_IMAGE_PIXELS, ImageError, Roi, find_swatch_roi, image_size, read_image,
                                           swatch_crop)
from deadlines import within

SIM = (200, 150)   # a small rig frame (the rig's is 400 x 300): the same view, a quarter of the pixels


def flat_png(path, width: int, height: int, rgb=(120, 80, 40), rows: int = 50) -> None:
    """A valid one-colour RGB PNG of any size, made without holding its pixels: one deflate block
    (from a reset dictionary) repeated, then the checksum of the whole."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    assert height % rows == 0
    block = (b"\x00" + bytes(rgb) * width) * rows
    c = zlib.compressobj(9)
    first = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH)
    again = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH)
    adler = 1
    for _ in range(height // rows):
        adler = zlib.adler32(block, adler)
    idat = first + again * (height // rows - 1) + b"\x03\x00" + struct.pack(">I", adler)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", idat) + chunk(b"IEND", b""))


def chart_positions() -> list[tuple[float, float]]:
    """Chart centres the rig allows: the whole chart on the holder, in view, right of the swatch
    (the view is RIG_HALF_WIDTH either side of RIG_TARGET, 4:3), at its corners, edges and default."""
    from hairdigi.render.domain import rig_geometry
    from hairdigi.render.strands import SWATCH_WIDTH

    pitch = rig_geometry.CHART_PATCH + rig_geometry.CHART_GAP
    half_w, half_h = 3 * pitch + rig_geometry.CHART_GAP, 2 * pitch + rig_geometry.CHART_GAP   # the board
    view_x = rig_geometry.RIG_TARGET[0] + rig_geometry.RIG_HALF_WIDTH
    view_y = rig_geometry.RIG_HALF_WIDTH * SIM[1] / SIM[0]
    x_lo, x_hi = SWATCH_WIDTH / 2 + 0.02 + half_w, view_x - 0.02 - half_w
    y_hi = view_y - 0.02 - half_h
    return [rig_geometry.CHART_CENTER] + [(x, y) for x in (x_lo, x_hi) for y in (-y_hi, 0.0, y_hi)]


def chart_box(center, size=SIM) -> tuple[int, int, int, int]:
    """The chart board's pixel box (x, y, w, h) in the rig view."""
    from hairdigi.render.domain import rig_geometry

    pitch = rig_geometry.CHART_PATCH + rig_geometry.CHART_GAP
    half_w, half_h = 3 * pitch + rig_geometry.CHART_GAP, 2 * pitch + rig_geometry.CHART_GAP
    (x0, x1), (y0, y1) = rig_geometry.rig_pixel(np.array([center[0] - half_w, center[0] + half_w]),
                                          np.array([center[1] + half_h, center[1] - half_h]), size)
    return int(x0), int(y0), int(x1 - x0), int(y1 - y0)


def overlap(a, b) -> int:
    """Pixels shared by two (x, y, w, h) boxes."""
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    return ix * iy


@pytest.fixture(scope="module")
def rig_frames():
    """{chart centre: simulated rig frame (8-bit sRGB through the camera model)}, tiny renders."""
    from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN
    from hairdigi.render.camera_model import spread_glints
    from hairdigi.render.domain import rig_geometry
    from hairdigi.render.camera_model import CameraModel, sensor_response
    from hairdigi.render.chart import colorchecker_reflectances
    from hairdigi.render.renderer import Renderer, SceneSpec

    renderer = Renderer(max_cached=1)
    chart = tuple(map(tuple, colorchecker_reflectances()))
    rng = np.random.default_rng(0)
    frames = {}
    for centre in chart_positions():
        spec = SceneSpec("swatch", framing="rig", chart=chart, target=rig_geometry.RIG_TARGET,
                         half_width=rig_geometry.RIG_HALF_WIDTH, chart_center=centre)
        linear = spread_glints(renderer.render(DEFAULT_HIDDEN, spec, SIM, 4, seed=1).linear)
        frames[centre] = sensor_response(linear, CameraModel(), rng)
    return frames


def test_chart_positions_cover_the_rig():
    from hairdigi.render.domain.rig_geometry import swatch_roi

    positions = chart_positions()
    assert len(positions) == 7 and len(set(positions)) == 7
    for centre in positions:   # each chart lies wholly in the frame and clear of the swatch
        x, y, w, h = chart_box(centre)
        assert 0 <= x and x + w <= SIM[0] and 0 <= y and y + h <= SIM[1], centre
        assert overlap((x, y, w, h), swatch_roi(SIM)) == 0


def test_the_swatch_is_found_beside_the_chart_wherever_the_chart_is(rig_frames):
    from hairdigi.render.domain.rig_geometry import swatch_roi

    truth = swatch_roi(SIM)
    for centre, frame in rig_frames.items():
        roi = find_swatch_roi(frame)
        box = (roi.x, roi.y, roi.w, roi.h)
        shared = overlap(box, truth)
        iou = shared / (roi.w * roi.h + truth[2] * truth[3] - shared)
        chart = chart_box(centre)
        assert shared >= 0.9 * truth[2] * truth[3] and iou >= 0.5, (centre, roi, truth)
        assert overlap(box, chart) <= 0.05 * chart[2] * chart[3], (centre, roi, chart)
        crop, _ = swatch_crop(frame)
        assert crop.shape[0] == crop.shape[1] >= 32


def test_a_large_frame_is_searched_scaled_down(rig_frames):
    frame = rig_frames[chart_positions()[0]]
    small = find_swatch_roi(frame)
    factor = 20                                   # 4000 x 3000, as a camera still
    big = cv2.resize(frame, None, fx=factor, fy=factor, interpolation=cv2.INTER_NEAREST)
    start = time.perf_counter()
    roi = find_swatch_roi(big)
    seconds = time.perf_counter() - start
    expected = np.array([small.x, small.y, small.w, small.h]) * factor
    assert np.all(np.abs(np.array([roi.x, roi.y, roi.w, roi.h]) - expected) <= 0.06 * expected.max()), (roi, expected)
    assert seconds < within(10), seconds                  # it took minutes when the frame was searched whole


def test_all_hair_and_flat_noise_keep_the_whole_image():
    noise = np.random.default_rng(0).integers(0, 255, (64, 64, 3), np.uint8)
    assert find_swatch_roi(noise) == Roi(0, 0, 64, 64)


def test_image_size_is_read_from_the_header(tmp_path):
    img = np.random.default_rng(0).integers(0, 255, (30, 70, 3), np.uint8)
    for ext in (".png", ".jpg", ".tiff", ".bmp", ".webp"):
        ok, data = cv2.imencode(ext, img)
        assert ok and image_size(data.tobytes()) == (70, 30), ext
    assert image_size(b"not an image") is None


def test_a_huge_image_is_refused_from_its_header_quickly(tmp_path):
    path = tmp_path / "huge.png"
    flat_png(path, 20000, 20000)                 # 1.2 MB on disk, 1.2 GB decoded
    assert path.stat().st_size < 2_000_000
    start = time.perf_counter()
    with pytest.raises(ImageError, match="20000x20000 px is more than hairdigi decodes"):
        read_image(path)
    assert time.perf_counter() - start < within(1.0)
    assert 6000 * 4000 <= MAX_IMAGE_PIXELS < 20000 * 20000   # a camera still is read; this is not


def test_other_formats_are_sized_from_their_header_too(tmp_path):
    def bmp_header(width, height):   # a BMP's 54-byte header alone: enough to read the size
        return (b"BM" + struct.pack("<IHHI", 54 + width * height * 3, 0, 0, 54)
                + struct.pack("<IiiHHIIiiII", 40, width, height, 1, 24, 0, width * height * 3, 2835, 2835, 0, 0))
    (tmp_path / "big.bmp").write_bytes(bmp_header(10000, 10000))     # 100 MP: over the cap
    with pytest.raises(ImageError, match="10000x10000 px is more than hairdigi decodes"):
        read_image(tmp_path / "big.bmp")
    (tmp_path / "bomb.bmp").write_bytes(bmp_header(20000, 20000))    # 400 MP: Pillow's bomb
    with pytest.raises(ImageError, match="bomb.bmp: the image is larger than .* more than hairdigi decodes"):
        read_image(tmp_path / "bomb.bmp")


def test_read_image_errors_name_the_file_and_the_fix(tmp_path):
    with pytest.raises(ImageError, match="is a folder"):
        read_image(tmp_path)
    with pytest.raises(ImageError, match="no such file"):
        read_image(tmp_path / "none.png")
    (tmp_path / "x.png").write_bytes(b"")
    with pytest.raises(ImageError, match="empty"):
        read_image(tmp_path / "x.png")
    flat_png(tmp_path / "ok.png", 64, 50)
    assert read_image(tmp_path / "ok.png").shape == (50, 64, 3)
