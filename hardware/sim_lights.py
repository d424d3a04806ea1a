"""Simulated light boards that speak PROTOCOL.md over a real pseudo-terminal.

The host opens ``board.port``, a stable symlink to the pty's slave side (like udev's
``/dev/serial/by-id/...`` names), through pyserial exactly as it opens the real board.

``SimulatedLightBoard`` is the protocol in Python; faults can be injected: lost replies, garbage,
partial lines, slow replies, and an unplug and replug. ``EmulatedFirmwareBoard`` runs the real
firmware (``firmware/hairdigi_lights``, built for an Arduino Uno) in the simavr AVR emulator.
"""
from __future__ import annotations

import atexit
import os
import select
import shutil
import signal
import subprocess
import tempfile
import termios
import threading
import time
import tty
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path

from hairdigi.hardware.lights import N_LIGHTS

FIRMWARE = "sim-1.1"
PROTOCOL_VERSION = "1"
MAX_LINE = 32


@dataclass
class BoardState:
    on: list[bool] = field(default_factory=lambda: [False] * N_LIGHTS)
    intensity: list[int] = field(default_factory=lambda: [255] * N_LIGHTS)
    fault: list[bool] = field(default_factory=lambda: [False] * N_LIGHTS)  # a driver's fault input

    def levels(self) -> tuple[float, float, float]:
        """Light output in [0, 1] for each light: on x intensity / 255."""
        return tuple(float(o) * i / 255.0 for o, i in zip(self.on, self.intensity))


def handle(line: str, state: BoardState, serial_no: str = "SIM0001") -> str:
    """One line (its ``\\n`` removed, one character a byte) against ``state``; the reply, without newline."""
    if line.endswith("\r"):  # a CRLF line ending; any other \r is a stray byte
        line = line[:-1]
    if len(line) > MAX_LINE:
        return "ERR E4 line too long"
    if not all(" " <= c <= "~" for c in line):  # a control character, NUL or 8-bit byte
        return "ERR E1 unknown command"
    if line == "ID?":
        return f"OK HAIRDIGI-LIGHTS {PROTOCOL_VERSION} {FIRMWARE} {serial_no}"
    if line == "STATUS?":
        return "OK " + " ".join(f"{int(o)}:{i}" for o, i in zip(state.on, state.intensity))
    if line == "ALL OFF":
        state.on = [False] * N_LIGHTS
        return "OK"
    if line.startswith("L") and " " in line:  # a light command: the index runs up to the first space
        index, arg = line[1:].split(" ", 1)
        if index not in [str(n) for n in range(N_LIGHTS)]:
            return "ERR E2 no such light"
        n = int(index)
        if arg in ("ON", "OFF"):
            if arg == "ON" and state.fault[n]:
                return "ERR E5 driver fault"
            state.on[n] = arg == "ON"
            return "OK"
        if arg.startswith("I "):
            value = arg[2:]  # ASCII digits only: no sign, no space
            if not value or not all("0" <= c <= "9" for c in value) or int(value) > 255:
                return "ERR E3 value out of range"
            state.intensity[n] = int(value)
            return "OK"
    return "ERR E1 unknown command"


def _terminated(signum, frame) -> None:
    """SIGTERM: unwind like an exit, so ``finally`` blocks and ``atexit`` remove what the run made."""
    raise SystemExit(128 + signum)


def _remove_on_exit(folder: Path) -> None:
    """Remove ``folder`` when the process exits, by SIGTERM too (the default SIGTERM skips ``atexit``)."""
    atexit.register(shutil.rmtree, str(folder), True)
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _terminated)


class SimulatedLightBoard:
    """Runs the board in a thread behind a pty; ``port`` is the path to open with pyserial."""

    def __init__(self, link_dir: str | os.PathLike | None = None) -> None:
        self.state = BoardState()
        self._own_dir = link_dir is None  # made here, removed on close
        self._dir = Path(link_dir or tempfile.mkdtemp(prefix="hairdigi-serial-"))
        if self._own_dir:
            _remove_on_exit(self._dir)
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
        if self._own_dir:
            shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> "SimulatedLightBoard":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def set_fault(self, light: int, fault: bool) -> None:
        """Make ``light``'s driver report a fault (its fault input low), or clear it."""
        with self._lock:
            self.state.fault[light] = fault

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
                line = raw.decode("latin-1")  # one character a byte, as the firmware sees them
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


# -- the real firmware in simavr -------------------------------------------------------------------
FIRMWARE_DIR = Path(str(files(__package__))) / "firmware"
ARDUINO_CORE = Path("/usr/share/arduino/hardware/arduino/avr/cores/arduino")
FAULT_PINS = (("D", 2), ("D", 3), ("D", 4))  # the Uno's pins 2, 3 and 4 are PD2, PD3 and PD4
FIRMWARE_PACKAGES = "gcc-avr avr-libc arduino-core-avr simavr libsimavr-dev libelf-dev"


