"""The camera's one owner: reads never overlap, handed-out frames are fresh, failures are reported."""
import threading
import time

import pytest
from media import write_video

from hairdigi.hardware.cameras import CameraError, FileCamera
from hairdigi.hardware.frame_source import FrameSource


class WatchedCamera(FileCamera):
    """A real file camera that records how many reads run at once (a driver that is not thread-safe)."""

    def __init__(self, path, **kw) -> None:
        super().__init__(path, **kw)
        self.inside = 0
        self.most_inside = 0
        self.reads = 0
        self._count = threading.Lock()

    def read(self):
        with self._count:
            self.inside += 1
            self.most_inside = max(self.most_inside, self.inside)
        try:
            time.sleep(0.002)            # a driver's exposure: room for another thread to come in
            frame = super().read()
            self.reads += 1
            return frame
        finally:
            with self._count:
                self.inside -= 1


@pytest.fixture
def video(tmp_path):
    return write_video(tmp_path / "feed.avi", frames=30, size=(32, 24), step=8, fps=30)


def test_the_feed_and_three_workers_never_read_the_camera_at_once(video):
    camera = WatchedCamera(video)
    source = FrameSource(camera, fps=200)
    seen = []
    unsubscribe = source.subscribe(seen.append)
    got, errors = [], []

    def worker():
        try:
            for _ in range(10):
                asked = time.time()
                frame = source.next_frame(timeout=5)
                got.append(frame.time >= asked)
        except Exception as exc:   # surfaced below
            errors.append(exc)

    threads = [threading.Thread(target=worker) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    unsubscribe()
    assert not errors
    assert camera.most_inside == 1                     # one read at a time, whoever asked
    assert len(got) == 30 and all(got)                 # every frame handed out was taken after the ask
    assert len(seen) >= 10 and source.frames_read == camera.reads
    assert not source.running                          # the feed stops with its last subscriber
    source.close()


def test_a_reader_does_not_wait_out_a_slow_feeds_period(video):
    """With the feed at one frame in 20 s, four fresh frames (a capture's single-light frames and its frame) come
    at once: the waiting reader wakes the feed, which then keeps its own pace."""
    camera = WatchedCamera(video)
    source = FrameSource(camera, fps=0.05)
    seen = []
    unsubscribe = source.subscribe(seen.append)
    try:
        start = time.monotonic()
        frames = [source.next_frame(timeout=30) for _ in range(4)]
        took = time.monotonic() - start
        assert took < 10.0, took                       # one period alone would be 20 s; four, 80 s
        assert [f.meta["frame"] for f in frames] == sorted({f.meta["frame"] for f in frames})   # four fresh frames
        assert camera.most_inside == 1 and source.running
    finally:
        unsubscribe()
        source.close()


def test_without_a_feed_next_frame_reads_on_the_callers_thread(video):
    source = FrameSource(WatchedCamera(video))
    first, second = source.next_frame(), source.next_frame()
    assert not source.running and source.frames_read == 2
    assert first.meta["frame"] + 1 == second.meta["frame"]
    assert source.latest() is second
    source.close()


def test_a_camera_that_stops_is_reported_to_the_feed_and_to_next_frame(video):
    source = FrameSource(FileCamera(video, loop=False), fps=500)
    failures = []
    done = threading.Event()
    source.subscribe(lambda frame: None, lambda message: (failures.append(message), done.set()))
    assert done.wait(10)
    assert "no more frames" in failures[0]
    with pytest.raises(CameraError, match="no more frames"):
        source.next_frame(timeout=1)
    source.close()
