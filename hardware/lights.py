"""The host side of the light protocol (see PROTOCOL.md): a pyserial client with retries and reconnection."""
from __future__ import annotations

import numbers
import re
import threading
import time
from dataclasses import dataclass

import serial
import serial.tools.list_ports

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.rig_geometry import N_LIGHTS  # the rig has as many lights as the board has channels

try:  # pyserial's POSIX backend lets termios.error (not an OSError) escape from a vanished tty
    import termios
    LINK_ERRORS: tuple = (serial.SerialException, OSError, termios.error)
except ImportError:  # Windows
    LINK_ERRORS = (serial.SerialException, OSError)

BAUDRATE = 115200
IDENT_PREFIX = "OK HAIRDIGI-LIGHTS"
MAX_COMMAND = 32          # characters a command may hold, its line ending not counted (PROTOCOL.md)
#: A board unplugged and plugged back (USB re-enumerates) is reopened for about this long, with backoff.
RECONNECT_S = 1.6
_STATUS_PART = re.compile(r"([01]):(0|[1-9][0-9]{0,2})")


class LightError(HairdigiError, RuntimeError):
    """Base of the light-controller errors; each message names the command and the fix."""


class LightTimeout(LightError):
    pass


class LightProtocolError(LightError):
    pass


class LightLinkError(LightError):
    pass


class LightCommandError(LightError):
    """The board answered ``ERR``: the command was understood but refused."""


class LightArgumentError(LightError, ValueError):
    """The host refuses to send a command or an argument the protocol does not allow; nothing was sent."""


def check_command(command: str) -> None:
    """Raise ``LightArgumentError`` unless ``command`` is one line of printable ASCII (PROTOCOL.md)."""
    if not isinstance(command, str):
        raise LightArgumentError(f"command must be a str, not {type(command).__name__} {command!r}")
    if "\n" in command or "\r" in command:
        raise LightArgumentError(f"command {command!r} contains a line break; send one command per call")
    if not all(" " <= c <= "~" for c in command):
        raise LightArgumentError(f"command {command[:40]!r} may hold only printable ASCII characters (space to '~')")
    if len(command) > MAX_COMMAND:
        raise LightArgumentError(f"command {command[:40]!r}... is {len(command)} characters; the protocol allows "
                                 f"at most {MAX_COMMAND}")


def check_index(index: int) -> int:
    """The light index as an int, or ``LightArgumentError`` if it is not an int from 0 to N_LIGHTS - 1."""
    if isinstance(index, bool) or not isinstance(index, numbers.Integral) or not 0 <= index < N_LIGHTS:
        raise LightArgumentError(f"light index must be an int from 0 to {N_LIGHTS - 1}, not {index!r}")
    return int(index)


def check_intensity(intensity: float) -> int:
    """The intensity rounded to a PWM step, or ``LightArgumentError`` if it is not a real number from 0 to 255."""
    if isinstance(intensity, bool) or not isinstance(intensity, numbers.Real) or not 0 <= intensity <= 255:
        raise LightArgumentError(f"intensity must be a number from 0 to 255, not {intensity!r}")
    return round(float(intensity))


@dataclass(frozen=True)
class LightState:
    on: bool
    intensity: int


def parse_status(reply: str) -> tuple[LightState, ...]:
    """``OK 1:255 0:128 1:200`` to three ``LightState``; raises ``LightProtocolError`` otherwise."""
    parts = reply.split()
    if len(parts) != N_LIGHTS + 1 or parts[0] != "OK":
        raise LightProtocolError(f"malformed STATUS reply {reply!r}")
    states = []
    for part in parts[1:]:
        match = _STATUS_PART.fullmatch(part)
        if match is None or int(match.group(2)) > 255:   # on is 0 or 1; an intensity 0 to 255, digits only
            raise LightProtocolError(f"malformed STATUS reply {reply!r}")
        states.append(LightState(match.group(1) == "1", int(match.group(2))))
    return tuple(states)


def _is_protocol_line(line: str) -> bool:
    return line == "OK" or line.startswith(("OK ", "ERR "))


