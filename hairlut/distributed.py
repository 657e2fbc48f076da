"""JAX's own scale-out for bakes: every local device (``jax.sharding``), many processes (``jax.distributed``).

:func:`map_units` runs a per-unit kernel over a block of units (sectors, tangents) split
across every local device with a 1-D :class:`jax.sharding.Mesh` and ``shard_map``.  Units
are cut into micro-chunks of a fixed size *before* they are dealt to devices, and each
call of the sharded kernel gives every device exactly one chunk (calls are dispatched
asynchronously, so devices stay busy); so every unit is computed by the same compiled
per-device program on the same neighbours whatever the device count.  (A loop over a
device's chunks inside the kernel would not do: XLA compiles loops of different trip
counts differently, and the last bits of float32 results move.)  A bake is bitwise
identical on 1 or N devices (tested with ``JAX_NUM_CPU_DEVICES``).

:func:`initialize` joins JAX's distributed runtime (``jax.distributed.initialize``): with
no arguments where JAX detects the cluster itself (SLURM, Open MPI, …), or with an explicit
coordinator ``HOST:PORT``, process count and process id.  Processes talk only through
:func:`barrier`; each computes its own share on its own devices (:mod:`hairlut.parts`).
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import numpy as np

from . import errors

_ADDRESS = re.compile(r"^\[?[A-Za-z0-9_.:\-]+\]?:(\d{1,5})$")


@dataclass(frozen=True)
class Process:
    """This process's place in a (possibly one-process) bake."""

    index: int = 0
    count: int = 1

    @property
    def leader(self) -> bool:
        return self.index == 0


def check_args(coordinator=None, num_processes=None, process_id=None) -> None:
    """Validate explicit ``jax.distributed`` arguments (all three or none)."""
    given = {"coordinator": coordinator, "num_processes": num_processes, "process_id": process_id}
    if any(v is not None for v in given.values()) and any(v is None for v in given.values()):
        missing = [k for k, v in given.items() if v is None]
        raise errors.ValidationError(missing[0], None, "give --coordinator, --num-processes and --process-id together "
                                     "(or none of them where JAX detects the cluster: SLURM, Open MPI, ...)")
    if coordinator is None:
        return
    m = _ADDRESS.match(str(coordinator))
    if not m or not 0 < int(m.group(1)) < 65536:
        raise errors.ValidationError("coordinator", coordinator, "use HOST:PORT, e.g. 127.0.0.1:12355")
    if isinstance(num_processes, bool) or not isinstance(num_processes, int | np.integer) or num_processes < 1:
        raise errors.ValidationError("num_processes", num_processes, "must be an integer ≥ 1")
    if isinstance(process_id, bool) or not isinstance(process_id, int | np.integer) or not 0 <= process_id < num_processes:
        raise errors.ValidationError("process_id", process_id, f"need 0 ≤ process_id < {num_processes}")


def initialize(coordinator=None, num_processes=None, process_id=None, timeout_s: int = 300) -> Process:
    """Join JAX's distributed runtime (once per process) and return this process's place in it."""
    check_args(coordinator, num_processes, process_id)
    import jax

    if not jax.distributed.is_initialized():
        kwargs = {} if coordinator is None else {"coordinator_address": str(coordinator),
                                                 "num_processes": int(num_processes), "process_id": int(process_id)}
        try:
            jax.distributed.initialize(**kwargs, initialization_timeout=int(timeout_s))
        except (RuntimeError, ValueError) as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise errors.ValidationError("distributed", coordinator or "auto-detect",
                                         f"jax.distributed.initialize failed: {first}") from None
    return current()


def current() -> Process:
    """(process index, process count) of JAX's runtime; (0, 1) when it is not distributed."""
    import jax

    if not jax.distributed.is_initialized():
        return Process()
    return Process(jax.process_index(), jax.process_count())


def barrier(name: str) -> None:
    """Wait until every process of a distributed run reaches ``name`` (no-op for one process)."""
    if current().count <= 1:
        return
    from jax.experimental import multihost_utils

    multihost_utils.sync_global_devices(name)


def local_devices() -> list:
    import jax

    return list(jax.local_devices())


@functools.lru_cache(maxsize=64)
def _kernel(fn, static: tuple):
    """jit(fn) on one micro-chunk: the one executable every device runs."""
    import jax

    kw = dict(static)
    return jax.jit(lambda xs, rep: fn(*xs, *rep, **kw))


def map_units(fn, sharded: tuple, replicated: tuple = (), *, micro: int = 1, devices: int | None = None,
              **static) -> tuple[np.ndarray, ...]:
    """``fn(*micro_chunk_of_sharded, *replicated, **static)`` over every unit, on every local device.

    ``sharded`` arrays share their leading (unit) axis; ``fn`` maps (micro, ...) arrays to a
    tuple of (micro, ...) arrays and must be a module-level function (it keys the compile
    cache).  Units are padded with copies of the last one to whole micro-chunks; chunk c
    runs on local device c mod D (``devices`` caps D; default all local devices), each call
    dispatched asynchronously, the replicated inputs placed once per device.
    """
    import jax

    n = len(sharded[0])
    if n == 0 or any(len(a) != n for a in sharded):
        raise errors.ValidationError("units", [len(a) for a in sharded], "sharded inputs need one equal, non-zero length")
    devs = local_devices()
    devs = devs if devices is None else devs[:max(1, min(int(devices), len(devs)))]
    chunks = -(-n // micro)
    kernel = _kernel(fn, tuple(sorted(static.items())))
    rep = {d: tuple(jax.device_put(np.asarray(r), d) for r in replicated) for d in devs}
    xs = []
    for a in sharded:
        a = np.asarray(a)
        if chunks * micro > n:
            a = np.concatenate([a, np.repeat(a[-1:], chunks * micro - n, axis=0)])
        xs.append(a)
    calls = []
    for c in range(chunks):
        d = devs[c % len(devs)]
        calls.append(kernel(tuple(jax.device_put(x[c * micro:(c + 1) * micro], d) for x in xs), rep[d]))
    outs = [np.concatenate([np.asarray(call[i]) for call in calls]) for i in range(len(calls[0]))]
    return tuple(o[:n] for o in outs)