def firmware_tools_missing() -> str | None:
    """Why the firmware and its simavr harness cannot be built here, or None when they can."""
    tools = ("make", "gcc", "pkg-config", "avr-gcc", "avr-g++", "avr-size")
    missing = [tool for tool in tools if not shutil.which(tool)]
    if not (ARDUINO_CORE / "Arduino.h").exists():
        missing.append(str(ARDUINO_CORE / "Arduino.h"))
    if shutil.which("pkg-config") and subprocess.run(["pkg-config", "--exists", "simavr", "libelf"]).returncode:
        missing.append("simavr and libelf for pkg-config")
    return f"missing {', '.join(missing)}; apt-get install {FIRMWARE_PACKAGES}" if missing else None


def build_firmware(build_dir: str | os.PathLike) -> Path:
    """Build the sketch for an Uno and the simavr harness into ``build_dir`` (with make: only what changed)."""
    build = Path(build_dir).resolve()
    done = subprocess.run(["make", "-C", str(FIRMWARE_DIR), f"BUILD={build}", "all"], capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"building the firmware failed:\n{done.stdout[-2000:]}{done.stderr[-4000:]}")
    return build


class EmulatedFirmwareBoard:
    """The firmware built by ``build_firmware`` on an emulated ATmega328P, its UART behind a pty at ``port``."""

    def __init__(self, build_dir: str | os.PathLike, link_dir: str | os.PathLike | None = None) -> None:
        self.build = Path(build_dir)
        self._own_dir = link_dir is None  # made here, removed on close
        self._dir = Path(link_dir or tempfile.mkdtemp(prefix="hairdigi-avr-"))
        self.port = str(self._dir / "ttyHAIRDIGI0")
        self._rx_log = self._dir / "received.bin"  # every byte the AVR has received
        self._proc: subprocess.Popen | None = None
        self._out = b""  # the harness's stdout not read yet
        self.plug()

    def plug(self, timeout: float = 10.0) -> None:
        """Power the board up (a fresh boot, every light off) and wait until its port is there."""
        self._rx_log.touch()
        with open(self._dir / "simavr.log", "ab") as log:
            self._proc = subprocess.Popen(
                [str(self.build / "simavr_uart"), str(self.build / "hairdigi_lights.elf"), self.port,
                 str(self._rx_log)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log)
        self._out = b""
        try:
            self._expect(b"ready ", timeout)
        except RuntimeError:
            self.unplug()
            raise

    def _expect(self, prefix: bytes, timeout: float) -> bytes:
        """The harness's next stdout line that starts with ``prefix``; raises if it exits or stays silent."""
        assert self._proc is not None and self._proc.stdout is not None
        fd, deadline = self._proc.stdout.fileno(), time.monotonic() + timeout
        while True:
            while b"\n" in self._out:
                line, self._out = self._out.split(b"\n", 1)
                if line.startswith(prefix):
                    return line
            wait = deadline - time.monotonic()
            chunk = os.read(fd, 4096) if wait > 0 and select.select([fd], [], [], wait)[0] else b""
            if not chunk:
                log = (self._dir / "simavr.log").read_text(errors="replace")[-2000:]
                raise RuntimeError(f"no {prefix.decode().strip()!r} from the simavr harness "
                                   f"(exit status {self._proc.poll()}); its log: {log}")
            self._out += chunk

    def unplug(self) -> None:
        """Pull the cable: the emulator stops, its pty and the port's symlink go."""
        if self._proc is not None:
            self._proc.send_signal(signal.SIGTERM)
            try:
                self._proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
            for pipe in (self._proc.stdin, self._proc.stdout):
                pipe.close()
            self._proc = None
        Path(self.port).unlink(missing_ok=True)

    def close(self) -> None:
        self.unplug()
        if self._own_dir:
            shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> "EmulatedFirmwareBoard":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def received(self) -> list[str]:
        """The complete lines the board has received (without their ``\\n``), one character a byte."""
        return self._rx_log.read_bytes().decode("latin-1").split("\n")[:-1]

    def set_fault(self, light: int, fault: bool) -> None:
        """Pull the fault input of ``light``'s driver low (a fault) or let it go high."""
        assert self._proc is not None and self._proc.stdin is not None
        port, pin = FAULT_PINS[light]
        self._proc.stdin.write(f"pin {port} {pin} {0 if fault else 1}\n".encode())
        self._proc.stdin.flush()
        self._expect(b"ok pin", 5.0)