class LightController:
    """Three lights on a serial port. Every call is one command and one reply line."""

    def __init__(self, port: str, timeout: float = 0.5, retries: int = 2, baudrate: int = BAUDRATE) -> None:
        self.port_name = port
        self.timeout = timeout
        self.retries = retries
        self.baudrate = baudrate
        self.log: list[tuple[str, str]] = []  # (sent, received) for diagnostics
        self._serial: serial.Serial | None = None
        self._lock = threading.RLock()  # one command and its reply at a time, whatever the thread
        self._open()

    # -- link ----------------------------------------------------------------------------------
    def _open(self) -> None:
        try:
            self._serial = serial.serial_for_url(self.port_name, baudrate=self.baudrate, timeout=self.timeout,
                                                 write_timeout=self.timeout)
        except (serial.SerialException, OSError) as exc:
            raise LightLinkError(f"cannot open the light board on {self.port_name} ({exc}); check the USB "
                                 f"cable, or run 'hairdigi rig --list-ports' to find the board") from None

    def _reopen(self) -> bool:
        """Open the port again, retrying with backoff for about ``RECONNECT_S`` (a replug takes a moment)."""
        deadline, delay = time.monotonic() + RECONNECT_S, 0.05
        while True:
            time.sleep(delay)
            try:
                self._open()
                return True
            except LightLinkError:
                if time.monotonic() + delay > deadline:
                    return False
                delay = min(2 * delay, 0.4)

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            except LINK_ERRORS:
                pass  # the device is already gone
            finally:
                self._serial = None

    def __enter__(self) -> "LightController":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def connected(self) -> bool:
        return self._serial is not None and self._serial.is_open

    def _exchange(self, command: str) -> str:
        assert self._serial is not None
        self._serial.reset_input_buffer()
        self._serial.write((command + "\n").encode("ascii"))
        self._serial.flush()
        raw = self._serial.readline()
        if not raw:
            raise LightTimeout(f"no reply to {command!r} within {self.timeout} s")
        if not raw.endswith(b"\n"):
            raise LightProtocolError(f"partial reply {raw!r} to {command!r}")
        try:
            line = raw.decode("ascii").strip()
        except UnicodeDecodeError:
            raise LightProtocolError(f"garbage reply {raw!r} to {command!r}") from None
        if not _is_protocol_line(line):
            raise LightProtocolError(f"garbage reply {line!r} to {command!r}")
        if not line.startswith("ERR") and (line == "OK") == command.endswith("?"):
            # a query answered with a bare OK, or a setting answered with data: a stale reply
            raise LightProtocolError(f"reply {line!r} does not answer {command!r}")
        return line

    def command(self, command: str) -> str:
        """Send one command; retry lost or garbled replies, reconnect once after a link failure."""
        check_command(command)
        with self._lock:
            line = self._command(command)
        if line.startswith("ERR"):  # refused: sending it again would be refused again
            raise LightCommandError(f"the board refused {command!r}: {line}")
        return line

    def _command(self, command: str) -> str:
        """The board's reply to ``command`` (``OK ...`` or ``ERR ...``), after the retries it needs."""
        reconnected = False
        last: Exception | None = None
        attempt = 0
        while attempt <= self.retries:
            try:
                if not self.connected:
                    self._open()
                line = self._exchange(command)
                self.log.append((command, line))
                return line
            except (LightTimeout, LightProtocolError) as exc:
                last = exc
                attempt += 1
                # let a late reply to this try arrive, so the next try's reset discards it
                time.sleep(self.timeout / 2)
            except (*LINK_ERRORS, LightLinkError) as exc:
                self.close()
                if reconnected or not self._reopen():
                    raise LightLinkError(f"lost the light board on {self.port_name} during {command!r} "
                                         f"({exc}); check the USB cable and power, then reconnect") from None
                reconnected = True
                last = exc
        raise type(last)(f"{last} (after {self.retries + 1} tries)") if isinstance(last, LightError) else \
            LightTimeout(f"no valid reply to {command!r} after {self.retries + 1} tries")

    # -- the protocol ----------------------------------------------------------------------------
    def identify(self) -> str:
        reply = self.command("ID?")
        if not reply.startswith(IDENT_PREFIX):
            raise LightProtocolError(f"{self.port_name} is not a hairdigi light board (it says {reply!r})")
        return reply[3:]

    def set_light(self, index: int, on: bool | None = None, intensity: float | None = None) -> None:
        """Set light ``index``'s intensity (0 to 255), then switch it on or off; None leaves either as it is."""
        index = check_index(index)
        if on is not None and not isinstance(on, bool):
            raise LightArgumentError(f"on must be True, False or None, not {on!r}")
        if intensity is not None:
            self.command(f"L{index} I {check_intensity(intensity)}")
        if on is not None:
            self.command(f"L{index} {'ON' if on else 'OFF'}")

    def all_off(self) -> None:
        self.command("ALL OFF")

    def status(self) -> tuple[LightState, ...]:
        return parse_status(self.command("STATUS?"))


def discover(timeout: float = 0.3) -> list[tuple[str, str]]:
    """Ports whose device answers ``ID?`` as a hairdigi light board: (port, identity)."""
    found = []
    for info in serial.tools.list_ports.comports():
        try:
            with LightController(info.device, timeout=timeout, retries=0) as lc:
                found.append((info.device, lc.identify()))
        except (LightError, ValueError):
            continue
    return found
