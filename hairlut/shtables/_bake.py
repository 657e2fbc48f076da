"""Baking the SH convolution tables: recipe → compact exact form (+ dense grids).

The bake computes, in float64, the diffuse k_l, the specular k_l(θ′) at the
Chebyshev–Lobatto nodes of both θ′ halves (doubling the node count until the
series' tail is below ``CHEB_TOL`` of its largest coefficient), and takes the
Gaunt tensor.  Dense Rd/Rs on cube-map tangents and a θ′ grid are optional,
for shaders that want textures.

The dense tables (Rd, Rs and, with a light, Cd, Cs at each cube-map tangent t) are the
bake's units: :mod:`hairlut.bake.sharding` splits them over ``t`` into resumable parts,
``--shard K/N`` slices and ``--distributed`` processes.  Each tangent is computed inside
one fixed micro-chunk of :data:`MICRO` tangents (chunk c holds tangents [c·MICRO,
(c+1)·MICRO), whatever the block, shard or process), by one executable spread over the
local devices (:func:`hairlut.bake.devices.map_units`), so its numbers do not depend on how
the bake was shared.  The compact tables are recomputed by each process (a fraction of a
second) and memoised per recipe.
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..assets import canonical_json, read_table, recipe_hash
from ..bake.devices import map_units
from ..sh import gaunt
from ._io import concat_parts, read_part, whole_tables, write_part, write_sh_tables, write_textures
from ._kind import KIND
from ._recipe import full_recipe, resolve_recipe
from ._tables import Bands, SHTables, _l_of_k, _rd_kernel, _rs_kernel
from ._zonal import cheb_coeffs, diffuse_coeffs, diffuse_nodes, lobatto_nodes, specular_coeffs, specular_nodes

CHEB_TOL = 1e-14
CHEB_START, CHEB_MAX = 16, 512
#: Tangents per micro-chunk of the dense tables: the fixed unit of work of one executable call.
MICRO = 32


@functools.partial(jax.jit, static_argnames=("lmax_d", "lmax_s", "n_d", "n_s"))
def _zonal_kernel(p, nodes, lmax_d, lmax_s, n_d, n_s):
    """The bake's one jitted kernel: diffuse k_l and specular k_l at the θ′ nodes."""
    kd = diffuse_coeffs(lmax_d, n_d) if lmax_d >= 0 else None
    ks = specular_coeffs(lmax_s, n_s, p, nodes) if lmax_s >= 0 else None
    return kd, ks


def _zonal(p, nodes, lmax_d, lmax_s):
    with jax.enable_x64(True):
        kd, ks = _zonal_kernel(
            jnp.float64(p),
            jnp.asarray(nodes, jnp.float64),
            lmax_d,
            lmax_s,
            diffuse_nodes(max(lmax_d, 0)),
            specular_nodes(max(lmax_s, 0), p),
        )
        return (None if kd is None else np.asarray(kd)), (None if ks is None else np.asarray(ks))


def bake_compact(recipe: dict) -> tuple[SHTables, dict]:
    """Bake the exact compact tables for a resolved recipe; returns (tables, bake info)."""
    kern, bands = recipe["kernel"], recipe["bands"]
    b = Bands(bands["light_diffuse"], bands["light_specular"], bands["transmittance"])
    lmax_d = b.light_diffuse + b.transmittance - 2 if kern["diffuse"] else -1
    lmax_s = b.light_specular + b.transmittance - 2 if kern["specular"] else -1
    p = kern["p"]
    fixed = recipe["quadrature"]["chebyshev"]
    n = fixed if fixed != "auto" else CHEB_START
    info = {"lmax_diffuse": lmax_d, "lmax_specular": lmax_s}
    while True:
        kd, ks = _zonal(p, lobatto_nodes(n), lmax_d, lmax_s)
        if ks is None:
            tail = 0.0
            break
        coeffs = cheb_coeffs(ks)
        scale = float(np.abs(coeffs).max()) or 1.0
        tail = float(np.abs(coeffs[:, -3:, :]).max()) / scale
        if fixed != "auto" or tail < CHEB_TOL or n >= CHEB_MAX:
            break
        n *= 2
    info.update({"chebyshev_nodes": n, "chebyshev_tail": tail, "specular_nodes": ks})
    l_out = max(lmax_d, lmax_s)
    g = gaunt(
        l_out,
        max(b.light_diffuse if kern["diffuse"] else 0, b.light_specular if kern["specular"] else 0) - 1,
        b.transmittance - 1,
    )
    tables = SHTables(b, p, kd, None if ks is None else cheb_coeffs(ks), g, recipe)
    return tables, info


