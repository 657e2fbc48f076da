"""Writing the ``sh_tables`` HDF5 asset and its shader-ready EXR textures (the reader is
:func:`hairlut.shtables.load_sh_tables`, beside :class:`SHTables`).

HDF5 layout (axes in /axes, see hairlut.assets.h5):

``kernel/diffuse_k``   (l_d)                   k_l of sin θ
``kernel/specular_k``  (theta_v_node, l_s)     k_l(θ′) at the Chebyshev–Lobatto nodes of
                                               [0, π/2] then [π/2, π] (π/2 appears twice)
``gaunt``              (sh_k, light, trans)    real Gaunt coefficients ∫ Y_k Y_i Y_j dω
``dense/t_dirs``       (t, xyz)                tangent grid: cube-map texel centres (optional)
``dense/rd``           (t, light_d, trans)     Rd on the grid (optional)
``dense/rs``           (t, theta_v, light_s, trans)  Rs on the grid (optional)
``light/a``            (light, channel)        light SH coefficients (when a light is given)
``light/cd``, ``light/cs``                     Cd, Cs on the dense grid (when both are present)

The per-tangent tables (``t`` first) are what a bake splits (:mod:`hairlut.bake.sharding`): an
``sh_shard`` file (a part in ``<out>.parts/``, or the output of ``--shard``) holds tangents
[t_start, t_stop) of them, plus ``light/a``; a virtual ``sh_tables`` stores them as HDF5
virtual datasets over the parts and everything else itself (:func:`whole_tables`).

Textures (EXR, one part each, layers indexed by j, the paper's "2-D texture
arrays"): part ``cd`` is n × 6n per layer ``j<j>.R/G/B`` (the six cube faces
+x −x +y −y +z −z side by side, OpenGL face orientation); part ``cs`` stacks one
such strip per θ′ sample, top to bottom: (n·n_θ′) × 6n.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import errors
from ..assets import Axis, ExrPart, Variable, read_table, write_exr, write_table
from ._kind import KIND, SHARD_KIND
from ._tables import SHTables


def _index_axis(name, n, long_name, start: int = 0):
    return Axis(name, np.arange(start, start + n, dtype=np.int32), "1", long_name)


def table_axes(tables: SHTables, info: dict) -> list[Axis]:
    """The axes of the compact exact tables (Gaunt tensor, kernel coefficients)."""
    g = tables.gaunt
    axes = [
        _index_axis("sh_k", g.shape[0], "SH index k of the kernel expansion (i = l*l + l + m)"),
        _index_axis("light", g.shape[1], "light SH index i"),
        _index_axis("trans", g.shape[2], "transmittance SH index j"),
    ]
    if tables.has_diffuse:
        axes.append(_index_axis("l_d", len(tables.kd_l), "Legendre degree l (diffuse)"))
    if tables.has_specular:
        nodes = info["theta_v_nodes"]
        axes.append(Axis("theta_v_node", nodes.ravel(), "rad", "theta' at Chebyshev-Lobatto nodes of [0,pi/2] and [pi/2,pi]"))
        axes.append(_index_axis("l_s", info["specular_nodes"].shape[-1], "Legendre degree l (specular)"))
    return axes


def table_variables(tables: SHTables, info: dict) -> list[Variable]:
    """The compact exact tables: the Gaunt tensor and the kernels' Legendre coefficients."""
    variables = [
        Variable("gaunt", tables.gaunt, ("sh_k", "light", "trans"), "1", "real Gaunt coefficients: integral of Y_k Y_i Y_j")
    ]
    if tables.has_diffuse:
        variables.append(Variable("kernel/diffuse_k", tables.kd_l, ("l_d",), "sr", "Legendre coefficients k_l of sin(theta)"))
    if tables.has_specular:
        variables.append(
            Variable(
                "kernel/specular_k",
                info["specular_nodes"].reshape(-1, info["specular_nodes"].shape[-1]),
                ("theta_v_node", "l_s"),
                "sr",
                "Legendre coefficients k_l(theta') of max(0, cos(pi - theta - theta'))^p",
            )
        )
    return variables


def light_axes(light: dict) -> list[Axis]:
    a = light["a"]
    return [
        _index_axis("light_coeff", a.shape[0], "light SH index"),
        Axis("channel", np.arange(a.shape[1], dtype=np.int32), "1", "colour channel: " + ",".join(light["channels"])),
    ]


def light_variables(light: dict) -> list[Variable]:
    return [Variable("light/a", light["a"], ("light_coeff", "channel"), "W/(m2 sr)", "light SH coefficients a_i")]


