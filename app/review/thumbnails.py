"""The session list's thumbnails: a capture's small picture, read off the UI thread."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from hairdigi.app.models.work import Work
from hairdigi.app.review.payloads import Entry, Thumbnail
from hairdigi.render.domain.session_folder import SessionFolder


def read_thumbnail(folder: Path, entry: Entry, size=(64, 48)) -> np.ndarray | None:
    """A small RGB picture of a capture, or None when its image is missing."""
    path = SessionFolder(folder).image(entry.record.capture or "")
    img = cv2.imread(str(path)) if path.is_file() else None
    return None if img is None else cv2.resize(img[..., ::-1], size)


def thumbnail_work(folder: Path, entries: list[Entry]) -> Work | None:
    """Read the thumbnails of ``entries``, one :class:`Thumbnail` each; None when there are none."""
    if not entries:
        return None

    def run():
        for entry in entries:
            yield Thumbnail(entry.id, read_thumbnail(folder, entry))
    return Work("thumbnails", run)