def band_truncation_error(p: float, light_specular: int, theta_v=None) -> float:
    """Relative L2 energy of the specular lobe of exponent p above ``light_specular`` light
    bands, max over θ′ (default: 65 angles over [0, π]).

    For a zonal f, ‖f‖² = Σ_l k_l² (2l+1)/4π (Funk–Hecke and the addition
    theorem), and the total ‖f‖² = 2π ∫ f² sin θ dθ is the l = 0 coefficient of
    the same kernel with exponent 2p; the light keeps the bands l < light_specular.
    """
    lk = light_specular - 1
    theta_v = np.linspace(0.0, np.pi, 65) if theta_v is None else theta_v
    theta_v = jnp.asarray(np.atleast_1d(np.asarray(theta_v, np.float64)))
    with jax.enable_x64(True):
        k = np.asarray(specular_coeffs(lk, specular_nodes(lk, p), p, theta_v))
        total = np.asarray(specular_coeffs(0, specular_nodes(0, 2 * p), 2 * p, theta_v))[..., 0]
    kept = (k**2 * (2 * np.arange(lk + 1) + 1) / (4 * np.pi)).sum(-1)
    return float(np.sqrt(np.clip(1 - kept / total, 0, None)).max())


def truncation_error(tables: SHTables, theta_v) -> float:
    """:func:`band_truncation_error` of a table's exponent and light bands."""
    return band_truncation_error(tables.p, tables.bands.light_specular, theta_v)


def compact(recipe: dict) -> tuple[SHTables, dict]:
    """The compact tables of a resolved recipe and their bake info (nodes, tail, θ′ nodes, truncation error)."""
    tables, info = _compact(canonical_json(recipe))
    return tables, dict(info)


@functools.lru_cache(maxsize=8)
def _compact(text: str) -> tuple[SHTables, dict]:
    import json

    tables, info = bake_compact(json.loads(text))
    for name, arr in (("kernel/diffuse_k", tables.kd_l), ("kernel/specular_k", tables.ks_cheb), ("gaunt", tables.gaunt)):
        if arr is not None and not np.all(np.isfinite(arr)):  # finite or refused: never write NaN/Inf
            r = tables.recipe
            raise errors.NonFiniteError(
                f"sh_tables: {name} is not finite for kernel.p={r['kernel']['p']}, "
                f"bands.light_specular={r['bands']['light_specular']}, "
                f"bands.transmittance={r['bands']['transmittance']}"
            )
    info["theta_v_nodes"] = lobatto_nodes(info["chebyshev_nodes"])
    if tables.has_specular:
        info["truncation_error"] = truncation_error(tables, np.linspace(0.0, np.pi, 65))
    return tables, info


def tangent_grid(recipe: dict) -> tuple[np.ndarray, np.ndarray]:
    """(t_dirs (6n², 3), θ′ samples) of a recipe's dense tables (n = dense.t_resolution > 0)."""
    from ..envlight import cube_dirs

    t_dirs, _ = cube_dirs(recipe["dense"]["t_resolution"])
    return t_dirs, np.linspace(0.0, np.pi, recipe["dense"]["theta_v_steps"])


def _dense_units(t, theta_v, kd, cheb, gd, gs, hd, hs, l_of_k, *, lmax_d, lmax_s, diffuse, specular, light):
    """Rd, Rs (and with a light Cd, Cs) at a micro-chunk of tangents t (m, 3) (float64; eqs 2–5)."""
    out = []
    if diffuse:
        out.append(_rd_kernel(t, kd, gd, lmax_d))
    if specular:
        out.append(_rs_kernel(t[:, None, :], theta_v[None, :], cheb, gs, lmax_s, l_of_k))
    if light and diffuse:
        out.append(_rd_kernel(t, kd, hd, lmax_d).swapaxes(-1, -2))
    if light and specular:
        out.append(_rs_kernel(t[:, None, :], theta_v[None, :], cheb, hs, lmax_s, l_of_k).swapaxes(-1, -2))
    return tuple(out)


