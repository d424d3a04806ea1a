"""Runtime hook of the desktop build, run before hairdigi starts: point Dr.Jit at the bundled libLLVM,
and check the system libraries the build cannot carry before the window needs them, so that a missing
one is one line naming it and its install command, not an abort in Qt's or VTK's loader."""
import ctypes
import os
import sys

#: What the window needs from the system (the graphics stack: drivers must match the machine, so
#: PyInstaller never bundles them): library, what it is, the Debian/Ubuntu package.
SYSTEM_LIBS = (("libGL.so.1", "OpenGL", "libgl1"), ("libEGL.so.1", "EGL", "libegl1"),
               ("libOpenGL.so.0", "OpenGL", "libopengl0"), ("libGLX.so.0", "GLX", "libglx0"),
               ("libxcb.so.1", "X11 xcb", "libxcb1"))
#: Qt platforms that draw without a display server.
HEADLESS = ("offscreen", "minimal", "vnc")


def _command(argv: list) -> str:
    """The subcommand, as hairdigi's CLI finds it: the first argument that is not an option."""
    return next((a for a in argv if not a.startswith("-")), "")


def _use_bundled_llvm() -> None:
    """Dr.Jit looks for libLLVM in the system folders; the build carries libLLVM 19 (see packaging/README.md)."""
    bundled = os.path.join(sys._MEIPASS, "llvm", "libLLVM.so.19.1")
    if os.path.exists(bundled) and "DRJIT_LIBLLVM_PATH" not in os.environ:
        os.environ["DRJIT_LIBLLVM_PATH"] = bundled


def _check_window_libraries() -> None:
    """Before ``hairdigi app``: a display, and the system's graphics libraries; else one line and exit 2."""
    platform = os.environ.get("QT_QPA_PLATFORM", "")
    if platform.startswith(HEADLESS):
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
        packages = " ".join(dict.fromkeys(p for _, _, p in missing))
        sys.stderr.write(f"hairdigi app: error: the system lacks {names}, which the window needs; install "
                         f"with: sudo apt-get install {packages}\n")
        sys.exit(2)


_use_bundled_llvm()
if _command(sys.argv[1:]) == "app" and not {"-h", "--help"} & set(sys.argv[1:]):
    _check_window_libraries()
