"""The scene table on the one shard path (:mod:`hairlut.bake.sharding`): its table rows are the units.

A unit is one non-empty sector of the scene (one table row, in ``prepare``'s order).  A part
(``scene_shard``) holds rows [start, stop): their ``alpha`` and ``ratio`` (the storage dtype),
``scene_index`` (the scene sector each row traces, the inverse of the asset's ``row``), and the
root attributes ``sector_start``/``sector_stop``/``sector_total``, ``sectors`` (the scene's sector
count) and ``mirror_error`` (the part's largest mirror-symmetry violation: 0 since the bake computes α on
V/2 views only, the other half being their mirror by construction; tables baked before kept the measured one).  So the whole asset is
built from its parts alone (no scene needed: ``hairlut merge`` joins ``--shard`` files), and a row's
numbers depend on its own sector alone: a sharded, resumed, distributed or virtual bake holds the
same data as a one-shot bake.

The scene's sector inputs (:func:`hairlut.scenemaps.scene_inputs`) are built once per process and
recipe (:func:`scene_rows`) and shared by its blocks.  Within a block, rows are traced
(``hairlut.march.bake_view_grid``: α on V/2 views, the re/α bins on the kept views only) :data:`MICRO` at a time on every local device
(:func:`hairlut.bake.devices.map_chunks`); across processes, ``--distributed`` shares the blocks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import errors
from ..assets import Axis, Variable, open_table, read_table, recipe_hash, write_table
from ..assets.layout import layout
from ..bake.devices import map_chunks
from ._bake import ratio_terms, scene_inputs
from ._kind import KIND, SHARD_KIND
from ._recipe import geometry_key, hrir_recipe

#: Rows per call of the tracer, dealt round-robin to the local devices (a row's numbers do not depend on it).
MICRO = 16
_ROWS: dict[str, tuple] = {}  # one entry: recipe hash → (density, geometry, scene index, sector count) of the rows


def scene_rows(recipe: dict, scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """(density (n, …), geometry (n, 11), scene index (n,), N) of the scene's n non-empty sectors (its table
    rows) of N.

    Built once per recipe hash (which holds the groom's geometry key) and process."""
    if scene is None:
        raise errors.ValidationError(
            "scene",
            None,
            "a scene_maps table is one scene's: give the scene "
            "(hairlut bake scene_maps --scene SCENE.toml, or hairlut bake --scene SCENE.toml)",
        )
    key = recipe_hash(recipe)
    if key not in _ROWS:
        density, geometry = scene_inputs(scene, recipe)
        n = len(density)
        live = np.flatnonzero(density.reshape(n, -1).max(axis=1, initial=0.0) > 0) if n else np.zeros(0, np.int64)
        _ROWS.clear()
        _ROWS[key] = (density[live], geometry[live], live, n)
    return _ROWS[key]


def count(recipe: dict, scene=None, **_) -> int:
    return len(scene_rows(recipe, scene)[2])


def _axes(recipe: dict, rows: int, start: int = 0, sectors: int | None = None) -> list[Axis]:
    t, P = recipe["table"], hrir_recipe(recipe)["trace"]["pixels"]
    V, Q, K = t["views"], t["shading_pixels"], t["terms"]
    views = 2 * np.pi * np.arange(V) / V
    axes = [
        Axis("sector", np.arange(start, start + rows), "1", "non-empty sector (table row)"),
        Axis("view_half", views[: V // 2], "rad", "view azimuth θv (half circle; α(θ+π, p) = α(θ, P−1−p))", 2 * np.pi),
        Axis("view", views[:: t["ratio_step"]], "rad", "view azimuth θv of the ratio terms", 2 * np.pi),
        Axis("pixel", np.arange(P), "1", "pixel along the image line"),
        Axis("bin", np.arange(Q), "1", f"bin of {P // Q} pixels"),
        Axis("term", np.arange(2 * K + 1), "1", "c0, a1, b1, …: ρ(Δ) = c0 + Σ a_k cos kΔ + b_k sin kΔ, Δ = θl − θv"),
    ]
    if sectors is not None:
        axes.append(Axis("scene_sector", np.arange(sectors), "1", "sector of the scene (prepare's order)"))
    return axes


def _per_row(alpha, ratio, index) -> list[Variable]:
    return [
        Variable("alpha", alpha, ("sector", "view_half", "pixel"), "1", "opacity (satf eq 4)"),
        Variable("ratio", ratio, ("sector", "view", "bin", "term"), "1", "re/α Fourier terms in θl − θv"),
        Variable(
            "scene_index", np.asarray(index, np.int32), ("sector",), "1", "scene sector of each table row (the inverse of row)"
        ),
    ]


def _write_part(path, recipe: dict, alpha, ratio, index, start: int, total: int, sectors: int, mirror: float) -> Path:
    return write_table(
        path,
        SHARD_KIND,
        recipe,
        _axes(recipe, len(alpha), start),
        _per_row(alpha, ratio, index),
        attrs={
            "sector_start": np.int64(start),
            "sector_stop": np.int64(start + len(alpha)),
            "sector_total": np.int64(total),
            "sectors": np.int64(sectors),
            "mirror_error": float(mirror),
        },
    )


def bake_part(recipe: dict, start: int, stop: int, total: int, path, scene=None, **_) -> Path:
    """Trace table rows [start, stop) of the scene and write them as the ``scene_shard`` part ``path``."""
    from ..march import bake_view_grid

    density, geometry, live, sectors = scene_rows(recipe, scene)
    t, full = recipe["table"], hrir_recipe(recipe)
    dtype = np.dtype(t["dtype"])

    def rows(s, e):  # rows [start + s, start + e): traced (α on V/2 views, re/α only where kept), compressed, cast
        half, ab, rb = bake_view_grid(
            density[start + s : start + e],
            geometry[start + s : start + e],
            full,
            views=t["views"],
            lights=t["lights"],
            ratio_step=t["ratio_step"],
            bins=t["shading_pixels"],
            alpha_grid=t["alpha_grid"],
            shade_rays=t["shade_rays"] or None,
            shade_steps=t["shade_steps"] or None,
        )
        return half.astype(dtype), ratio_terms(ab, rb, t["views"], t["terms"], t["ratio_step"]).astype(dtype), 0.0

    done = map_chunks(rows, stop - start, micro=MICRO)  # every local device
    return _write_part(
        path,
        recipe,
        np.concatenate([d[0] for d in done]),
        np.concatenate([d[1] for d in done]),
        live[start:stop],
        start,
        total,
        sectors,
        max(d[2] for d in done),
    )


def _read(path) -> dict:
    """Everything a part holds: its tables and the attributes join/assemble/whole need."""
    t = read_table(path, kind=SHARD_KIND, required=("alpha", "ratio", "scene_index"))
    try:
        head = {k: int(t.attrs[k]) for k in ("sector_start", "sector_stop", "sector_total", "sectors")}
        head["mirror_error"] = float(t.attrs["mirror_error"])
    except KeyError as exc:
        raise errors.MissingDatasetError(path, f"scene_shard lacks root attribute {exc}") from None
    n = head["sector_stop"] - head["sector_start"]
    if not len(t["alpha"]) == len(t["ratio"]) == len(t["scene_index"]) == n:
        raise errors.CorruptAssetError(
            path, f"row range {head['sector_start']}..{head['sector_stop']} does not match the tables ({len(t['alpha'])} rows)"
        )
    return {"alpha": t["alpha"], "ratio": t["ratio"], "scene_index": t["scene_index"], **head}


def check(recipe: dict, path) -> None:
    """Raise unless ``path`` holds everything a part must (a part of an older format is baked again)."""
    _read(path)


def join(recipe: dict, parts, out) -> Path:
    """Consecutive parts as one ``scene_shard`` file (``--shard K/N``)."""
    read = [_read(p) for p in parts]
    cat = {k: np.concatenate([r[k] for r in read]) for k in ("alpha", "ratio", "scene_index")}
    return _write_part(
        out,
        recipe,
        cat["alpha"],
        cat["ratio"],
        cat["scene_index"],
        read[0]["sector_start"],
        read[0]["sector_total"],
        read[0]["sectors"],
        max(r["mirror_error"] for r in read),
    )


def part_index(recipe: dict, path, **_) -> dict[str, np.ndarray]:
    """What :func:`whole` reads from one part: its row indices, mirror error and scene sector count."""
    with open_table(path, SHARD_KIND, required=("scene_index",)) as f:
        return {
            "scene_index": np.asarray(layout(f)[1]["scene_index"][()], np.int64),
            "mirror_error": np.array([float(f.attrs["mirror_error"])]),
            "sectors": np.array([int(f.attrs["sectors"])]),
        }


def whole(recipe: dict, parts, index=None, **_) -> tuple[list[Axis], list[Variable], dict]:
    """What a ``scene_maps`` asset stores besides its per-row tables: the axes, ``row`` and the root
    attributes, from the parts' row indices and attributes alone (nothing else of a part is read), or from
    their :func:`part_index` dicts ``index``."""
    small = list(index) if index is not None else [part_index(recipe, p) for p in parts]
    mirror = max(float(d["mirror_error"][0]) for d in small)
    sectors = int(small[-1]["sectors"][0])
    index = np.concatenate([d["scene_index"] for d in small])
    if len(np.unique(index)) != len(index) or index.min(initial=0) < 0 or index.max(initial=-1) >= sectors:
        raise errors.CorruptAssetError(parts[0], f"the parts' scene_index rows are not distinct sectors of {sectors}")
    row = np.full(sectors, -1, np.int32)
    row[index] = np.arange(len(index), dtype=np.int32)
    variables = [Variable("row", row, ("scene_sector",), "1", "table row of each scene sector (−1: empty)")]
    return (
        _axes(recipe, len(index), sectors=sectors),
        variables,
        {"mirror_error": mirror, "sectors": sectors, "live": len(index)},
    )


def assemble(recipe: dict, parts, out, **_) -> Path:
    """Parts covering every row as one self-contained ``scene_maps`` asset."""
    read = [_read(p) for p in parts]
    axes, variables, attrs = whole(recipe, parts)
    per_row = _per_row(*(np.concatenate([r[k] for r in read]) for k in ("alpha", "ratio", "scene_index")))
    return write_table(out, KIND, recipe, axes, per_row + variables, attrs=attrs)


def _same_groom(recipe: dict, scene) -> None:
    """Refuse a recipe whose geometry key is another groom's than ``scene``'s."""
    given, key = (recipe or {}).get("geometry", {}).get("sha256"), geometry_key(scene)
    if given and given != key:
        raise errors.ValidationError(
            "geometry.sha256", given, f"the recipe is for another groom (this scene's geometry key is {key[:12]}…)"
        )


def start(recipe: dict, shard=None, scene=None, **_) -> None:
    """Refuse a bake without its scene, for another groom, or of a groom with no non-empty sector."""
    if scene is None:
        scene_rows(recipe, None)  # the error that asks for the scene
    _same_groom(recipe, scene)
    if count(recipe, scene) == 0:
        raise errors.ValidationError(
            "scene", str(getattr(scene, "path", "") or "scene"), "its groom has no non-empty sector: there is nothing to tabulate"
        )


def report(recipe: dict, rep: dict, **_) -> dict:
    """The table's own facts for the bake report: its recipe, every sector of the groom (``sectors``; the rows are
    the non-empty ones, ``total_units``) and the mirror symmetry's error."""
    with open_table(rep["out"]) as f:
        attrs = {k: f.attrs[k] for k in ("sectors", "mirror_error") if k in f.attrs}
    return {"recipe": recipe, "sectors": int(attrs.get("sectors", 0)), "mirror_error": float(attrs.get("mirror_error", 0.0))}


def bake(
    recipe, out, *, progress=None, shard=None, scene=None, block=None, keep_parts=False, distributed=False, merge=None
) -> dict:
    """Trace and write the scene table of ``scene`` (``hairlut.bake.registry.bake`` of this kind): resumable blocks
    of ``block`` rows in ``<out>.parts/``, ``shard`` 'K/N', ``distributed`` processes, the final asset copied
    (``merge='copy'``) or virtual over the parts (see :mod:`hairlut.bake.sharding`)."""
    from ..bake import registry

    if scene is not None:
        _same_groom(recipe, scene)  # before the registry folds the scene's key into the recipe
    return registry.bake(
        KIND,
        recipe,
        out,
        progress=progress,
        shard=shard,
        distributed=distributed,
        merge=merge,
        options={"block": block, "keep_parts": keep_parts},
        scene=scene,
    )
