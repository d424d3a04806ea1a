"""Media the tests write for the real readers: videos (MJPG through OpenCV, which ``cv2.VideoCapture``
replays like a camera). RAW stills come from ``hairdigi.hardware.sim_still.write_raw_still``."""
import cv2
import numpy as np


def write_video(path, frames: int = 5, size=(64, 48), step: int = 40, fps: int = 10):
    """A video of ``frames`` flat grey frames, ``step`` levels apart, of ``size`` (width, height)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, size)
    assert writer.isOpened()
    for i in range(frames):
        writer.write(np.full((size[1], size[0], 3), step * i, np.uint8))
    writer.release()
    return path


def chart_profile(matrix):
    """A calibration profile whose chart correction is ``matrix`` (no measured patches)."""
    from hairdigi.render.domain.records import CalibrationProfile

    return CalibrationProfile(id="t", method="Finlayson 2015", matrix=tuple(map(tuple, matrix)), time=1.7e9)
