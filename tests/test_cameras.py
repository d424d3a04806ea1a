"""Camera backends on real files: a DNG written here and read by rawpy, a video written by OpenCV."""
import cv2
import numpy as np
import pytest

from hairdigi.hardware.cameras import CameraError, FileCamera, OpenCVCamera, read_raw
from hairdigi.hardware.sim_still import write_raw_still
from media import write_video


def write_dng(path, width=64, height=48, level=(0.25, 0.5, 0.125)):
    return write_raw_still(path, np.broadcast_to(np.asarray(level, float), (height, width, 3)))


def test_dng_written_here_reads_back_linear(tmp_path):
    path = write_dng(tmp_path / "still.dng")
    frame = read_raw(path)
    h, w, _ = frame.linear.shape
    centre = frame.linear[h // 4: 3 * h // 4, w // 4: 3 * w // 4].reshape(-1, 3).mean(0)
    # linear camera RGB: the Bayer levels come back as written
    assert centre == pytest.approx([0.25, 0.5, 0.125], abs=0.01)
    assert frame.srgb.dtype == np.uint8 and frame.meta["white_level"] == 4095
    assert path.read_bytes()[:2] in (b"II", b"MM")  # the file is kept as written


def test_broken_raw_is_a_clear_error(tmp_path):
    (tmp_path / "bad.dng").write_bytes(b"II*\x00garbage")
    with pytest.raises(CameraError, match="rawpy cannot read"):
        read_raw(tmp_path / "bad.dng")


def test_video_file_replays_and_loops(tmp_path):
    path = str(write_video(tmp_path / "session.avi"))
    cam = FileCamera(path)
    levels = [cam.read().srgb.mean() for _ in range(7)]
    cam.close()
    assert levels[1] > levels[0] + 20 and levels[4] > levels[3]
    assert abs(levels[5] - levels[0]) < 5  # looped back to the first frame


def test_image_file_camera_and_missing_devices(tmp_path):
    cv2.imwrite(str(tmp_path / "f.png"), np.full((20, 30, 3), (10, 20, 30), np.uint8))
    frame = FileCamera(tmp_path / "f.png").read()
    assert frame.srgb.shape == (20, 30, 3) and tuple(frame.srgb[0, 0]) == (30, 20, 10)
    with pytest.raises(CameraError, match="no such"):
        FileCamera(tmp_path / "none.mp4")
    with pytest.raises(CameraError, match="--sim"):
        OpenCVCamera(9)  # no camera on a CI machine
