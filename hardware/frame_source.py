"""The one owner of the camera: every read goes through a :class:`FrameSource`.

Camera drivers are not thread-safe (``cv2.VideoCapture`` is not; the simulated rig advances one
random generator), yet the live feed, capture, calibration and the light check all want frames.
The source serialises every read under one lock and publishes each frame to its subscribers (the
window's feed). While someone subscribes, its thread reads at ``fps`` and ``next_frame`` waits for
the next frame from that thread, which it wakes to read at once (a capture's four frames do not wait out
the feed's period: 1.0 s of the app's capture at the busy feed's 4 frames a second); with no subscriber
(the command line), ``next_frame`` reads on the caller's thread. Either way a frame handed out by
``next_frame`` was exposed after the call began, so a capture taken just after switching a light sees the
light. A camera that fails stops the feed,
unless it can reopen itself (a GenICam camera's ``reconnect``): then the feed waits for it to come back.
"""
from __future__ import annotations

import threading
import time
from typing import Callable

from hairdigi.hardware.cameras import Camera, CameraError, Frame

Subscriber = Callable[[Frame], None]


class FrameSource:
    """Owns ``camera``: reads it, publishes the latest frame, and hands fresh frames to whoever asks."""

    def __init__(self, camera: Camera, fps: float = 20.0) -> None:
        self.camera = camera
        self.period = 1.0 / fps
        self._read_lock = threading.Lock()          # one read (or settings query) at a time
        self._published = threading.Condition()
        self._latest: Frame | None = None
        self._latest_started = 0.0                  # when the latest frame's read began
        self._subscribers: list[Subscriber] = []
        self._error_subscribers: list[Callable[[str], None]] = []
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._wake = threading.Event()              # set by a reader waiting for a fresh frame, and to stop
        self.error: str | None = None               # why the feed stopped, if it did
        self.frames_read = 0

    # -- reading -----------------------------------------------------------------------------
    def _read(self) -> Frame:
        started = time.monotonic()
        with self._read_lock:
            frame = self.camera.read()
        with self._published:
            self.frames_read += 1
            self._latest, self._latest_started = frame, started
            self._published.notify_all()
            subscribers = list(self._subscribers)
        for callback in subscribers:
            callback(frame)
        return frame

    def next_frame(self, timeout: float = 10.0) -> Frame:
        """A frame whose exposure began after this call: from the feed thread if it runs, else read now."""
        asked = time.monotonic()
        if not self.running:
            return self._read()
        deadline = asked + timeout
        self._wake.set()                             # the feed reads now rather than when its period ends
        with self._published:
            while self._latest_started < asked:
                if self.error is not None:
                    raise CameraError(self.error)
                left = deadline - time.monotonic()
                if left <= 0 or not self.running:
                    break
                self._published.wait(left)
            else:
                return self._latest
        if self.error is not None:
            raise CameraError(self.error)
        return self._read()                          # the feed stopped meanwhile: read here

    def latest(self) -> Frame | None:
        """The last frame read, by anyone (None before the first)."""
        return self._latest

    def settings(self) -> dict:
        """The camera's settings, queried between reads."""
        with self._read_lock:
            return self.camera.settings()

    # -- the feed ----------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def subscribe(self, callback: Subscriber, on_error: Callable[[str], None] | None = None) -> Callable[[], None]:
        """Call ``callback(frame)`` (on the source's thread) for every frame, and ``on_error(message)``
        if the camera fails; starts the feed. Returns a function that unsubscribes (the feed stops
        with the last subscriber)."""
        with self._published:
            self._subscribers.append(callback)
            if on_error is not None:
                self._error_subscribers.append(on_error)
        self._start()

        def unsubscribe() -> None:
            with self._published:
                if callback in self._subscribers:
                    self._subscribers.remove(callback)
                if on_error in self._error_subscribers:
                    self._error_subscribers.remove(on_error)
                last = not self._subscribers
            if last:
                self._halt()
        return unsubscribe

    def _start(self) -> None:
        if self.running:
            return
        self._stop.clear()
        self.error = None
        self._thread = threading.Thread(target=self._run, name="hairdigi-frame-source", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            start = time.perf_counter()
            try:
                self._read()
            except Exception as exc:   # a driver error stops the feed; next_frame reports it
                with self._published:
                    name = getattr(self.camera, "name", "camera")
                    self.error = str(exc) if str(exc).startswith(name) else f"{name}: {exc}"
                    self._published.notify_all()
                    report = list(self._error_subscribers)
                for on_error in report:
                    on_error(self.error)
                if not self._await_camera():
                    return
                continue
            self._wake.wait(max(0.0, self.period - (time.perf_counter() - start)))
            self._wake.clear()

    def _await_camera(self, poll_s: float = 1.0) -> bool:
        """After a failure, wait for a camera that can reopen itself (``reconnect``) to come back, while the
        feed runs; True when it did (the feed goes on), False for any other camera (the feed stops)."""
        reconnect = getattr(self.camera, "reconnect", None)
        if reconnect is None:
            return False
        while not self._stop.is_set():
            with self._read_lock:
                back = reconnect(wait_s=0.0)
            if back:
                with self._published:
                    self.error = None
                return True
            self._stop.wait(poll_s)
        return False

    def _halt(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._thread = None

    def close(self) -> None:
        """Stop the feed and release the camera."""
        with self._published:
            self._subscribers.clear()
            self._error_subscribers.clear()
        self._halt()
        with self._read_lock:
            self.camera.close()
