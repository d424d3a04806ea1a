"""A simulated light board that speaks PROTOCOL.md over a real pseudo-terminal.

The host opens ``board.port``, a stable symlink to the pty's slave side (like udev's
``/dev/serial/by-id/...`` names), through pyserial exactly as it opens the real board. Faults
can be injected: lost replies, garbage, partial lines, slow replies, and an unplug and replug.
"""
from __future__ import annotations

import os
import select
import tempfile
import termios
import threading
import time
import tty
from dataclasses import dataclass, field
from pathlib import Path

from hardware.lights import N_LIGHTS

FIRMWARE = "sim-1.0"
PROTOCOL_VERSION = "1"


@dataclass
class BoardState:
    on: list[bool] = field(default_factory=lambda: [False] * N_LIGHTS)
    intensity: list[int] = field(default_factory=lambda: [255] * N_LIGHTS)

    def levels(self) -> tuple[float, float, float]:
        """Light output in [0, 1] for each light: on x intensity / 255."""
        return tuple(float(o) * i / 255.0 for o, i in zip(self.on, self.intensity))


def handle(line: str, state: BoardState, serial_no: str = "SIM0001") -> str:
    """One protocol command against ``state``; returns the reply line (without newline)."""
    if len(line) > 32:
        return "ERR E4 line too long"
    if line == "ID?":
        return f"OK HAIRDIGI-LIGHTS {PROTOCOL_VERSION} {FIRMWARE} {serial_no}"
    if line == "STATUS?":
        return "OK " + " ".join(f"{int(o)}:{i}" for o, i in zip(state.on, state.intensity))
    if line == "ALL OFF":
        state.on = [False] * N_LIGHTS
        return "OK"
    parts = line.split(" ")
    if len(parts) >= 2 and len(parts[0]) == 2 and parts[0][0] == "L":
        if not parts[0][1].isdigit() or int(parts[0][1]) >= N_LIGHTS:
            return "ERR E2 no such light"
        n = int(parts[0][1])
        if parts[1:] == ["ON"] or parts[1:] == ["OFF"]:
            state.on[n] = parts[1] == "ON"
            return "OK"
        if len(parts) == 3 and parts[1] == "I":
            if not parts[2].isdigit() or not 0 <= int(parts[2]) <= 255:
                return "ERR E3 value out of range"
            state.intensity[n] = int(parts[2])
            return "OK"
    return "ERR E1 unknown command"


class SimulatedLightBoard:
    """Runs the board in a thread behind a pty; ``port`` is the path to open with pyserial."""

    def __init__(self, link_dir: str | os.PathLike | None = None) -> None:
        self.state = BoardState()
        self._dir = Path(link_dir or tempfile.mkdtemp(prefix="hairdigi-serial-"))
        self.port = str(self._dir / "ttyHAIRDIGI0")
        self.received: list[str] = []
        self.faults: list[str] = []   # queue: "drop", "garbage", "partial", "slow"
        self.unplugged = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._master = -1
        self._slave = -1
        self._thread: threading.Thread | None = None
        self.plug()

    # -- lifecycle -----------------------------------------------------------------------------
    def plug(self) -> None:
        """Create a fresh pty (as a USB device re-enumerates) and point ``port`` at it."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        attrs[3] &= ~termios.ECHO
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
        tmp = self.port + ".tmp"
        Path(tmp).unlink(missing_ok=True)
        os.symlink(os.ttyname(self._slave), tmp)
        os.replace(tmp, self.port)
        self.unplugged = False
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, args=(self._master,), daemon=True)
        self._thread.start()

    def unplug(self) -> None:
        """Vanish: close the pty so the host's next read or write fails, and remove the port."""
        self.unplugged = True
        self._stop.set()
        if self._thread:
            self._thread.join(timeout=2)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        Path(self.port).unlink(missing_ok=True)

    def close(self) -> None:
        if not self.unplugged:
            self.unplug()

    def __enter__(self) -> "SimulatedLightBoard":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def inject(self, *faults: str) -> None:
        """Queue faults for the next replies: ``drop``, ``garbage``, ``partial``, ``slow``, ``unplug``."""
        with self._lock:
            self.faults.extend(faults)

    # -- the board ------------------------------------------------------------------------------
    def _serve(self, master: int) -> None:
        buffer = b""
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([master], [], [], 0.05)
                if not ready:
                    continue
                chunk = os.read(master, 256)
            except OSError:
                return
            if not chunk:
                return
            buffer += chunk
            while b"\n" in buffer:
                raw, buffer = buffer.split(b"\n", 1)
                line = raw.decode("ascii", "replace").strip("\r")
                self._reply(master, line)

    def _reply(self, master: int, line: str) -> None:
        with self._lock:
            self.received.append(line)
            fault = self.faults.pop(0) if self.faults else None
            reply = handle(line, self.state)
        if fault == "unplug":  # the cable comes out mid-command: no reply, and the port is gone
            threading.Thread(target=self.unplug, daemon=True).start()
            return
        if fault == "drop":
            return
        data = (reply + "\n").encode("ascii")
        if fault == "garbage":
            data = b"\xff\xfe#~\x00garbage\n"
        elif fault == "partial":
            data = data[: max(1, len(data) // 2)]
        elif fault == "slow":  # later than the host's timeout, within its retries
            time.sleep(0.4)
        try:
            os.write(master, data)
        except OSError:
            pass
