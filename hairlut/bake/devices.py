"""JAX's own scale-out for bakes: every local device, many processes (``jax.distributed``).

:func:`map_units` runs a per-unit kernel over a block of units (sectors, tangents) on every
local device.  Units are cut into micro-chunks of a fixed size *before* they are dealt to
devices; chunk c runs on device c mod D as one call of one single-device executable
(``jax.jit`` of the kernel on one micro-chunk, inputs placed with ``jax.device_put``),
dispatched asynchronously so that every device stays busy.  So every unit is computed by the
same compiled program on the same neighbours whatever the device count, and a bake is
bitwise identical on 1 or N devices (tested with ``JAX_NUM_CPU_DEVICES``).

*Why not one SPMD program* (a 1-D ``Mesh`` with ``shard_map``, or ``jit`` on ``NamedSharding``
inputs), which the issue proposed: it does not give the one-device bits.  Measured by
``benchmarks/spmd_bits.py`` (JAX 0.10.2, 2 CPU devices, 8 HRIR sectors, 8 × 8 angles, 16 px,
16 steps; against one sector per call on one device): ``shard_map`` with one sector per device
per call (the very same per-device shapes) changes 632 of 8,192 reflectance values by up to
11 float32 ULPs (2.7e-7 absolute); with four sectors per device, or ``jit`` on ``NamedSharding``
inputs, 896 of 8,192 by up to 226 ULPs (2.1e-6) and 21 of 1,024 α values.  The batch alone
also moves bits (two sectors per call on one device: 165 reflectance values), which is why the
micro-chunk is fixed.  The round-robin dispatch costs one Python call per chunk, negligible
against a sector's trace; it keeps the determinism rule (DESIGN.md: bitwise-identical assets
however many devices shared the bake).

:func:`map_chunks` does the same for host-driven work (a function that calls jitted kernels itself,
such as the scene table's view-grid tracer): fixed micro-chunks dealt round-robin, one host thread per
device with that device as JAX's default.

:func:`initialize` joins JAX's distributed runtime (``jax.distributed.initialize``): with
no arguments where JAX detects the cluster itself (SLURM, Open MPI, …), or with an explicit
coordinator ``HOST:PORT``, process count and process id.  Processes talk only through
:func:`agree` (before a bake) and :func:`barrier`, and part with :func:`leave`; each computes its own
share on its own devices (:mod:`hairlut.bake.sharding`).  How they join, wait and fail is
:mod:`hairlut.bake.coordination`'s.
"""

from __future__ import annotations

import functools
import re

import numpy as np

from .. import errors
from .coordination import TIMEOUT_S, Process, active, join

_ADDRESS = re.compile(r"^\[?[A-Za-z0-9_.:\-]+\]?:(\d{1,5})$")


def check_args(coordinator=None, num_processes=None, process_id=None) -> None:
    """Validate explicit ``jax.distributed`` arguments (all three or none)."""
    given = {"coordinator": coordinator, "num_processes": num_processes, "process_id": process_id}
    if any(v is not None for v in given.values()) and any(v is None for v in given.values()):
        missing = [k for k, v in given.items() if v is None]
        raise errors.ValidationError(
            missing[0],
            None,
            "give --coordinator, --num-processes and --process-id together "
            "(or none of them where JAX detects the cluster: SLURM, Open MPI, ...)",
        )
    if coordinator is None:
        return
    m = _ADDRESS.match(str(coordinator))
    if not m or not 0 < int(m.group(1)) < 65536:
        raise errors.ValidationError("coordinator", coordinator, "use HOST:PORT, e.g. 127.0.0.1:12355")
    if isinstance(num_processes, bool) or not isinstance(num_processes, int | np.integer) or num_processes < 1:
        raise errors.ValidationError("num_processes", num_processes, "must be an integer ≥ 1")
    if isinstance(process_id, bool) or not isinstance(process_id, int | np.integer) or not 0 <= process_id < num_processes:
        raise errors.ValidationError("process_id", process_id, f"need 0 ≤ process_id < {num_processes}")


def initialize(coordinator=None, num_processes=None, process_id=None, timeout_s: float = TIMEOUT_S, on_fatal=None) -> Process:
    """Join JAX's distributed runtime (once per process) and return this process's place in it.

    ``timeout_s``: how long to wait for a peer that has not come or has stopped answering.  ``on_fatal(message)``
    (the command line's): called instead of JAX's abort with the one line to show (None: the bake had finished),
    and must not return; see :mod:`hairlut.bake.coordination`.

    Call it before anything that runs JAX, as ``hairlut bake --distributed`` does: JAX joins only before its
    backend starts, and building a scene's recipe already runs it (the planner fits the clusters to choose the
    sector grid, :func:`hairlut.planner.scene_maps_recipe`)."""
    check_args(coordinator, num_processes, process_id)
    join(coordinator, num_processes, process_id, timeout_s, on_fatal)
    return current()


def current() -> Process:
    """(process index, process count) of JAX's runtime; (0, 1) when it is not distributed."""
    session = active()
    if session is not None:
        return session.proc
    import jax

    if not jax.distributed.is_initialized():
        return Process()
    return Process(jax.process_index(), jax.process_count())


#: How long a process waits at a barrier for the others (the parts barrier waits for the slowest share's bake).
BARRIER_TIMEOUT_S = 7 * 24 * 3600


