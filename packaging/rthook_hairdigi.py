"""Runtime hook of the desktop build, run before hairdigi starts. Its first-run checks turn what the
system lacks into one line naming it and its install command, never an abort or a traceback:

- Dr.Jit is pointed at the bundled libLLVM 19. Left to itself it takes any system libLLVM, and
  Mesa's LLVM 15, on most desktops, aborts on hair curves. If the bundled one cannot load, renders
  use ``scalar_rgb`` (about 2x slower) and one line says why.
- ``hairdigi app`` needs a display and the system's graphics libraries (drivers must match the
  machine, so they are never bundled).
"""
import ctypes
import os
import sys

LLVM = os.path.join(sys._MEIPASS, "llvm", "libLLVM.so.19.1")
#: What the window needs from the system and the build does not carry (PyInstaller leaves the GL
#: stack and libxcb to the system; packaging/README.md lists how this was found): library, what it
#: is, the Debian/Ubuntu package. Qt's libQt6Gui links the first two, its xcb plugin the third.
SYSTEM_LIBS = (("libGL.so.1", "OpenGL", "libgl1"), ("libEGL.so.1", "EGL", "libegl1"),
               ("libxcb.so.1", "X11 xcb", "libxcb1"))
#: With the libraries, the Mesa drivers that make them draw (on a machine without another GPU driver).
DRIVERS = "libglx-mesa0 libegl-mesa0"
#: Qt platforms that draw without a display server.
HEADLESS = ("offscreen", "minimal", "vnc")
#: Arguments after which hairdigi only prints (no render, no window).
PRINT_ONLY = {"--version", "-h", "--help"}


def _command(argv: list) -> str:
    """The subcommand, as hairdigi's CLI finds it: the first argument that is not an option."""
    return next((a for a in argv if not a.startswith("-")), "")


def _use_bundled_llvm() -> None:
    """Point Dr.Jit at the bundled libLLVM 19; if it does not load, say why and use scalar_rgb."""
    if "DRJIT_LIBLLVM_PATH" in os.environ or not os.path.exists(LLVM):
        return   # the user's choice, or a build made without LLVM (HAIRDIGI_BUNDLE_LLVM=0)
    os.environ["DRJIT_LIBLLVM_PATH"] = LLVM
    try:
        ctypes.CDLL(LLVM)
    except OSError as exc:
        # scalar_rgb outright: Dr.Jit must not try a system LLVM 15, nor log its own failure
        os.environ.setdefault("HAIRDIGI_VARIANT", "scalar_rgb")
        reason = " ".join(str(exc).split())
        sys.stderr.write(f"hairdigi: the bundled libLLVM 19 does not load ({reason}); rendering with "
                         f"scalar_rgb, about 2x slower; install what it lacks with: sudo apt-get install libllvm19\n")


def _check_window_libraries() -> None:
    """Before ``hairdigi app``: a display, and the system's graphics libraries; else one line and exit 2."""
    if os.environ.get("QT_QPA_PLATFORM", "").startswith(HEADLESS):
        return
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        sys.stderr.write("hairdigi app: error: no display (DISPLAY is not set); run it on the desktop, or "
                         "headless with xvfb-run -a hairdigi app\n")
        sys.exit(2)
    missing = []
    for name, what, package in SYSTEM_LIBS:
        try:
            ctypes.CDLL(name)
        except OSError:
            missing.append((name, what, package))
    if missing:
        names = ", ".join(f"{n} ({w})" for n, w, _ in missing)
        packages = " ".join(dict.fromkeys(p for _, _, p in missing)) + " " + DRIVERS
        sys.stderr.write(f"hairdigi app: error: the system lacks {names}, which the window needs; install "
                         f"with: sudo apt-get install {packages}\n")
        sys.exit(2)


if not PRINT_ONLY & set(sys.argv[1:]) and len(sys.argv) > 1:
    _use_bundled_llvm()
    if _command(sys.argv[1:]) == "app":
        _check_window_libraries()
