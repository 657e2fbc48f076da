"""Baking the HRIR database: sample sectors, trace them in blocks, resume, shard, merge (satf §5).

Determinism: sector i is drawn as by ``sample_sectors(1, space, seed=sector_seed(seed, i))``
(``sample_each``: bitwise that, one block at a time), so it depends on the recipe's seed and i
alone, never on blocks or shards; its density and its HRIRs are computed one sector at a time
inside the jitted kernels (``chunk=1``: each sector by the one-sector program),
spread over every local device by :func:`hairlut.bake.devices.map_units`, so the numbers
do not depend on how sectors are grouped, nor on how many devices or processes share the
bake.  The block loop, resume, shards, ``--distributed`` processes and the final virtual
or copied asset are the one shard path of every kind, :mod:`hairlut.bake.sharding`; this
module supplies the ``hrir_db`` pieces (:func:`bake_part`, :func:`join_parts`,
:func:`assemble_parts`; the virtual index is ``_parts``).  A copied final file is assembled from the
part files alone, so an interrupted and an uninterrupted bake write the same bytes
(``created`` comes from SOURCE_DATE_EPOCH, 0 when unset).
"""

from __future__ import annotations

import numpy as np

from ..bake.devices import dispatch_units, free_memory
from ..geometry.density import sector_density
from ..geometry.sampler import sample_each
from ..geometry.splats import SplatBatch
from ..march import sector_geometry
from ._io import PARAMS, assemble, concat, read_shard, storage_errors, write_shard  # noqa: F401
from ._kind import KIND
from ._recipe import sector_space
from ._tracer import trace_kernel

BLOCK = 32
#: Blocks a bake is cut into at most when ``block`` is not given (:func:`auto_block`).
PIPELINE_BLOCKS = 16


def sector_seed(seed: int, index: int) -> int:
    """The sampler seed of sector ``index``: a SeedSequence spawn of (seed, index)."""
    state = np.random.SeedSequence(int(seed), spawn_key=(int(index),)).generate_state(2, np.uint32)
    return int((int(state[0]) << 31) ^ int(state[1]))


def sample_block(recipe: dict, start: int, stop: int) -> tuple[SplatBatch, dict]:
    """Splats and parameters of sectors [start, stop): each sector from its own seed, bitwise
    ``sample_sectors(1, space, seed=sector_seed(seed, i))``, the arithmetic done once for the block."""
    seed = recipe["sectors"]["seed"]
    drawn = sample_each([sector_seed(seed, i) for i in range(start, stop)], sector_space(recipe))
    return drawn.splats, {k: drawn.params[k] for k in (*PARAMS, "v_range")}


def trace_sectors(density, geometry, recipe: dict, *, views=None, lights=None, **overrides):
    """alpha (N, V, P) and reflectance (N, V, L, P) of sectors by the jitted kernel (float32).

    ``overrides`` replace ``trace`` settings (n_pix, n_steps, rays, shadow, smooth, eps).
    """
    return dispatch_trace(density, geometry, recipe, views=views, lights=lights, **overrides)()


def dispatch_trace(density, geometry, recipe: dict, *, views=None, lights=None, **overrides):
    """:func:`trace_sectors` enqueued on the devices; returns ``gather()``, which waits and returns (α, reflectance)."""
    from ..geometry import angle_grid

    tr, ph = recipe["trace"], recipe["phong"]
    cfg = {
        "n_pix": tr["pixels"],
        "n_steps": tr["steps"],
        "rays": tr["rays_per_pixel"],
        "shadow": tr["self_shadow"],
        "smooth": tr["smooth"],
        "eps": float(tr["termination"]),
    }
    cfg.update(overrides)
    V = recipe["angles"]["views"] if views is None else None
    views = angle_grid(V) if views is None else np.asarray(views)
    L = recipe["angles"]["lights"] if lights is None else None
    lights = angle_grid(L) if lights is None else np.asarray(lights)
    phong = np.array([ph["ambient"], ph["diffuse"], ph["specular"], ph["shininess"]])
    f32 = [np.asarray(x, np.float32) for x in (density, geometry, views, lights, phong)]
    return dispatch_units(_trace_units, tuple(f32[:2]), tuple(f32[2:]), **cfg)


def _trace_units(rho, geom, views, lights, phong, **cfg):
    """The per-device body: the tracer kernel on a device's sectors, one at a time (``chunk=1``)."""
    return trace_kernel(rho, geom, views, lights, phong, chunk=1, **cfg)


def bake_block(recipe: dict, start: int, stop: int) -> dict:
    """Everything stored for sectors [start, stop)."""
    return launch_block(recipe, start, stop)()


