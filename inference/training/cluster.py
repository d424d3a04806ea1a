"""Dataset shards on Ray: one task per shard, on a running cluster or on a local Ray instance.

``hairdigi dataset --backend ray [--address ADDRESS]`` comes here through ``dataset.generate``.

Design: a task renders a whole shard with ``dataset.render_shard`` (the local pool's core: one
scene, loaded once and updated per sample) and *returns* the shard's arrays; the driver writes each
one atomically as it arrives (``dataset.write_shard``). So

- the workers need no folder shared with the driver (only hairdigi and Ray installed);
- which shards are missing, and so what a resumed run renders, is decided in one place
  (``dataset.generate``), and a task killed half-way leaves no file behind;
- a sample is bitwise the one the local backend renders: same core, same (seed, index), same
  Mitsuba variant (the driver names it; each task sets it).

A shard is small next to Ray's object store (50 swatches of 64² float16 RGB: 1.2 MB). A task whose
worker dies is run again, up to ``MAX_RETRIES`` times; an exception raised by the rendering itself
(bad settings) is not retried.
"""
from __future__ import annotations

import socket
import logging
from typing import Callable

from hairdigi.render.domain.errors import HairdigiError

INSTALL_HINT = "pip install 'hairdigi[cluster]'"
#: How often Ray runs a shard's task again after its worker died (a node lost, out of memory).
MAX_RETRIES = 3


class ClusterError(HairdigiError, RuntimeError):
    """The Ray backend cannot run: Ray missing, no cluster at the address, no GPU for a CUDA variant."""


def require_ray():
    """The ``ray`` module, or ClusterError saying how to install it."""
    try:
        import ray   # deferred: ray is the optional [cluster] extra
    except ImportError:
        raise ClusterError(f"the ray backend needs Ray (ray>=2.9), which is not installed; install it with "
                           f"{INSTALL_HINT}") from None
    return ray


#: Seconds to wait for a cluster's port to answer before the run is refused.
CONNECT_TIMEOUT_S = 3.0


def check_address(address: str | None, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Refuse a ``HOST:PORT`` or ``ray://HOST:PORT`` address whose port does not accept a connection
    within ``timeout`` (Ray itself would wait for minutes); ``auto`` and None are left to Ray."""
    if not address or address in ("auto", "local"):
        return
    rest = address.split("://", 1)[-1]
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise ClusterError(f"--address {address}: give HOST:PORT (e.g. 10.0.0.5:6379), ray://HOST:10001 or auto")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            pass
    except OSError as exc:
        raise ClusterError(f"cannot reach the Ray cluster at {address} ({exc.strerror or exc}); start its head "
                           f"with `ray start --head`, check the address, or leave out --address for a local "
                           f"instance") from None


def _start(ray, address: str | None, num_cpus: int | None) -> bool:
    """Connect to the cluster at ``address``, or start a local instance; True when this run started
    (and so must stop) it. A Ray already initialised in this process is used as it is."""
    if ray.is_initialized():
        return False
    try:
        if address:
            ray.init(address=address, log_to_driver=False, logging_level=logging.WARNING)
        else:   # "local": a new instance even when RAY_ADDRESS names a cluster
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, log_to_driver=False,
                     logging_level=logging.ERROR)
    except Exception as exc:
        where = f"the Ray cluster at {address}" if address else "a local Ray instance"
        raise ClusterError(f"cannot start or reach {where}: {' '.join(str(exc).split())}; start a head with "
                           f"`ray start --head`, or leave out --address for a local instance") from exc
    return not address


def render_shards(task_fn: Callable[[dict, int, str, int], dict], config: dict, shards: list[int], variant: str,
                  arrived: Callable[[int, dict], None], address: str | None = None,
                  num_cpus: int | None = None, cpus_per_task: int = 1) -> None:
    """Render ``shards`` of a dataset as Ray tasks, each ``task_fn(config, shard, variant, threads)`` (a
    module-level function, so Ray's workers import it; ``config`` a plain dict), calling ``arrived(shard,
    arrays)`` on this process as each one completes (in completion order).

    ``address``: a running cluster (``auto``, ``HOST:6379``, ``ray://HOST:10001``); None starts a
    local instance with ``num_cpus`` CPUs and stops it at the end. Each task asks for
    ``cpus_per_task`` CPUs (drjit uses as many threads) and, for a CUDA variant, one GPU.
    """
    ray = require_ray()
    if not shards:
        return
    started = _start(ray, address, num_cpus)
    pending: list = []
    try:
        gpus = 1 if variant.startswith("cuda") else 0
        if gpus and ray.cluster_resources().get("GPU", 0) < 1:
            raise ClusterError(f"Mitsuba variant {variant} needs a GPU, and the Ray cluster has none; use "
                               f"--variant llvm_ad_rgb, or add GPU nodes")
        task = ray.remote(task_fn).options(num_cpus=cpus_per_task, num_gpus=gpus,
                                                max_retries=MAX_RETRIES, retry_exceptions=False)
        shard_of = {task.remote(config, s, variant, 0 if gpus else cpus_per_task): s for s in shards}
        pending = list(shard_of)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            for ref in ready:
                try:
                    arrays = ray.get(ref)
                except ray.exceptions.RayTaskError as exc:   # the render raised: that error, not Ray's wrapper
                    cause = getattr(exc, "cause", None)
                    if isinstance(cause, Exception):
                        raise cause from exc
                    raise
                except ray.exceptions.RayError as exc:       # the worker died MAX_RETRIES + 1 times
                    raise ClusterError(f"shard {shard_of[ref]} failed on Ray after {MAX_RETRIES} retries "
                                       f"({type(exc).__name__}: {' '.join(str(exc).split())[:300]}); the "
                                       f"finished shards are kept: run again to resume") from exc
                arrived(shard_of[ref], arrays)
    finally:
        for ref in pending:   # interrupted, or a shard failed: stop the rest
            try:
                ray.cancel(ref, force=True)
            except Exception:
                pass
        if started:
            ray.shutdown()