def dense_axes(tables: SHTables, n: int, theta_v, start: int = 0) -> list[Axis]:
    """The axes of the per-tangent tables of tangents [start, start + n) (the split axis ``t`` first)."""
    b = tables.bands
    axes = [
        _index_axis("t", n, "tangent direction index (cube-map texel centres)", start),
        Axis("xyz", np.arange(3, dtype=np.int32), "1", "x, y, z"),
        Axis("theta_v", np.asarray(theta_v), "rad", "theta' = angle(tangent, view)"),
    ]
    if tables.has_diffuse:
        axes.append(_index_axis("light_d", b.n_light_diffuse, "light SH index (diffuse)"))
    if tables.has_specular:
        axes.append(_index_axis("light_s", b.n_light_specular, "light SH index (specular)"))
    return axes


def _finite_in(name: str, values, dtype, drivers: str) -> np.ndarray:
    """``values`` in the storage ``dtype``, finite or refused: NonFiniteError naming ``name`` and the
    recipe keys or inputs that drive it (``drivers``) when a value is NaN/inf or does not fit ``dtype``."""
    v = np.asarray(values)
    dtype = np.dtype(dtype)
    finite = np.isfinite(v)
    top, cap = float(np.max(np.abs(v), where=finite, initial=0.0)), float(np.finfo(dtype).max)
    if not finite.all() or top > cap:
        bad = int(v.size - finite.sum())
        why = f"{bad} NaN/inf values" if bad else f"|values| up to {top:.3g}, beyond {dtype.name}'s {cap:.3g}"
        raise errors.NonFiniteError(f"sh_tables: {name} is not finite in {dtype.name} ({why}); {drivers}")
    return v.astype(dtype)


def dense_variables(tables: SHTables, dense: dict, light: dict | None = None) -> list[Variable]:
    """The per-tangent tables (``t`` first): t_dirs, Rd, Rs in the recipe's dense storage, Cd, Cs (float32),
    each finite in its dtype or refused (:func:`_finite_in`) — the whole bake and every part of a sharded one."""
    b, r = tables.bands, tables.recipe
    st = np.dtype(r["dense"]["storage"])
    n = len(dense["t_dirs"])
    keys = (
        f"the recipe drives it: kernel.p={r['kernel']['p']}, bands.light_diffuse={b.light_diffuse}, "
        f"bands.light_specular={b.light_specular}, bands.transmittance={b.transmittance}, dense.storage={st.name}"
    )
    variables = [Variable("dense/t_dirs", dense["t_dirs"], ("t", "xyz"), "1", "unit tangent directions")]
    if "rd" in dense:
        variables.append(
            Variable(
                "dense/rd",
                _finite_in("dense/rd", dense["rd"], st, keys),
                ("t", "light_d", "trans"),
                "sr",
                "Rd(i, j, t)",
                chunks=(min(64, n), b.n_light_diffuse, b.n_trans),
            )
        )
    if "rs" in dense:
        variables.append(
            Variable(
                "dense/rs",
                _finite_in("dense/rs", dense["rs"], st, keys),
                ("t", "theta_v", "light_s", "trans"),
                "sr",
                "Rs(i, j, t, theta')",
                chunks=(min(16, n), len(dense["theta_v"]), b.n_light_specular, b.n_trans),
            )
        )
    if light:
        a = np.asarray(light["a"], np.float64)
        lit = (
            f"the light drives it: its SH coefficients reach |a| = {float(np.max(np.abs(a), initial=0.0)):.3g} "
            "(the environment map's values times environment.intensity)"
        )
    if light and "cd" in light:
        variables.append(
            Variable("light/cd", _finite_in("light/cd", light["cd"], np.float32, lit), ("t", "trans", "channel"), "1", "Cd(j, t)")
        )
    if light and "cs" in light:
        variables.append(
            Variable(
                "light/cs",
                _finite_in("light/cs", light["cs"], np.float32, lit),
                ("t", "theta_v", "trans", "channel"),
                "1",
                "Cs(j, t, theta')",
            )
        )
    return variables


def table_attrs(info: dict) -> dict:
    attrs = {"chebyshev_tail": float(info["chebyshev_tail"])}
    if "truncation_error" in info:
        attrs["specular_truncation_error"] = float(info["truncation_error"])
    return attrs


def _unique(axes: list[Axis]) -> list[Axis]:
    return list({a.name: a for a in axes}.values())


def whole_tables(tables: SHTables, info: dict, dense_meta: dict | None, light: dict | None):
    """(axes, variables, attrs): everything an ``sh_tables`` asset stores besides its per-tangent tables.

    ``dense_meta`` holds ``total`` (tangents) and ``theta_v`` when the asset has dense tables."""
    axes = table_axes(tables, info)
    variables = table_variables(tables, info)
    if dense_meta:
        axes += dense_axes(tables, dense_meta["total"], dense_meta["theta_v"])
    if light:
        axes += light_axes(light)
        variables += light_variables(light)
    return _unique(axes), variables, table_attrs(info)


def write_sh_tables(path, tables: SHTables, info: dict, dense: dict | None = None, light: dict | None = None) -> Path:
    """Write the asset; ``dense`` holds t_dirs/theta_v/rd/rs, ``light`` holds a/channels/cd/cs."""
    meta = {"total": len(dense["t_dirs"]), "theta_v": dense["theta_v"]} if dense else None
    axes, variables, attrs = whole_tables(tables, info, meta, light)
    if dense:
        variables += dense_variables(tables, dense, light)
    return write_table(path, KIND, tables.recipe, axes, variables, attrs=attrs)


