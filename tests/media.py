"""Media the tests write for the real readers: RAW stills (a linear Bayer DNG, RGGB, 12-bit in 16,
written with tifffile's CFA and DNG tags, which rawpy reads like a camera's file) and videos (MJPG
through OpenCV, which ``cv2.VideoCapture`` replays like a camera)."""
import cv2
import numpy as np

WHITE = 4095


def write_raw_still(path, linear: np.ndarray):
    """Mosaic an (H, W, 3) linear image in [0, 1] (even H and W) onto an RGGB sensor and write it as DNG."""
    import tifffile

    linear = np.clip(np.asarray(linear, float), 0.0, 1.0)
    cfa = np.empty(linear.shape[:2], np.uint16)
    counts = np.round(linear * WHITE).astype(np.uint16)
    cfa[0::2, 0::2] = counts[0::2, 0::2, 0]
    cfa[0::2, 1::2] = counts[0::2, 1::2, 1]
    cfa[1::2, 0::2] = counts[1::2, 0::2, 1]
    cfa[1::2, 1::2] = counts[1::2, 1::2, 2]
    identity = [(1, 1), (0, 1), (0, 1), (0, 1), (1, 1), (0, 1), (0, 1), (0, 1), (1, 1)]
    tags = [
        (50706, "B", 4, (1, 4, 0, 0), True),          # DNGVersion
        (50707, "B", 4, (1, 1, 0, 0), True),          # DNGBackwardVersion
        (50708, "s", 0, "hairdigi test camera", True),  # UniqueCameraModel
        (33421, "H", 2, (2, 2), True),                # CFARepeatPatternDim
        (33422, "B", 4, (0, 1, 1, 2), True),          # CFAPattern: RGGB
        (50714, "H", 1, 0, True),                     # BlackLevel
        (50717, "H", 1, WHITE, True),                 # WhiteLevel
        (50721, "2i", 9, [v for pair in identity for v in pair], True),  # ColorMatrix1 (SRATIONAL)
        (50778, "H", 1, 21, True),                    # CalibrationIlluminant1: D65
        (50728, "2I", 3, (1, 1, 1, 1, 1, 1), True),   # AsShotNeutral
    ]
    tifffile.imwrite(path, cfa, photometric=32803, extratags=tags, subfiletype=0)
    return path


def write_video(path, frames: int = 5, size=(64, 48), step: int = 40, fps: int = 10):
    """A video of ``frames`` flat grey frames, ``step`` levels apart, of ``size`` (width, height)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, size)
    assert writer.isOpened()
    for i in range(frames):
        writer.write(np.full((size[1], size[0], 3), step * i, np.uint8))
    writer.release()
    return path
