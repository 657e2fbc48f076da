"""Baking the SH convolution tables: recipe → compact exact form (+ dense grids).

The bake computes, in float64, the diffuse k_l, the specular k_l(θ′) at the
Chebyshev–Lobatto nodes of both θ′ halves (doubling the node count until the
series' tail is below ``CHEB_TOL`` of its largest coefficient), and takes the
Gaunt tensor.  Dense Rd/Rs on cube-map tangents and a θ′ grid are optional,
for shaders that want textures.
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..assets import recipe_hash
from ..baker import no_shard
from ..sh import gaunt
from ._io import write_sh_tables, write_textures
from ._kind import KIND
from ._recipe import full_recipe, resolve_recipe, specular_band_rule
from ._tables import Bands, SHTables
from ._zonal import cheb_coeffs, diffuse_coeffs, diffuse_nodes, lobatto_nodes, specular_coeffs, specular_nodes

CHEB_TOL = 1e-14
CHEB_START, CHEB_MAX = 16, 512


@functools.partial(jax.jit, static_argnames=("lmax_d", "lmax_s", "n_d", "n_s"))
def _zonal_kernel(p, nodes, lmax_d, lmax_s, n_d, n_s):
    """The bake's one jitted kernel: diffuse k_l and specular k_l at the θ′ nodes."""
    kd = diffuse_coeffs(lmax_d, n_d) if lmax_d >= 0 else None
    ks = specular_coeffs(lmax_s, n_s, p, nodes) if lmax_s >= 0 else None
    return kd, ks


def _zonal(p, nodes, lmax_d, lmax_s):
    with jax.enable_x64(True):
        kd, ks = _zonal_kernel(
            jnp.float64(p), jnp.asarray(nodes, jnp.float64), lmax_d, lmax_s,
            diffuse_nodes(max(lmax_d, 0)), specular_nodes(max(lmax_s, 0), p),
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
    g = gaunt(l_out, max(b.light_diffuse if kern["diffuse"] else 0, b.light_specular if kern["specular"] else 0) - 1,
              b.transmittance - 1)
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


def compute(recipe: dict | None = None, light=None) -> dict:
    """Compute everything a recipe asks for, in memory; ``light`` is an :class:`hairlut.envlight.EnvLight` or None.

    Returns a dict with the resolved ``recipe``, the exact ``tables``, bake
    ``info`` (Chebyshev nodes and tail, truncation error), optional ``dense``
    grids and optional ``light`` products (a, Cd, Cs).
    """
    from ..envlight import cube_dirs

    r = full_recipe(recipe, light)
    tables, info = bake_compact(r)
    info["theta_v_nodes"] = lobatto_nodes(info["chebyshev_nodes"])
    if tables.has_specular:
        info["truncation_error"] = truncation_error(tables, np.linspace(0.0, np.pi, 65))
    dense = None
    n = r["dense"]["t_resolution"]
    if n > 0:
        t_dirs, _ = cube_dirs(n)
        theta_v = np.linspace(0.0, np.pi, r["dense"]["theta_v_steps"])
        dense = {"t_dirs": t_dirs, "theta_v": theta_v, "n": n}
        if tables.has_diffuse:
            dense["rd"] = np.asarray(tables.rd(t_dirs))
        if tables.has_specular:
            dense["rs"] = np.asarray(tables.rs(t_dirs[:, None, :], theta_v[None, :]))
    products = None
    if light is not None:
        contracted = tables.contract(light.coeffs)
        products = {"a": light.coeffs, "channels": list(light.channels), "contracted": contracted}
        if dense is not None:
            if tables.has_diffuse:
                products["cd"] = np.asarray(contracted.cd(dense["t_dirs"]))
            if tables.has_specular:
                products["cs"] = np.asarray(contracted.cs(dense["t_dirs"][:, None, :], dense["theta_v"][None, :]))
    return {"recipe": r, "tables": tables, "info": info, "dense": dense, "light": products}


def bake(recipe: dict | None, out, *, progress=None, shard=None, light=None, textures=None) -> dict:
    """Bake a recipe into the ``sh_tables`` asset ``out`` (written atomically); the baker protocol's bake.

    ``light`` (an :class:`hairlut.envlight.EnvLight`) also bakes the contracted Cd/Cs; a recipe that
    names a light (its ``light`` section) needs that light.  ``textures``: also write Cd/Cs shader
    textures (EXR), which need a light and ``dense.t_resolution`` > 0.  SH tables cannot shard.
    ``progress(done, total)`` counts the two stages (tables, file)."""
    no_shard(KIND, shard)
    t0 = time.perf_counter()
    r = resolve_recipe(recipe, light)
    if "light" in r and light is None:
        raise errors.ValidationError("light", None, "the recipe names an environment light (source sha256 "
                                     f"{str(r['light']['source_sha256'])[:16]}…): pass that light")
    if textures and (light is None or r["dense"]["t_resolution"] == 0):
        raise errors.ValidationError("textures", str(textures), "needs --light and dense.t_resolution > 0")
    if progress:
        progress(0, 2)
    result = compute(r, light)
    if progress:
        progress(1, 2)
    path = write_sh_tables(out, result["tables"], result["info"], result["dense"], result["light"])
    tex = None
    if textures:
        lp = result["light"]
        tex = write_textures(textures, lp.get("cd"), lp.get("cs"), result["dense"]["n"], lp["channels"], r)
    if progress:
        progress(2, 2)
    info = result["info"]
    return {"out": str(path), "kind": KIND, "textures": None if tex is None else str(tex),
            "seconds": time.perf_counter() - t0, "bytes": Path(path).stat().st_size, "recipe": r,
            "recipe_hash": recipe_hash(r), "chebyshev_nodes": info["chebyshev_nodes"],
            "chebyshev_tail": info["chebyshev_tail"], "specular_truncation_error": info.get("truncation_error")}
