"""The built-in demo: bake a small real table and image, then summarise both.

It grows with the toolchain; today it samples the Kajiya–Kay kernels (the
lobes every SH table integrates) into an HDF5 table and an EXR image.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .assets import Axis, Variable, preview, summarize, write_exr, write_table
from .kernels import sample_lobes

DEFAULT_RECIPE = {"n_theta": 181, "n_theta_v": 181, "exponents": [8.0, 49.0, 200.0], "storage": "float32"}


def bake_lobes(out_dir: str | os.PathLike, recipe: dict | None = None) -> tuple[Path, Path]:
    """Write ``kk_lobes.h5`` and ``kk_lobes.exr`` into ``out_dir``; return their paths."""
    r = {**DEFAULT_RECIPE, **(recipe or {})}
    theta, theta_v, diff, spec = sample_lobes(r["n_theta"], r["n_theta_v"], r["exponents"])
    dtype = np.dtype(r["storage"])
    out_dir = Path(out_dir)
    axes = [
        Axis("theta", theta, "rad", "angle between light direction and tangent"),
        Axis("theta_v", theta_v, "rad", "angle between tangent and view direction"),
        Axis("exponent", np.asarray(r["exponents"], np.float64), "1", "specular exponent p"),
    ]
    variables = [
        Variable("diffuse", diff.astype(dtype), ("theta",), "1", "Kajiya-Kay diffuse kernel sin(theta)"),
        Variable("specular", spec.astype(dtype), ("exponent", "theta", "theta_v"), "1",
                 "Kajiya-Kay specular kernel max(0, cos(pi - theta - theta_v))^p"),
    ]
    h5 = write_table(out_dir / "kk_lobes.h5", "kk_lobes", r, axes, variables)
    layers = {f"p{p:g}.Y": spec[i] for i, p in enumerate(r["exponents"])}
    layers["diffuse.Y"] = np.broadcast_to(diff[:, None], spec.shape[1:])
    exr = write_exr(out_dir / "kk_lobes.exr", layers, recipe=r, kind="kk_lobes")
    return h5, exr


def run(out_dir: str | os.PathLike) -> dict:
    """Bake the demo assets, preview the specular lobe, return their inspect summaries."""
    h5, exr = bake_lobes(out_dir)
    png = preview(exr, Path(out_dir) / "kk_lobes_p49.png", channel="p49")
    return {"assets": [summarize(h5), summarize(exr)], "previews": [str(png)]}
