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

Textures (EXR, one part each, layers indexed by j, the paper's "2-D texture
arrays"): part ``cd`` is n × 6n per layer ``j<j>.R/G/B`` (the six cube faces
+x −x +y −y +z −z side by side, OpenGL face orientation); part ``cs`` stacks one
such strip per θ′ sample, top to bottom: (n·n_θ′) × 6n.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import errors
from ..assets import Axis, ExrPart, Variable, write_exr, write_table
from ._kind import KIND
from ._tables import SHTables


def _index_axis(name, n, long_name):
    return Axis(name, np.arange(n, dtype=np.int32), "1", long_name)


def write_sh_tables(path, tables: SHTables, info: dict, dense: dict | None = None, light: dict | None = None) -> Path:
    """Write the asset; ``dense`` holds t_dirs/theta_v/rd/rs, ``light`` holds a/channels/cd/cs."""
    b = tables.bands
    g = tables.gaunt
    axes = [
        _index_axis("sh_k", g.shape[0], "SH index k of the kernel expansion (i = l*l + l + m)"),
        _index_axis("light", g.shape[1], "light SH index i"),
        _index_axis("trans", g.shape[2], "transmittance SH index j"),
    ]
    variables = [Variable("gaunt", g, ("sh_k", "light", "trans"), "1", "real Gaunt coefficients: integral of Y_k Y_i Y_j")]
    if tables.has_diffuse:
        axes.append(_index_axis("l_d", len(tables.kd_l), "Legendre degree l (diffuse)"))
        variables.append(Variable("kernel/diffuse_k", tables.kd_l, ("l_d",), "sr", "Legendre coefficients k_l of sin(theta)"))
    if tables.has_specular:
        nodes = info["theta_v_nodes"]
        axes.append(Axis("theta_v_node", nodes.ravel(), "rad", "theta' at Chebyshev-Lobatto nodes of [0,pi/2] and [pi/2,pi]"))
        axes.append(_index_axis("l_s", info["specular_nodes"].shape[-1], "Legendre degree l (specular)"))
        variables.append(Variable(
            "kernel/specular_k", info["specular_nodes"].reshape(-1, info["specular_nodes"].shape[-1]), ("theta_v_node", "l_s"),
            "sr", "Legendre coefficients k_l(theta') of max(0, cos(pi - theta - theta'))^p",
        ))
    if dense:
        st = np.dtype(tables.recipe["dense"]["storage"])
        axes += [_index_axis("t", len(dense["t_dirs"]), "tangent direction index (cube-map texel centres)"),
                 Axis("xyz", np.arange(3, dtype=np.int32), "1", "x, y, z"),
                 Axis("theta_v", dense["theta_v"], "rad", "theta' = angle(tangent, view)")]
        variables.append(Variable("dense/t_dirs", dense["t_dirs"], ("t", "xyz"), "1", "unit tangent directions"))
        if "rd" in dense:
            axes.append(_index_axis("light_d", b.n_light_diffuse, "light SH index (diffuse)"))
            variables.append(Variable("dense/rd", dense["rd"].astype(st), ("t", "light_d", "trans"), "sr", "Rd(i, j, t)",
                                      chunks=(min(64, len(dense["t_dirs"])), b.n_light_diffuse, b.n_trans)))
        if "rs" in dense:
            axes.append(_index_axis("light_s", b.n_light_specular, "light SH index (specular)"))
            variables.append(Variable("dense/rs", dense["rs"].astype(st), ("t", "theta_v", "light_s", "trans"), "sr",
                                      "Rs(i, j, t, theta')", chunks=(16, len(dense["theta_v"]), b.n_light_specular, b.n_trans)))
    if light:
        a = light["a"]
        axes += [_index_axis("light_coeff", a.shape[0], "light SH index"),
                 Axis("channel", np.arange(a.shape[1], dtype=np.int32), "1", "colour channel: " + ",".join(light["channels"]))]
        variables.append(Variable("light/a", a, ("light_coeff", "channel"), "W/(m2 sr)", "light SH coefficients a_i"))
        if dense and "cd" in light:
            variables.append(Variable("light/cd", light["cd"].astype(np.float32), ("t", "trans", "channel"), "1", "Cd(j, t)"))
        if dense and "cs" in light:
            variables.append(Variable("light/cs", light["cs"].astype(np.float32), ("t", "theta_v", "trans", "channel"), "1",
                                      "Cs(j, t, theta')"))
    attrs = {"chebyshev_tail": float(info["chebyshev_tail"])}
    if "truncation_error" in info:
        attrs["specular_truncation_error"] = float(info["truncation_error"])
    return write_table(path, KIND, tables.recipe, axes, variables, attrs=attrs)


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