def write_part(path, tables: SHTables, dense: dict, light: dict | None, start: int, total: int) -> Path:
    """Tangents [start, start + n) of a bake as an ``sh_shard`` file: the per-tangent tables, and the light's
    coefficients (so that parts alone make the asset)."""
    n = len(dense["t_dirs"])
    axes = dense_axes(tables, n, dense["theta_v"], start) + [
        _index_axis("trans", tables.bands.n_trans, "transmittance SH index j")
    ]
    variables = dense_variables(tables, dense, light)
    attrs = {"t_start": np.int64(start), "t_stop": np.int64(start + n), "t_total": np.int64(total)}
    if light:
        axes += light_axes(light)
        variables += light_variables(light)
        attrs["channels"] = ",".join(light["channels"])
    return write_table(path, SHARD_KIND, tables.recipe, _unique(axes), variables, attrs=attrs)


def read_part(path, recipe: dict) -> tuple[dict, dict | None, int, int]:
    """(dense, light, start, total) of an ``sh_shard`` file of ``recipe`` (every table the recipe implies)."""
    t = read_table(path, kind=SHARD_KIND)
    kern = recipe["kernel"]
    want = ["dense/t_dirs", *(["dense/rd"] if kern["diffuse"] else []), *(["dense/rs"] if kern["specular"] else [])]
    if "light" in recipe:
        want += ["light/a", *(["light/cd"] if kern["diffuse"] else []), *(["light/cs"] if kern["specular"] else [])]
    try:
        start, stop, total = (int(t.attrs[f"t_{k}"]) for k in ("start", "stop", "total"))
        dense = {
            "t_dirs": t["dense/t_dirs"],
            "theta_v": t.axes["theta_v"].values,
            **{k: t[f"dense/{k}"] for k in ("rd", "rs") if f"dense/{k}" in want},
        }
        light = None
        if "light" in recipe:
            channels = t.attrs["channels"]
            channels = channels.decode() if isinstance(channels, bytes) else str(channels)
            light = {
                "a": t["light/a"],
                "channels": channels.split(","),
                **{k: t[f"light/{k}"] for k in ("cd", "cs") if f"light/{k}" in want},
            }
    except KeyError as exc:
        raise errors.MissingDatasetError(path, f"sh_shard lacks {exc}") from None
    if len(dense["t_dirs"]) != stop - start:
        raise errors.CorruptAssetError(path, f"t range {start}..{stop} does not match its {len(dense['t_dirs'])} tangents")
    return dense, light, start, total


def concat_parts(read: list[tuple[dict, dict | None, int, int]]) -> tuple[dict, dict | None]:
    """Join the per-tangent tables of consecutive parts (as :func:`read_part` returns them)."""
    dense = {k: np.concatenate([r[0][k] for r in read]) for k in read[0][0] if k != "theta_v"}
    dense["theta_v"] = read[0][0]["theta_v"]
    light = None
    if read[0][1] is not None:
        light = {
            "a": read[0][1]["a"],
            "channels": read[0][1]["channels"],
            **{k: np.concatenate([r[1][k] for r in read]) for k in ("cd", "cs") if k in read[0][1]},
        }
    return dense, light


def cube_strip(values: np.ndarray, n: int) -> np.ndarray:
    """(6·n·n, ...) texel values in face order → an n × 6n strip (..., n, 6n)."""
    v = values.reshape(6, n, n, *values.shape[1:])
    v = np.moveaxis(v, (0, 1, 2), (-3, -2, -1))  # (..., 6, n, n)
    return np.concatenate([v[..., f, :, :] for f in range(6)], axis=-1)


def write_textures(path, cd: np.ndarray | None, cs: np.ndarray | None, n: int, channels, recipe) -> Path:
    """Shader textures: part 'cd' (layers j<j>.<channel>, n × 6n) and part 'cs' ((n·n_θ′) × 6n)."""
    parts = []
    if cd is not None:  # (T, J, C)
        strips = cube_strip(cd, n)  # (J, C, n, 6n)
        parts.append(ExrPart("cd", {f"j{j}.{c}": strips[j, k] for j in range(strips.shape[0]) for k, c in enumerate(channels)}))
    if cs is not None:  # (T, Θ, J, C)
        strips = cube_strip(cs, n)  # (Θ, J, C, n, 6n)
        stacked = np.concatenate(list(strips), axis=-2)  # (J, C, Θ·n, 6n)
        parts.append(ExrPart("cs", {f"j{j}.{c}": stacked[j, k] for j in range(stacked.shape[0]) for k, c in enumerate(channels)}))
    if not parts:
        raise errors.ValidationError("textures", None, "nothing to write")
    return write_exr(path, parts, recipe=recipe, kind="sh_textures")