def dense_block(tables: SHTables, t_dirs, theta_v, start: int, stop: int, light=None) -> tuple[dict, dict | None]:
    """(dense, light products) of tangents [start, stop) of ``t_dirs`` (the whole grid), each computed in its fixed
    micro-chunk (module docstring); ``light`` an EnvLight or None."""
    total = len(t_dirs)
    lo, hi = start // MICRO * MICRO, min(total, -(-stop // MICRO) * MICRO)
    zero = np.zeros(1)
    d, s = tables.has_diffuse, tables.has_specular
    kd = tables.kd_l[_l_of_k(tables.lmax_d)] if d else zero
    gd = tables._g(tables.lmax_d, tables.bands.n_light_diffuse) if d else zero
    gs = tables._g(tables.lmax_s, tables.bands.n_light_specular) if s else zero
    hd = hs = zero
    if light is not None:
        con = tables.contract(light.coeffs)
        hd = np.asarray(con.hd).transpose(0, 2, 1) if d else zero
        hs = np.asarray(con.hs).transpose(0, 2, 1) if s else zero
    rep = (
        np.asarray(theta_v, np.float64),
        kd,
        tables.ks_cheb if s else zero,
        gd,
        gs,
        hd,
        hs,
        _l_of_k(tables.lmax_s) if s else np.zeros(1, np.int64),
    )
    with jax.enable_x64(True):
        outs = list(
            map_units(
                _dense_units,
                (np.asarray(t_dirs[lo:hi], np.float64),),
                rep,
                micro=MICRO,
                lmax_d=max(tables.lmax_d, 0),
                lmax_s=max(tables.lmax_s, 0),
                diffuse=d,
                specular=s,
                light=light is not None,
            )
        )
    outs = [o[start - lo : stop - lo] for o in outs]
    dense = {"t_dirs": np.asarray(t_dirs[start:stop]), "theta_v": np.asarray(theta_v)}
    for key, ok in (("rd", d), ("rs", s)):
        if ok:
            dense[key] = outs.pop(0)
    products = None
    if light is not None:
        products = {"a": light.coeffs, "channels": list(light.channels)}
        for key, ok in (("cd", d), ("cs", s)):
            if ok:
                products[key] = outs.pop(0)
    return dense, products


def compute(recipe: dict | None = None, light=None) -> dict:
    """Compute everything a recipe asks for, in memory; ``light`` is an :class:`hairlut.envlight.EnvLight` or None.

    Returns a dict with the resolved ``recipe``, the exact ``tables``, bake
    ``info`` (Chebyshev nodes and tail, truncation error), optional ``dense``
    grids and optional ``light`` products (a, Cd, Cs).  The dense grids are the
    numbers a (sharded) bake stores, before the storage dtype.
    """
    r = full_recipe(recipe, light)
    tables, info = compact(r)
    dense = products = None
    if r["dense"]["t_resolution"] > 0:
        t_dirs, theta_v = tangent_grid(r)
        dense, products = dense_block(tables, t_dirs, theta_v, 0, len(t_dirs), light)
        dense["n"] = r["dense"]["t_resolution"]
    if light is not None:
        products = {**(products or {}), "a": light.coeffs, "channels": list(light.channels)}
    if products is not None:
        products["contracted"] = tables.contract(light.coeffs)
    return {"recipe": r, "tables": tables, "info": info, "dense": dense, "light": products}


# ----------------------------------------------------------------------------- the shard path's pieces


def bake_part(recipe: dict, start: int, stop: int, total: int, path, light=None, **_) -> None:
    """Bake tangents [start, stop) into the ``sh_shard`` part ``path`` (the sharding path's unit of work)."""
    tables, _ = compact(recipe)
    t_dirs, theta_v = tangent_grid(recipe)
    if len(t_dirs) != total:
        raise errors.ValidationError("t", total, f"the recipe's tangent grid has {len(t_dirs)} tangents")
    dense, products = dense_block(tables, t_dirs, theta_v, start, stop, light)
    write_part(path, tables, dense, products, start, total)


def join_parts(recipe: dict, parts, out):
    """Consecutive parts as one ``sh_shard`` file (``--shard K/N``)."""
    read = [read_part(p, recipe) for p in parts]
    dense, light = concat_parts(read)
    return write_part(out, compact(recipe)[0], dense, light, read[0][2], read[0][3])


def assemble_parts(recipe: dict, parts, out, **_):
    """Parts covering every tangent as one self-contained ``sh_tables`` (the light's coefficients from the parts)."""
    tables, info = compact(recipe)
    dense, light = concat_parts([read_part(p, recipe) for p in parts])
    return write_sh_tables(out, tables, info, dense, light)


def whole_parts(recipe: dict, parts, **_):
    """What a virtual ``sh_tables`` stores itself: the compact tables, the whole axes, the light's coefficients."""
    tables, info = compact(recipe)
    dense, light, _, total = read_part(parts[0], recipe)
    return whole_tables(tables, info, {"total": total, "theta_v": dense["theta_v"]}, light)