def barrier(name: str, timeout_s: float = BARRIER_TIMEOUT_S) -> None:
    """Wait until every process of a distributed run reaches ``name`` (no-op for one process).

    Through the coordination service that ``jax.distributed.initialize`` started, not a device collective: a
    collective's first call sets up the CPU transport (gloo), whose connect times out after seconds, so a
    process that finished its share first would fail while a slower one was still baking.  In a session
    (:func:`initialize`) a dead or failed peer ends the wait with an error that names it
    (:meth:`hairlut.bake.coordination.Session.barrier`)."""
    if current().count <= 1:
        return
    session = active()
    if session is not None:
        session.barrier(name, timeout_s)
        return
    from jax._src import distributed as jax_distributed  # the runtime's client: JAX has no public barrier

    client = jax_distributed.global_state.client
    try:
        client.wait_at_barrier(str(name), int(timeout_s * 1000))
    except Exception as exc:  # XlaRuntimeError (deadline, a peer gone): a typed, one-line error
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise errors.ValidationError("distributed", name, f"barrier failed: {first}") from None


def agree(fields: dict, recipe: dict | None = None) -> None:
    """Refuse a bake whose ``fields`` (recipe hash, output, blocks) or ``recipe`` differ between processes,
    before any work, naming the difference (no-op outside a session)."""
    session = active()
    if session is not None and session.proc.count > 1:
        session.agree(fields, recipe)


def leave(exc: BaseException | None = None) -> None:
    """End this process's part in the distributed run: after ``exc``, tell the others; shut JAX's client down."""
    session = active()
    if session is not None:
        session.leave(exc)


def local_devices() -> list:
    import jax

    return list(jax.local_devices())


def map_chunks(fn, n: int, *, micro: int, devices: int | None = None) -> list:
    """``[fn(start, stop) for each micro-chunk of range(n)]``, chunk c run with local device c mod D as JAX's default.

    For host-driven work (a function that calls jitted kernels and returns NumPy): one host thread per device
    (``jax.default_device`` is per thread; XLA releases the GIL while it computes), chunks of fixed size
    ``micro`` dealt round-robin, results in chunk order.  A chunk's numbers are the same whatever the device
    count when ``fn``'s are independent of the device, as they are on identical devices."""
    import jax

    chunks = [(s, min(s + micro, n)) for s in range(0, n, micro)]
    devs = local_devices()
    devs = devs if devices is None else devs[: max(1, min(int(devices), len(devs)))]
    if len(devs) == 1 or len(chunks) == 1:
        return [fn(s, e) for s, e in chunks]

    def work(d: int) -> list:
        with jax.default_device(devs[d]):
            return [(c, fn(*chunks[c])) for c in range(d, len(chunks), len(devs))]

    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(len(devs)) as pool:
        done = [r for rs in pool.map(work, range(len(devs))) for r in rs]
    return [r for _, r in sorted(done, key=lambda x: x[0])]


@functools.lru_cache(maxsize=64)
def _kernel(fn, static: tuple):
    """jit(fn) on one micro-chunk: the one executable every device runs."""
    import jax

    kw = dict(static)
    return jax.jit(lambda xs, rep: fn(*xs, *rep, **kw))


def map_units(
    fn, sharded: tuple, replicated: tuple = (), *, micro: int = 1, devices: int | None = None, **static
) -> tuple[np.ndarray, ...]:
    """``fn(*micro_chunk_of_sharded, *replicated, **static)`` over every unit, on every local device.

    ``sharded`` arrays share their leading (unit) axis; ``fn`` maps (micro, ...) arrays to a
    tuple of (micro, ...) arrays and must be a module-level function (it keys the compile
    cache).  Units are padded with copies of the last one to whole micro-chunks; chunk c
    runs on local device c mod D (``devices`` caps D; default all local devices), each call
    dispatched asynchronously, the replicated inputs placed once per device.
    """
    return dispatch_units(fn, sharded, replicated, micro=micro, devices=devices, **static)()


def dispatch_units(fn, sharded: tuple, replicated: tuple = (), *, micro: int = 1, devices: int | None = None, **static):
    """:func:`map_units` without waiting: every call is enqueued on its device, and the returned ``gather()``
    waits for them and returns the NumPy outputs.  The host is free in between (JAX's asynchronous
    dispatch): a bake writes one block while the devices compute the next."""
    import jax

    n = len(sharded[0])
    if n == 0 or any(len(a) != n for a in sharded):
        raise errors.ValidationError("units", [len(a) for a in sharded], "sharded inputs need one equal, non-zero length")
    devs = local_devices()
    devs = devs if devices is None else devs[: max(1, min(int(devices), len(devs)))]
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
        calls.append(kernel(tuple(jax.device_put(x[c * micro : (c + 1) * micro], d) for x in xs), rep[d]))

    def gather() -> tuple[np.ndarray, ...]:
        outs = [np.concatenate([np.asarray(call[i]) for call in calls]) for i in range(len(calls[0]))]
        return tuple(o[:n] for o in outs)

    return gather


def free_memory() -> int | None:
    """Bytes free on the most loaded local device (``memory_stats``: limit − in use); None where unknown (CPU)."""
    free = []
    for d in local_devices():
        try:
            stats = d.memory_stats()
        except (AttributeError, NotImplementedError, RuntimeError):
            stats = None  # a backend that keeps no allocator statistics (the CPU): the free memory is unknown
        if not stats or "bytes_limit" not in stats:
            return None
        free.append(int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0)))
    return min(free) if free else None
