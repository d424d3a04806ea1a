"""One thread budget for the process, from the cores the operating system gives it.

``len(os.sched_getaffinity(0))`` (``taskset``, a container's cpuset, a scheduler's allotment), not
the machine's count: each pool sized for the whole machine oversubscribes a share of it (measured:
the app's previews ran 25x slower beside one other CPU-bound process). :func:`plan` is where each
pool's size is decided; :func:`start_up` applies what must be set before the libraries load (the
command line calls it first); each pool's owner reads its entry when it creates the pool:

- Dr.Jit's pool (the path tracer): the budget, set by ``render.variant.select_variant``;
- OIDN (the preview denoiser): its TBB pool follows the affinity mask, the same number;
- onnxruntime (the encoder, ``inference.encoder``): 1 intra-op thread; the encoder takes 0.2 ms;
- OpenBLAS / OpenMP (numpy): 1; hairdigi's arrays are small, and idle BLAS threads spin (the app's
  idle window took 132% of a core with them, 37% without).

``HAIRDIGI_THREADS`` lowers the budget (never above the cores given). The standard library only.
"""
from __future__ import annotations

import os

ENV = "HAIRDIGI_THREADS"
#: The pools numpy's BLAS and OpenMP read from the environment when they load.
_ENV_POOLS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def cores() -> int:
    """The processors this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):     # no affinity call on this OS
        return max(1, os.cpu_count() or 1)


def budget() -> int:
    """Threads for the process's compute pools: the cores given, or fewer with ``HAIRDIGI_THREADS``."""
    given = cores()
    value = os.environ.get(ENV, "").strip()
    return min(given, int(value)) if value.isdigit() and int(value) >= 1 else given


def plan() -> dict[str, int]:
    """Each pool's threads (see the module's note)."""
    n = budget()
    return {"drjit": n, "oidn": n, "onnxruntime": 1, "blas": 1}


def start_up() -> dict[str, int]:
    """At start-up, before numpy's BLAS loads: set the pools read from the environment (a value the
    user set is kept); returns the plan."""
    chosen = plan()
    for var in _ENV_POOLS:
        os.environ.setdefault(var, str(chosen["blas"]))
    return chosen
