"""Whether ``DISPLAY`` is an X server, by the X11 connection handshake, before Qt is started on it.

Qt aborts the process (exit 134, several lines) on a display it cannot open, and waits without end on a
socket that accepts but never answers as X does. So the window's command first connects itself, with a
timeout, sends the X11 connection setup request (no authorisation) and reads the reply's head: an X
server answers Failed (0), Success (1) or Authenticate (2), and for the first two its protocol version,
11 (the X Window System Protocol, section 8, "Connection Setup"). A refusal for want of authorisation
still says an X server is there: Qt brings the cookie.
"""
from __future__ import annotations

import os
import re
import socket
import struct
import sys
import time
from pathlib import Path

#: Seconds the X server has to accept and to answer the setup request.
HANDSHAKE_TIMEOUT_S = 3.0
#: Qt platforms that open no X display.
NO_X_PLATFORMS = ("offscreen", "minimal", "vnc", "eglfs", "linuxfb", "wayland", "wayland-egl")
_DISPLAY = re.compile(r"(?:(?P<proto>[A-Za-z]+)/)?(?P<host>[^:]*):(?P<number>\d+)(?:\.\d+)?")


def shown(text: str) -> str:
    """A user's text for a message: printable ASCII only (no escape reaches the terminal), at most 60 characters."""
    return "".join(c if 32 <= ord(c) < 127 else "?" for c in text[:60])


def setup_request() -> bytes:
    """The X11 connection setup request, little-endian, protocol 11.0, no authorisation."""
    return struct.pack("<BxHHHHxx", ord("l"), 11, 0, 0, 0)


def is_x_reply(head: bytes) -> bool:
    """Whether the first 8 bytes of a reply are an X server's answer to :func:`setup_request`."""
    if len(head) < 8:
        return False
    if head[0] == 2:   # Authenticate: the rest is the server's reason
        return True
    return head[0] in (0, 1) and struct.unpack("<H", head[2:4])[0] == 11


def _connect(display: str, timeout: float) -> socket.socket:
    """A socket to the X server ``display`` names (its Unix socket, or TCP port 6000 + number)."""
    match = _DISPLAY.fullmatch(display)
    if not match:
        raise ValueError(f"DISPLAY={shown(display)!r} is not a display name ([host]:number[.screen], e.g. :0)")
    host, number = match.group("host"), int(match.group("number"))
    if host in ("", "unix") and match.group("proto") in (None, "unix"):
        path = f"/tmp/.X11-unix/X{number}"
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(timeout)
        try:   # the file, else Linux's abstract socket of the same name (where Xorg listens too)
            sock.connect(path if Path(path).exists() else "\0" + path)
        except OSError:
            sock.close()
            raise
        return sock
    return socket.create_connection((host, 6000 + number), timeout=timeout)


def x_handshake_problem(display: str, timeout: float = HANDSHAKE_TIMEOUT_S) -> str | None:
    """Why ``display`` is not an X server this process can open a window on, in words, or None: no connection,
    no answer within ``timeout`` seconds, or an answer that is not X's."""
    deadline = time.monotonic() + timeout
    try:
        sock = _connect(display, timeout)
    except ValueError as exc:
        return str(exc)
    except OSError as exc:
        why = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__)
        return f"DISPLAY={shown(display)}: no X server accepts a connection ({why})"
    head = b""
    try:
        with sock:
            sock.sendall(setup_request())
            while len(head) < 8:
                sock.settimeout(max(0.01, deadline - time.monotonic()))
                piece = sock.recv(8 - len(head))
                if not piece:
                    break
                head += piece
    except TimeoutError:
        return (f"DISPLAY={shown(display)}: something accepts the connection but does not answer as an X server "
                f"within {timeout:g} s (another program on the X port?)")
    except OSError as exc:
        return f"DISPLAY={shown(display)}: the connection failed during the X handshake ({exc.strerror or exc})"
    if not is_x_reply(head):
        return (f"DISPLAY={shown(display)}: what answers is not an X server (its first bytes {head[:8].hex() or 'none'}; "
                "another program on the X port?)")
    return None


def uses_x() -> bool:
    """Whether Qt will open an X display: on Linux, with no Qt platform that needs none and no Wayland compositor
    it would use instead (``QT_QPA_PLATFORM=xcb`` forces X)."""
    platform = os.environ.get("QT_QPA_PLATFORM", "").split(":")[0]
    if not sys.platform.startswith("linux") or platform in NO_X_PLATFORMS:
        return False
    if platform == "xcb":
        return True
    wayland = os.environ.get("WAYLAND_DISPLAY")
    if wayland:
        runtime = os.environ.get("XDG_RUNTIME_DIR", "")
        if (Path(wayland) if os.path.isabs(wayland) else Path(runtime or "/nonexistent") / wayland).is_socket():
            return False
    return bool(os.environ.get("DISPLAY"))


def display_problem(timeout: float = HANDSHAKE_TIMEOUT_S) -> str | None:
    """Why the window cannot open on ``DISPLAY`` (an X handshake that fails), with the fix, or None."""
    if not uses_x():
        return None
    problem = x_handshake_problem(os.environ["DISPLAY"], timeout)
    if problem is None:
        return None
    return (f"no display: {problem}; run it on the desktop, or without one under a virtual X server: "
            "xvfb-run hairdigi app ...")
