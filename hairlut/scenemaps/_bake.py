"""Baking and reading a ``scene_maps`` table (module docstring of the package).

**Bake.**  The scene's sectors (its clusters in order, each cluster's sectors in the sector table's
order: the order ``hairlut.synth.prepare`` concatenates them in) become tracer inputs by
``hairlut.march.scene_sector_inputs`` (the metric extent the texels read).  Every non-empty sector
is traced on V views θv,i = 2πi/V and L lights θl,j = 2πj/L (satf eqs 4–5; float32) by
``hairlut.march.bake_view_grid``, which computes only what is stored: α on views 0 … V/2 − 1 (through
the recipe's ``alpha_grid`` Cartesian resampling, one matrix product for every view, or with
alpha_grid 0 the tracer's own march) and the per-bin α and re on the kept views (the tracer's march
with ``shade_rays`` and ``shade_steps``).  With alpha_grid, shade_rays and shade_steps 0 these are
``hairlut.march.trace_view_grid``'s (``hairlut.hrir.trace_sectors``') arrays to float32 rounding,
binned (:func:`compress` takes that reference path's full arrays); then, in float64:

* **α** (N, V/2, P): views 0 … V/2 − 1; the others by the mirror symmetry
  α(θ + π, p) = α(θ, P − 1 − p) (the same line integrals, the pixel line reversed; :func:`compress`
  measures the largest violation of the reference's arrays as ``mirror_error``);
* **ratio** (N, V/step, Q, 2K + 1): per view (every ``ratio_step``-th) and per bin of P/Q pixels, ρ(θl) = Σ_bin re / Σ_bin α
  (bounded by k_a + k_d + k_s: re is α-weighted shading), as Fourier terms in Δ = θl − θv:
  ρ(Δ) = c₀ + Σ_k a_k cos kΔ + b_k sin kΔ (from the DFT over the L light angles, each term's phase
  turned by kθv, so the coefficients are exact for any L ≥ 2K + 1 up to the aliasing of terms > K);
* **row** (N_scene,): the table row of each of the scene's sectors, −1 for an empty one.

The bake itself runs on the one shard path (``_parts``: table rows as units, resumable parts,
``--shard``, ``--distributed``, virtual or copied assets).

**Read.**  :func:`load_scene_maps` validates the file and returns a :class:`SceneMaps`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import read_table
from ..assets.virtual_write import check_virtual
from ._kind import KIND
from ._recipe import hrir_recipe


@dataclass(frozen=True, eq=False)
class SceneMaps:
    """A loaded ``scene_maps`` table: ``alpha`` (N, V/2, P), ``ratio`` (N, V, Q, 2K + 1), ``row``
    (N_scene,) (−1: empty sector), its ``recipe``, ``path`` and ``attrs``."""

    alpha: np.ndarray
    ratio: np.ndarray
    row: np.ndarray
    recipe: dict
    path: Path | None = None
    attrs: dict | None = None

    @property
    def views(self) -> int:
        return 2 * self.alpha.shape[1]

    @property
    def pixels(self) -> int:
        return self.alpha.shape[-1]

    @property
    def terms(self) -> int:
        return (self.ratio.shape[-1] - 1) // 2


def scene_inputs(scene, recipe: dict) -> tuple[np.ndarray, np.ndarray]:
    """density (N, n_s, n_r) and geometry (N, 11) of every sector of every cluster of ``scene``
    (prepare's order), for the recipe's density grid and trace settings."""
    from ..march import scene_sector_inputs
    from ..scene import as_scene, scene_sector_tables

    full = hrir_recipe(recipe)
    dens, geom = [], []
    for table in scene_sector_tables(as_scene(scene)):  # the sectors the planner cut (the groom cache)
        d, g = scene_sector_inputs(table, full)
        dens.append(d)
        geom.append(g)
    return np.concatenate(dens), np.concatenate(geom)


def compress(alpha, re, views: int, terms: int, bins: int, step: int = 1) -> tuple[np.ndarray, np.ndarray, float]:
    """(α half (n, V/2, P), ratio (n, V/step, Q, 2K + 1), mirror error) from traced α (n, V, P) and re
    (n, V, L, P) on the grids θv,i = 2πi/V, θl,j = 2πj/L (module docstring), in float64; the ratio is
    kept on every ``step``-th view."""
    a, r = np.asarray(alpha, np.float64), np.asarray(re, np.float64)
    n, V, L, P = r.shape
    half = V // 2
    mirror = float(np.abs(a[:, half:] - a[:, :half, ::-1]).max(initial=0.0))
    ab = a[:, ::step].reshape(n, -1, bins, P // bins).sum(-1)
    rb = r[:, ::step].reshape(n, -1, L, bins, P // bins).sum(-1)
    return a[:, :half], ratio_terms(ab, rb, views, terms, step), mirror


def ratio_terms(ab, rb, views: int, terms: int, step: int = 1) -> np.ndarray:
    """The ratio's Fourier terms (n, Vr, Q, 2K + 1), float64, from per-bin α (n, Vr, Q) and re (n, Vr, L, Q) on
    the views θv,i = 2πi/V, i = 0, step, 2·step, … (Vr = V/step) and the lights θl,j = 2πj/L (module docstring)."""
    ab, rb = np.asarray(ab, np.float64), np.asarray(rb, np.float64)
    n, Vr, L, Q = rb.shape
    ratio = np.where(ab[:, :, None] > 1e-12, rb / np.where(ab > 1e-12, ab, 1.0)[:, :, None], 0.0)  # (n, Vr, L, Q)
    c = np.fft.fft(ratio, axis=2) / L  # ρ(θl) = Σ_k c_k e^{ikθl}
    k = np.arange(terms + 1)
    tv = 2 * np.pi * np.arange(0, views, step)[:Vr] / views
    d = c[:, :, : terms + 1] * np.exp(1j * k[None, None, :, None] * tv[None, :, None, None])  # in Δ = θl − θv
    coef = np.empty((n, Vr, Q, 2 * terms + 1))
    coef[..., 0] = d[:, :, 0].real
    coef[..., 1::2] = np.moveaxis(2 * d[:, :, 1:].real, 2, -1)
    coef[..., 2::2] = np.moveaxis(-2 * d[:, :, 1:].imag, 2, -1)
    return coef


def load_scene_maps(path) -> SceneMaps:
    """The validated ``scene_maps`` table at ``path`` (a virtual one with its parts)."""
    check_virtual(path)
    t = read_table(path, kind=KIND, required=("alpha", "ratio", "row"))
    alpha, ratio, row = t["alpha"], t["ratio"], np.asarray(t["row"], np.int64)
    n = len(alpha)
    if ratio.shape[0] != n or not ratio.shape[1] or alpha.shape[1] * 2 % ratio.shape[1] or (row >= n).any() or (row < -1).any():
        raise errors.CorruptAssetError(
            str(path),
            f"inconsistent scene_maps tables: alpha {alpha.shape}, ratio {ratio.shape}, rows up to {row.max(initial=-1)}",
        )
    return SceneMaps(alpha, ratio, row, t.recipe, Path(path), dict(t.attrs))
