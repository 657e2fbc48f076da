"""Baking the ``hair_bsdf`` tables: recipe → converged values with per-entry errors → HDF5 (and the EXR atlas).

The numbers come from :mod:`hairlut.hairbsdf._integrals` (deterministic quadrature of Chiang et al. 2016's
fibre in θ and φ, with an error estimate per entry), entry by entry, so a sin θ row's numbers do not depend on
which rows a part, a device or a process bakes with it (a part's rows are dealt one by one to the local devices,
:func:`hairlut.bake.devices.map_chunks`).  This module is the kind's side of the bake: the units of the
one shard path (:mod:`hairlut.bake.sharding`: parts of sin θ rows, ``--shard``, ``--distributed``, virtual or
copied assets), the whole bake of a coverage-only recipe, and the report.
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import canonical_json, open_table, recipe_hash
from ..bake.devices import map_chunks
from ._io import _largest, read_part, whole_tables, write_assembled, write_asset, write_joined, write_part
from ._kind import KIND
from ._recipe import grid_axes, grid_tables, physics_axes, quantities, resolve_recipe


def _physics():
    """The quadrature module (imported on first use: it loads JAX)."""
    from . import _integrals

    return _integrals


def _model(recipe: dict) -> dict:
    return {"eta": recipe["bsdf"]["eta"], "alpha": recipe["bsdf"]["alpha"]}


def _quadrature(recipe: dict, refine: int = 1) -> dict:
    q = recipe["quadrature"]
    return {"nodes": refine * q["nodes"], "levels": q["levels"], "coverage_nodes": refine * q["coverage_nodes"]}


def _split(table: str, values) -> dict[str, np.ndarray]:
    """{quantity: (…) float64} of a physics table whose last axis holds its fields."""
    fields = _physics().DUAL_SCATTERING_FIELDS if table == "dual_scattering" else _physics().MEAN_ENERGY_FIELDS
    v = np.asarray(values, np.float64)
    return {name: np.ascontiguousarray(v[..., i]) for i, name in enumerate(fields)}


def grid_rows(recipe: dict, start: int, stop: int, *, refine: int = 1) -> tuple[dict, dict]:
    """({quantity: values}, {quantity: error estimates}) of sin θ rows [start, stop) of the recipe's grid tables,
    float64 arrays of shape (stop − start, n_roughness, n_absorption); ``refine``: that many times the quadrature's
    Gauss–Legendre nodes per panel in every integration axis (a reference)."""
    axes, resolution = physics_axes(recipe)
    got = _physics().tables(
        axes,
        resolution,
        quadrature=_quadrature(recipe, refine),
        model=_model(recipe),
        which=grid_tables(recipe),
        start=start,
        stop=stop,
    )
    values, errs = {}, {}
    for table, (v, e) in got.items():
        values.update(_split(table, v))
        errs.update(_split(table, e))
    return values, errs


def montecarlo_rows(recipe: dict, start: int, stop: int, *, scale: float = 1, seed: int = 0) -> dict:
    """{quantity: values} of sin θ rows [start, stop) of the recipe's grid tables by Unreal's uniform Monte Carlo
    estimator (the benchmark's baseline) at ``scale`` times Unreal's sample count (√scale times its strata on each
    axis), float64 arrays of shape (stop − start, n_roughness, n_absorption)."""
    axes, resolution = physics_axes(recipe)
    got = _physics().montecarlo_unreal(
        axes,
        resolution,
        sample_scale=float(np.sqrt(scale)),
        seed=seed,
        model=_model(recipe),
        which=grid_tables(recipe),
        start=start,
        stop=stop,
    )
    out = {}
    for table, v in got.items():
        out.update(_split(table, v))
    return out


def sigma_a(recipe: dict) -> np.ndarray | None:
    """σ_a (n_roughness, n_absorption) at the grid's nodes (the colour axis maps through Chiang et al.'s eq. 9
    at β_n = the roughness); None without grid tables."""
    if not grid_tables(recipe):
        return None
    ax = grid_axes(recipe)
    return np.asarray(_physics().absorption_sigma(ax["absorption"], ax["roughness"], recipe["absorption"]["axis"]))


def coverage_table(recipe: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """(values, error estimates) of the coverage table over (radius, strands), float64; None when not baked."""
    if not recipe["coverage"]["bake"]:
        return None
    return _coverage(canonical_json(recipe))


@functools.lru_cache(maxsize=4)
def _coverage(text: str):
    import json

    recipe = json.loads(text)
    axes, resolution = physics_axes(recipe)
    v, e = _physics().tables(axes, resolution, quadrature=_quadrature(recipe), model=_model(recipe), which=("coverage",))[
        "coverage"
    ]
    return np.asarray(v, np.float64), np.asarray(e, np.float64)


# ----------------------------------------------------------------------------- the shard path's pieces


def bake_part(recipe: dict, start: int, stop: int, total: int, path, **_) -> Path:
    """Bake sin θ rows [start, stop) into the ``hair_bsdf_shard`` part ``path``."""
    if total != recipe["grid"]["resolution"][0]:
        raise errors.ValidationError("sin_theta", total, f"the recipe's grid has {recipe['grid']['resolution'][0]} sin θ rows")
    done = map_chunks(lambda s, e: grid_rows(recipe, start + s, start + e), stop - start, micro=1)  # every local device
    values = {k: np.concatenate([d[0][k] for d in done]) for k in done[0][0]}
    errs = {k: np.concatenate([d[1][k] for d in done]) for k in done[0][1]}
    return write_part(path, recipe, values, errs, start, total)


def join_parts(recipe: dict, parts, out) -> Path:
    """Consecutive parts as one ``hair_bsdf_shard`` file (``--shard K/N``)."""
    return write_joined(out, recipe, [read_part(p, recipe) for p in parts])


def assemble_parts(recipe: dict, parts, out, **_) -> Path:
    """Parts covering every sin θ row as one self-contained ``hair_bsdf`` asset (the coverage table computed here)."""
    return write_assembled(out, recipe, [read_part(p, recipe) for p in parts], coverage_table(recipe), sigma_a(recipe))


def part_index(recipe: dict, path, **_) -> dict[str, np.ndarray]:
    """What :func:`whole_parts` reads from one part: its largest error bound."""
    with open_table(path, f"{KIND}_shard") as f:
        return {"max_error": np.array([float(f.attrs["max_error"])])}


def whole_parts(recipe: dict, parts, index=None, **_):
    """What a virtual ``hair_bsdf`` stores itself: the axes, σ_a, the coverage table and the largest error."""
    small = list(index) if index is not None else [part_index(recipe, p) for p in parts]
    axes, variables, _ = whole_tables(recipe, coverage_table(recipe), None, sigma_a(recipe))
    top = max([float(d["max_error"][0]) for d in small] + [_largest(variables)])
    return axes, variables, {"max_error": top}


def budget(recipe: dict, block: int, held: int, note: str = "") -> None:
    """Refuse (BudgetError naming the key) a bake whose row kernels and held tables would not fit the memory budget,
    before anything is allocated: one grid row kernel per local device (:func:`_axes.peak_bytes`, the
    quadrature's own estimate) and the tables of ``held`` sin θ rows (float64 values and errors), then the coverage
    kernel.  ``note`` says why that many rows are held."""
    from .. import budget as _budget
    from ..bake.devices import local_devices

    _, resolution = physics_axes(recipe)
    q = _quadrature(recipe)
    peak = _physics().peak_bytes(resolution, q)
    _, n_r, n_a = recipe["grid"]["resolution"]
    devices = len(local_devices())
    key, value = _budget.driver(
        ("grid.resolution", n_r * n_a, 64 * 16), ("quadrature.nodes", q["nodes"], 12), ("quadrature.levels", q["levels"], 4)
    )
    tables = _budget.product(held, n_r, n_a, len(quantities(recipe)), 16)
    _budget.check(
        key,
        recipe["grid"]["resolution"] if key == "grid.resolution" else value,
        devices * peak["bsdf_row"] + tables,
        f"the quadrature's row kernel on {devices} device{'s' if devices > 1 else ''} ({n_r} × {n_a} entries, "
        f"{q['nodes']} nodes per panel, {q['levels']} levels) and {held} sin θ rows of tables" + (f"; {note}" if note else ""),
    )
    check_coverage_budget(recipe)


def check_coverage_budget(recipe: dict) -> None:
    """Refuse a coverage table whose row kernel would not fit the memory budget (BudgetError naming the key)."""
    from .. import budget as _budget

    if not recipe["coverage"]["bake"]:
        return
    _, resolution = physics_axes(recipe)
    q = _quadrature(recipe)
    key, value = _budget.driver(
        ("coverage.resolution", resolution["strand_count"], 64), ("quadrature.coverage_nodes", q["coverage_nodes"], 16)
    )
    _budget.check(
        key,
        recipe["coverage"]["resolution"] if key == "coverage.resolution" else value,
        _physics().peak_bytes(resolution, q)["coverage_row"],
        f"the coverage row kernel ({resolution['strand_count']} strand counts, {q['coverage_nodes']} nodes per panel)",
    )


def check_part(recipe: dict, path) -> None:
    """Refuse a part that lacks what ``join``/``assemble``/``whole`` read."""
    read_part(path, resolve_recipe(recipe, budget=False))


def start(recipe: dict, shard=None, atlas=None, **_) -> None:
    """Refuse a split bake's inputs before any work: an atlas of a shard (a slice of the tables)."""
    if atlas and shard is not None:
        raise errors.ValidationError("atlas", str(atlas), "a --shard file holds a slice: write the atlas from the merged asset")


def report(recipe: dict, rep: dict, atlas=None, **_) -> dict:
    """A split bake's own facts: the recipe, the largest error bound, and the atlas process 0 writes."""
    out = {"recipe": recipe, "atlas": None, "max_error": None}
    with open_table(rep["out"]) as f:
        if "max_error" in f.attrs:
            out["max_error"] = float(f.attrs["max_error"])
    if atlas and rep["process"] == 0 and rep["kind"] == KIND:
        out["atlas"] = str(_write_atlas(rep["out"], atlas))
    return out


def _write_atlas(path, atlas) -> Path:
    from ._atlas import write_atlas
    from ._lookup import load

    return write_atlas(atlas, load(path))


def bake_whole(r: dict, out, *, progress=None, atlas=None, **_) -> dict:
    """The bake of a recipe without grid tables (the coverage table alone: no split)."""
    t0 = time.perf_counter()
    check_coverage_budget(r)
    if progress:
        progress(0, 1)
    path = write_asset(out, r, None, coverage_table(r))
    if progress:
        progress(1, 1)
    rep = {
        "out": str(path),
        "kind": KIND,
        "recipe": r,
        "recipe_hash": recipe_hash(r),
        "bytes": Path(path).stat().st_size,
        "process": 0,
    }
    rep.update(report(r, rep, atlas=atlas))
    rep["seconds"] = time.perf_counter() - t0
    return rep


def bake(
    recipe: dict | None,
    out,
    *,
    progress=None,
    shard=None,
    atlas=None,
    block: int | None = None,
    keep_parts: bool = False,
    distributed=False,
    merge: str | None = None,
) -> dict:
    """Bake a recipe into the ``hair_bsdf`` asset ``out`` (written atomically): ``hairlut.bake.registry.bake`` of
    this kind.

    The grid tables bake through :mod:`hairlut.bake.sharding` over their sin θ rows (``block`` rows per
    resumable part in ``<out>.parts/``, ``shard`` 'K/N', ``distributed``, ``merge`` 'virtual' or 'copy');
    ``progress(done, total)`` counts rows.  ``atlas``: also write the EXR atlas (:func:`write_atlas`).  Returns the
    report (``out``, ``seconds``, ``bytes``, ``max_error``, ...)."""
    from ..bake import registry

    return registry.bake(
        KIND,
        recipe,
        out,
        progress=progress,
        shard=shard,
        distributed=distributed,
        merge=merge,
        options={"block": block, "keep_parts": keep_parts, "atlas": atlas},
    )
