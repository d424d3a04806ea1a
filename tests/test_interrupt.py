"""Ctrl-C around native rendering (render.domain.interrupt): Mitsuba's own SIGINT handler, which logs
from inside the handler and can deadlock, never runs; the signal becomes a KeyboardInterrupt once the
native call returns, and the native pools' threads never take it."""
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from deadlines import within

ROOT = Path(__file__).resolve().parents[1]
LINUX = sys.platform.startswith("linux")

#: A process like the command line's: the thread budget first, then tiny renders in a loop that counts
#: the Ctrl-Cs it gets as KeyboardInterrupts and ends at the fifth. At 16² and 1 spp two thirds of the
#: time is inside ``mi.render``, where Mitsuba's handler is installed (its kernel runs later, lazily,
#: when the image is read): before the fix, 5 signals all missed it in about 0.4% of runs.
RENDERS = """
from hairdigi.app.cli import start_up
start_up()
from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import default_renderer
renderer = default_renderer()
renderer.render(HairParams(), "swatch", 16, 1)      # compiled and loaded before the loop
print("rendering", flush=True)
renders = interrupts = 0
while renders < 100_000 and interrupts < 5:
    try:
        renderer.render(HairParams(), "swatch", 16, 1, seed=renders)
        renders += 1
    except KeyboardInterrupt:
        interrupts += 1
        print("interrupted", flush=True)
print("interrupts", interrupts, "renders", renders, flush=True)
"""


def _child(code: str) -> subprocess.Popen:
    # a test session run in the background ignores SIGINT, and an ignored signal stays ignored in a child
    return subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONPATH": str(ROOT), "OMP_WAIT_POLICY": "PASSIVE"},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


@pytest.mark.skipif(not LINUX, reason="signal masks per thread: Linux's /proc")
def test_ctrl_c_in_a_render_waits_for_the_call_and_is_a_keyboard_interrupt_mitsuba_never_sees():
    proc = _child(RENDERS)
    watchdog = threading.Timer(within(120), proc.kill)      # a child that stops answering ends the reads below
    watchdog.start()
    try:
        assert proc.stdout.readline().strip() == "rendering", proc.stderr.read()[-2000:]
        for _ in range(5):   # the next Ctrl-C once the last was taken: two in one render would be one signal
            time.sleep(0.3)
            proc.send_signal(signal.SIGINT)
            assert proc.stdout.readline().strip() == "interrupted", proc.stderr.read()[-2000:]
        # read on through the same buffered file: communicate() would miss a last line already buffered by readline
        out, err = proc.stdout.read(), proc.stderr.read()
        proc.wait(timeout=within(60))
    finally:
        watchdog.cancel()
        proc.kill()      # a failed check leaves no renderer behind
    # each Ctrl-C was one KeyboardInterrupt: none lost, none turned into Mitsuba's RuntimeError
    assert proc.returncode == 0 and out.split()[:2] == ["interrupts", "5"], (out, err[-2000:])
    assert 0 < int(out.split()[3]) < 100_000
    # Mitsuba's handler (integrator_v.cpp) would have logged this from inside the signal handler
    assert "winding down" not in out + err, (out, err[-2000:])


@pytest.mark.skipif(not LINUX, reason="signal masks per thread: Linux's /proc")
def test_no_thread_but_the_main_one_takes_ctrl_c_once_mitsuba_has_rendered():
    code = ("import json, os\n"
            "from hairdigi.app.cli import start_up\n"
            "start_up()\n"
            "from hairdigi.render.domain.params import HairParams\n"
            "from hairdigi.render.renderer import default_renderer\n"
            "default_renderer().render(HairParams(), 'swatch', 16, 1)\n"
            "takes = {}\n"
            "for task in os.listdir(f'/proc/{os.getpid()}/task'):\n"
            "    status = open(f'/proc/{os.getpid()}/task/{task}/status').read()\n"
            "    blocked = int(next(l for l in status.splitlines() if l.startswith('SigBlk')).split()[1], 16)\n"
            "    takes[task] = not blocked >> 1 & 1\n"
            "print(json.dumps({'pid': os.getpid(), 'takes': takes}))\n")
    proc = _child(code)
    try:
        out, err = proc.communicate(timeout=within(120))
    finally:
        proc.kill()
    assert proc.returncode == 0, err[-2000:]
    import json

    seen = json.loads(out.strip().splitlines()[-1])
    main = str(seen["pid"])
    assert len(seen["takes"]) >= 2, seen                     # Dr.Jit's pool (or scalar_rgb's) has started
    assert seen["takes"].pop(main) is True                   # the main thread still takes Ctrl-C
    assert not any(seen["takes"].values()), seen             # no native thread does


def test_a_signal_held_is_delivered_when_the_block_ends():
    from hairdigi.render.domain.interrupt import sigint_held

    if not hasattr(signal, "pthread_sigmask"):
        pytest.skip("no signal masks on this OS")
    reached = []
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)   # a background session ignores it
    try:
        with pytest.raises(KeyboardInterrupt):
            with sigint_held():
                signal.pthread_kill(threading.get_ident(), signal.SIGINT)   # to this thread, held here
                time.sleep(0.05)
                reached.append("after the signal")           # not interrupted inside the block
    finally:
        signal.signal(signal.SIGINT, previous)
    assert reached == ["after the signal"]
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, set())   # the block is lifted


@pytest.mark.parametrize("stop", [SystemExit(143), KeyboardInterrupt()])
def test_a_stop_during_a_variants_import_stops_and_is_not_taken_for_a_missing_variant(monkeypatch, stop):
    """A SIGTERM (SystemExit) or Ctrl-C raised inside an extension's import reaches the caller wrapped as
    an import error; taken as "variant unavailable", the process fell back to scalar_rgb and kept running."""
    import hairdigi.render.variant as V

    tried = []

    def set_variant(name):
        tried.append(name)
        try:
            raise stop
        except BaseException as exc:
            raise ImportError(f"the {name} extension could not be loaded") from exc

    monkeypatch.setattr(V.mi, "variant", lambda: None)
    monkeypatch.setattr(V.mi, "set_variant", set_variant)
    with pytest.raises(type(stop)):
        V.select_variant("auto")
    assert len(tried) == 1                                      # no fallback tried after the stop
