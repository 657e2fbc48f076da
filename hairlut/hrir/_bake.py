"""Baking the HRIR database: sample sectors, trace them in blocks, resume, shard, merge (satf §5).

Determinism: sector i is drawn by ``sample_sectors(1, space, seed=sector_seed(seed, i))``,
so it depends on the recipe's seed and i alone, never on blocks or shards; its density
and its HRIRs are computed one sector at a time inside the jitted kernels (``chunk=1``),
so the numbers do not depend on how sectors are grouped either.  Completed blocks are
written atomically to ``<out>.parts/`` as ``hrir_shard`` files; a rerun reuses every
valid part with the same recipe hash, and the final file is assembled from the part
files alone, so an interrupted and an uninterrupted bake write the same bytes
(``created`` comes from SOURCE_DATE_EPOCH, 0 when unset).
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .. import errors
from ..assets import canonical_json, recipe_hash
from ..baker import parse_shard
from ..geometry.density import sector_density
from ..geometry.sampler import sample_sectors
from ..geometry.splats import SplatBatch
from ._geometry import sector_geometry
from ._io import PARAMS, assemble, concat, read_shard, write_shard
from ._recipe import resolve_recipe, sector_space
from ._tracer import trace_kernel

BLOCK = 32


def sector_seed(seed: int, index: int) -> int:
    """The sampler seed of sector ``index``: a SeedSequence spawn of (seed, index)."""
    state = np.random.SeedSequence(int(seed), spawn_key=(int(index),)).generate_state(2, np.uint32)
    return int((int(state[0]) << 31) ^ int(state[1]))


def sample_block(recipe: dict, start: int, stop: int) -> tuple[SplatBatch, dict]:
    """Splats and parameters of sectors [start, stop)."""
    space = sector_space(recipe)
    drawn = [sample_sectors(1, space, seed=sector_seed(recipe["sectors"]["seed"], i)) for i in range(start, stop)]
    fields = ("center", "sigma", "radius", "mask", "area_scale", "v_range")
    splats = SplatBatch(*(np.concatenate([getattr(d.splats, f) for d in drawn]) for f in fields))
    params = {k: np.concatenate([d.params[k] for d in drawn]) for k in (*PARAMS, "v_range")}
    return splats, params


def trace_sectors(density, geometry, recipe: dict, *, views=None, lights=None, **overrides):
    """alpha (N, V, P) and reflectance (N, V, L, P) of sectors by the jitted kernel (float32).

    ``overrides`` replace ``trace`` settings (n_pix, n_steps, rays, shadow, smooth, eps).
    """
    from ..geometry import angle_grid

    tr, ph = recipe["trace"], recipe["phong"]
    cfg = {"n_pix": tr["pixels"], "n_steps": tr["steps"], "rays": tr["rays_per_pixel"], "shadow": tr["self_shadow"],
           "smooth": tr["smooth"], "eps": float(tr["termination"])}
    cfg.update(overrides)
    V = recipe["angles"]["views"] if views is None else None
    views = angle_grid(V) if views is None else np.asarray(views)
    L = recipe["angles"]["lights"] if lights is None else None
    lights = angle_grid(L) if lights is None else np.asarray(lights)
    phong = np.array([ph["ambient"], ph["diffuse"], ph["specular"], ph["shininess"]])
    a, r = trace_kernel(jnp.asarray(density, jnp.float32), jnp.asarray(geometry, jnp.float32),
                        jnp.asarray(views, jnp.float32), jnp.asarray(lights, jnp.float32),
                        jnp.asarray(phong, jnp.float32), chunk=1, **cfg)
    return np.asarray(a), np.asarray(r)


def bake_block(recipe: dict, start: int, stop: int) -> dict:
    """Everything stored for sectors [start, stop)."""
    splats, params = sample_block(recipe, start, stop)
    density = sector_density(splats, tuple(recipe["sectors"]["grid"]), density_scale=recipe["sectors"]["density_scale"],
                             chunk=1)
    geometry = sector_geometry(params, kappa=recipe["trace"]["extinction"], n_pix=recipe["trace"]["pixels"],
                               smooth_ratio=recipe["trace"]["smooth_ratio"])
    alpha, refl = trace_sectors(density, geometry, recipe)
    return {"alpha": alpha, "reflectance": refl, "density": density, "geometry": geometry,
            "params": {k: params[k] for k in PARAMS}}


def blocks_of(total: int, block: int, shard: tuple[int, int] | None = None) -> list[tuple[int, int]]:
    """The (start, stop) blocks of a bake, or of shard (K, N): the K-th of N contiguous runs of blocks."""
    blocks = [(s, min(s + block, total)) for s in range(0, total, block)]
    if shard is None:
        return blocks
    k, n = shard
    return blocks[k * len(blocks) // n:(k + 1) * len(blocks) // n]


def parts_dir(out) -> Path:
    out = Path(out)
    return out.with_name(out.name + ".parts")


def _intact(part, recipe_hash: str) -> bool:
    """Whether a completed part validates against the recipe (resumable)."""
    try:
        read_shard(part, recipe_hash)
    except errors.AssetError:
        return False
    return True


def bake(given: dict | None, out, *, shard=None, block: int = BLOCK, progress=None, keep_parts: bool = False) -> dict:
    """Bake (or resume) the HRIR-DB of a recipe into ``out`` (written atomically).

    ``shard`` ('K/N' or (K, N)) bakes only that slice into an ``hrir_shard`` file for
    :func:`merge`.  ``progress(done, total)`` is called with sector counts as blocks
    complete (resumed blocks first).  Returns a report dict.
    """
    r = resolve_recipe(given)
    if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
        raise errors.ValidationError("block", block, "must be an integer ≥ 1")
    sh = None if shard is None else parse_shard(shard)
    total = r["sectors"]["count"]
    todo = blocks_of(total, int(block), sh)
    if not todo:
        raise errors.ValidationError("shard", shard, f"empty: {total} sectors make fewer blocks than shards")
    want = todo[-1][1] - todo[0][0]
    h = recipe_hash(canonical_json(r))
    folder = parts_dir(out)
    t0 = time.perf_counter()
    done, resumed, computed = 0, 0, 0
    paths = []
    for s, e in todo:
        part = folder / f"part-{s:09d}-{e:09d}.h5"
        paths.append(part)
        if part.exists():
            if _intact(part, h):  # a damaged or stale part is baked again
                resumed += e - s
                done += e - s
                if progress:
                    progress(done, want)
                continue
        write_shard(part, r, bake_block(r, s, e), s, total)
        computed += e - s
        done += e - s
        if progress:
            progress(done, want)
    data = concat([read_shard(p, h)[0] for p in paths])
    if sh is None:
        path = assemble(out, r, data)
    else:
        path = write_shard(out, r, data, todo[0][0], total)
    if not keep_parts:
        shutil.rmtree(folder, ignore_errors=True)
    return {"out": str(path), "kind": "hrir_db" if sh is None else "hrir_shard", "sectors": want,
            "sector_range": [todo[0][0], todo[-1][1]], "total_sectors": total, "computed": computed,
            "resumed": resumed, "seconds": time.perf_counter() - t0, "bytes": Path(path).stat().st_size,
            "recipe_hash": h}


def merge(shards, out) -> dict:
    """Join ``hrir_shard`` files covering every sector of one recipe into an ``hrir_db``."""
    if not shards:
        raise errors.ValidationError("shards", shards, "give at least one shard")
    items = []
    for p in shards:
        data, start, total, recipe = read_shard(p)
        items.append((start, total, recipe, data, p))
    items.sort(key=lambda x: x[0])
    h0 = recipe_hash(canonical_json(items[0][2]))
    pos = 0
    for start, total, recipe, data, p in items:
        if recipe_hash(canonical_json(recipe)) != h0 or total != items[0][1]:
            raise errors.CorruptAssetError(p, "shard of a different bake (recipe or sector count differs)")
        if start != pos:
            raise errors.CorruptAssetError(p, f"sectors {pos}..{start - 1} are missing or overlap" if start > pos
                                           else f"overlaps the previous shard at sector {start}")
        pos = start + len(data["alpha"])
    if pos != items[0][1]:
        raise errors.ValidationError("shards", [str(i[4]) for i in items], f"cover sectors 0..{pos - 1} of {items[0][1]}")
    path = assemble(out, items[0][2], concat([i[3] for i in items]))
    return {"out": str(path), "shards": len(items), "sectors": pos, "bytes": Path(path).stat().st_size, "recipe_hash": h0}