def launch_block(recipe: dict, start: int, stop: int):
    """Sample sectors [start, stop), compute their densities and enqueue their tracing on the devices.

    Returns ``finish()``, which waits for the devices and returns everything stored for the sectors
    (:func:`bake_block`): between the two the host is free to write the previous block."""
    splats, params = sample_block(recipe, start, stop)
    density = sector_density(splats, tuple(recipe["sectors"]["grid"]), density_scale=recipe["sectors"]["density_scale"], chunk=1)
    geometry = sector_geometry(
        params, kappa=recipe["trace"]["extinction"], n_pix=recipe["trace"]["pixels"], smooth_ratio=recipe["trace"]["smooth_ratio"]
    )
    gather = dispatch_trace(density, geometry, recipe)
    return lambda: _finished(recipe, start, stop, density, geometry, params, *gather())


def _finished(recipe: dict, start: int, stop: int, density, geometry, params, alpha, refl) -> dict:
    """Everything stored for sectors [start, stop).  Finite and within their physical bounds or refused, naming the
    recipe keys, when the part is written (the kind's ``BOUNDS``, :mod:`hairlut.assets.bounds`)."""
    return {
        "alpha": alpha,
        "reflectance": refl,
        "density": density,
        "geometry": geometry,
        "params": {k: params[k] for k in PARAMS},
    }


def bake_part(recipe: dict, start: int, stop: int, total: int, path, **_):
    """Start baking sectors [start, stop) into the ``hrir_shard`` part ``path`` (the sharding path's unit of work).

    Returns the step that completes it (wait for the devices, check, write the part): the shard path calls
    it once the next block is on the devices (:class:`hairlut.bake.protocol.Units`)."""
    finish = launch_block(recipe, start, stop)
    return lambda: write_shard(path, recipe, finish(), start, total)


def auto_block(recipe: dict, *, shared: bool = False) -> int:
    """Sectors per block when none is given: sized to the device's memory (else the host's budget).

    At least :data:`BLOCK` sectors (a part file and its checks cost the same for any size), and large
    enough that a bake has at most :data:`PIPELINE_BLOCKS` blocks (fewer, larger parts on a fast
    device), but no more sectors than fit in an eighth of the device's free memory (``memory_stats``;
    the host's budget, :func:`hairlut.budget.memory_limit`, where the device does not say, as on CPUs)
    at their inputs and outputs (two blocks are in flight: one traced while the other is written).  A
    multiple of :data:`BLOCK`.  The default database (512 sectors) keeps blocks of 32.  A ``shared`` bake
    (``--shard``, ``--distributed``: processes that may sit on other machines must cut the same blocks,
    and as many as there are shares) keeps :data:`BLOCK`."""
    from ..budget import memory_limit

    if shared:
        return BLOCK
    n = recipe["sectors"]["count"]
    want = -(-n // (PIPELINE_BLOCKS * BLOCK)) * BLOCK
    V, L, P = recipe["angles"]["views"], recipe["angles"]["lights"], recipe["trace"]["pixels"]
    n_s, n_r = recipe["sectors"]["grid"]
    per_sector = 4 * (V * P * (L + 1) + n_s * n_r + 32)
    room = free_memory()
    room = memory_limit() if room is None else min(room, memory_limit())
    fits = max(BLOCK, room // 8 // per_sector // BLOCK * BLOCK)
    return int(min(want, fits))


def join_parts(recipe: dict, parts, out):
    """Consecutive parts as one ``hrir_shard`` file (``--shard K/N``)."""
    read = [read_shard(p) for p in parts]
    data = concat([r[0] for r in read])
    return write_shard(out, recipe, data, read[0][1], read[0][2], errors_=data["errors"])


def assemble_parts(recipe: dict, parts, out, **_):
    """Parts covering every sector as one self-contained ``hrir_db``."""
    return assemble(out, recipe, concat([read_shard(p)[0] for p in parts]))


def bake(
    given: dict | None,
    out,
    *,
    shard=None,
    block: int | None = None,
    progress=None,
    keep_parts: bool = False,
    distributed=False,
    merge: str | None = None,
) -> dict:
    """Bake (or resume) the HRIR-DB of a recipe into ``out`` (written atomically): ``hairlut.bake.registry.bake``
    of this kind, split over its sectors (:mod:`hairlut.bake.sharding`).

    ``shard`` ('K/N' or (K, N)) bakes only that slice into an ``hrir_shard`` file for ``registry.merge``;
    ``distributed`` makes this process one of JAX's distributed processes (``merge`` 'virtual', the default
    there, or 'copy').  ``progress(done, total)`` is called with sector counts, first once with the resumed
    sectors, then as blocks complete.  Returns a report dict."""
    from ..bake import registry

    return registry.bake(
        KIND,
        given,
        out,
        progress=progress,
        shard=shard,
        distributed=distributed,
        merge=merge,
        options={"block": block, "keep_parts": keep_parts},
    )