def bake(
    recipe: dict | None,
    out,
    *,
    progress=None,
    shard=None,
    light=None,
    textures=None,
    block: int | None = None,
    keep_parts: bool = False,
    distributed=False,
    merge: str | None = None,
) -> dict:
    """Bake a recipe into the ``sh_tables`` asset ``out`` (written atomically): ``hairlut.bake.registry.bake`` of
    this kind.

    ``light`` (an :class:`hairlut.envlight.EnvLight`) also bakes the contracted Cd/Cs; a recipe that
    names a light (its ``light`` section) needs that light.  ``textures``: also write Cd/Cs shader
    textures (EXR), which need a light and ``dense.t_resolution`` > 0.  A recipe with dense tables
    bakes through :mod:`hairlut.bake.sharding` over its tangents (``block`` tangents per resumable part,
    ``shard`` 'K/N', ``distributed``, ``merge`` 'virtual' or 'copy'); ``progress(done, total)`` then
    counts tangents, else the two stages (tables, file)."""
    from ..bake import registry

    return registry.bake(
        KIND,
        recipe,
        out,
        progress=progress,
        shard=shard,
        distributed=distributed,
        merge=merge,
        options={"block": block, "keep_parts": keep_parts, "light": light, "textures": textures},
    )


def _check_light(r: dict, light, textures) -> None:
    if "light" in r and light is None:
        raise errors.ValidationError(
            "light",
            None,
            f"the recipe names an environment light (source sha256 {str(r['light']['source_sha256'])[:16]}…): pass that light",
        )
    if textures and (light is None or r["dense"]["t_resolution"] == 0):
        raise errors.ValidationError("textures", str(textures), "needs --light and dense.t_resolution > 0")


def bake_whole(r: dict, out, *, progress=None, light=None, textures=None, **_) -> dict:
    """The bake of a recipe without dense tables (seconds: no split); ``progress`` counts its two stages."""
    t0 = time.perf_counter()
    _check_light(r, light, textures)
    if progress:
        progress(0, 2)
    result = compute(r, light)
    if progress:
        progress(1, 2)
    path = write_sh_tables(out, result["tables"], result["info"], result["dense"], result["light"])
    if progress:
        progress(2, 2)
    return _report(r, result["info"], path, t0)


def start(r: dict, shard=None, light=None, textures=None, **_) -> None:
    """Refuse a split bake's inputs before any work: a missing light, textures without one or of a shard."""
    _check_light(r, light, textures)
    if textures and shard is not None:
        raise errors.ValidationError(
            "textures", str(textures), "a --shard file holds a slice: write textures from the merged asset"
        )


def report(r: dict, rep: dict, light=None, textures=None, **_) -> dict:
    """A split bake's own facts: the compact tables' bake info, and the Cd/Cs textures process 0 writes."""
    tex = None
    if textures and rep["process"] == 0:
        t = read_table(rep["out"], kind=KIND)
        tex = write_textures(
            textures,
            t["light/cd"] if "light/cd" in t.variables else None,
            t["light/cs"] if "light/cs" in t.variables else None,
            r["dense"]["t_resolution"],
            light.channels,
            r,
        )
    _, info = compact(r)
    facts = _report(r, info, rep["out"], time.perf_counter(), kind=rep["kind"])
    del facts["seconds"]
    return {**facts, "textures": None if tex is None else str(tex)}


def check_part(recipe: dict, path) -> None:
    """Refuse a part that lacks what ``join``/``assemble``/``whole`` read (a part of an older format)."""
    read_part(path, resolve_recipe(recipe))


def load_checked(path):
    """The ``sh_tables`` asset at ``path``; a virtual asset's parts are checked first (every part present and of
    this recipe)."""
    from ..assets.virtual_write import check_virtual
    from ._tables import load_sh_tables

    check_virtual(path)
    return load_sh_tables(path)


def _report(r: dict, info: dict, path, t0: float, kind: str = KIND) -> dict:
    return {
        "out": str(path),
        "kind": kind,
        "textures": None,
        "seconds": time.perf_counter() - t0,
        "bytes": Path(path).stat().st_size,
        "recipe": r,
        "recipe_hash": recipe_hash(r),
        "chebyshev_nodes": info["chebyshev_nodes"],
        "chebyshev_tail": info["chebyshev_tail"],
        "specular_truncation_error": info.get("truncation_error"),
    }
