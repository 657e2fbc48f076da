"""Per-sector density features, the HRIR-DB index (satf §5.2, §6.2.1), and their normalisation.

For a density grid ρ[i, j] (i along s = phase, j along r = radius; cells of exact metric
area a_j, see ``density``) with bin centres s_i = (i + ½)/n_s and r_j = (j + ½)/n_r:

- ``rho_st`` = Σ ρ a / Σ a: the mean density over the sector's area (its mass over its
  area; grid-independent, since cell masses are exact);
- the density histograms along the two axes are the mean densities of the strips,
  h_s(i) = Σ_j ρ[i, j] a_j / Σ_j a_j and h_t(j) = (1/n_s) Σ_i ρ[i, j];
- ``rho_s`` = Σ_i s_i h_s(i) / Σ_i h_s(i) and ``rho_t`` = Σ_j r_j h_t(j) / Σ_j h_t(j):
  the "averages of the histogram curves" of §5.2 read as density-weighted centroids, in
  [0, 1] (the plain average of a histogram would only repeat ρ_st); an empty sector
  has centroids ½.

The richer, selectable set adds the spreads ``var_s`` = Σ (s_i − ρ_s)² h_s / Σ h_s and
``var_t`` (likewise), ``cov_st`` = Σ (s_i − ρ_s)(r_j − ρ_t) ρ[i, j] / Σ ρ, the
``contrast`` (area-weighted standard deviation of ρ over its mean, 0 if empty), the
``peak`` max ρ, and ``pc0`` … principal-component scores of the grid (a fitted
:class:`PCABasis`).  Feature sets by name: "basic" (ρ_st, ρ_s, ρ_t), "moments" (basic +
var_s, var_t, cov_st, contrast, peak), "projection" (``proj0`` … ``proj23``: principal-component
scores of each sector's own density projected at 8 views, which need the sector's tracer
geometry and so are computed by ``hairlut.hrir.projection_features``, not here).  :class:`FeatureStats` holds per-feature mean and
standard deviation so distances in the normalised space weigh features alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ValidationError
from .splats import SplatBatch

BASIC = ("rho_st", "rho_s", "rho_t")
MOMENTS = BASIC + ("var_s", "var_t", "cov_st", "contrast", "peak")
PROJECTION = tuple(f"proj{k}" for k in range(24))
FEATURE_SETS = {"basic": BASIC, "moments": MOMENTS, "projection": PROJECTION}
_ALL = MOMENTS


def feature_names(features="basic", pca: PCABasis | None = None) -> tuple[str, ...]:
    """Resolve a set name ("basic", "moments") or a list of names; ``pc<k>`` needs ``pca``."""
    names = FEATURE_SETS.get(features) if isinstance(features, str) else None
    if names is None:
        names = (features,) if isinstance(features, str) else tuple(features)
    if not names:
        raise ValidationError("features", features, "select at least one feature")
    if names == PROJECTION:
        return names
    for n in names:
        if n in _ALL:
            continue
        if isinstance(n, str) and n.startswith("pc") and n[2:].isdigit():
            if pca is None or int(n[2:]) >= pca.n_components:
                raise ValidationError("features", n, "principal-component scores need a PCABasis with that many components")
            continue
        raise ValidationError(
            "features", n, f"unknown feature; known: {', '.join(_ALL)}, pc0…, or sets {', '.join(FEATURE_SETS)}"
        )
    return tuple(names)


@jax.jit
def _moments(rho, row_area):
    n_s, n_r = rho.shape[1:]
    s = (jnp.arange(n_s, dtype=rho.dtype) + 0.5) / n_s
    r = (jnp.arange(n_r, dtype=rho.dtype) + 0.5) / n_r
    a = row_area[:, None, :]
    total_a = jnp.sum(a, axis=(1, 2)) * n_s
    mean = jnp.sum(rho * a, axis=(1, 2)) / total_a
    h_s = jnp.sum(rho * a, axis=2) / jnp.sum(row_area, axis=1)[:, None]
    h_t = jnp.mean(rho, axis=1)

    def centroid(h, x):
        tot = jnp.sum(h, axis=1)
        ok = tot > 0
        c = jnp.where(ok, jnp.sum(h * x, axis=1) / jnp.where(ok, tot, 1.0), 0.5)
        var = jnp.where(ok, jnp.sum(h * (x - c[:, None]) ** 2, axis=1) / jnp.where(ok, tot, 1.0), 0.0)
        return c, var

    c_s, v_s = centroid(h_s, s)
    c_t, v_t = centroid(h_t, r)
    tot = jnp.sum(rho, axis=(1, 2))
    ok = tot > 0
    cov = jnp.sum(rho * (s[None, :, None] - c_s[:, None, None]) * (r[None, None, :] - c_t[:, None, None]), axis=(1, 2))
    cov = jnp.where(ok, cov / jnp.where(ok, tot, 1.0), 0.0)
    var_rho = jnp.sum((rho - mean[:, None, None]) ** 2 * a, axis=(1, 2)) / total_a
    contrast = jnp.where(mean > 0, jnp.sqrt(var_rho) / jnp.where(mean > 0, mean, 1.0), 0.0)
    peak = jnp.max(rho, axis=(1, 2))
    return {
        "rho_st": mean,
        "rho_s": c_s,
        "rho_t": c_t,
        "var_s": v_s,
        "var_t": v_t,
        "cov_st": cov,
        "contrast": contrast,
        "peak": peak,
    }


def _row_areas(areas, density: np.ndarray) -> np.ndarray:
    n, n_s, n_r = density.shape
    if isinstance(areas, SplatBatch):
        return areas.row_areas(n_s, n_r)
    if areas is None:
        return np.ones((n, n_r))
    arr = np.asarray(areas, dtype=np.float64)
    if arr.shape != (n, n_r) or not (arr > 0).all():
        raise ValidationError("areas", arr.shape, f"need ({n}, {n_r}) positive row areas, or the SplatBatch")
    return arr


def sector_features(density, areas=None, features="basic", *, pca: PCABasis | None = None, chunk: int = 4096) -> np.ndarray:
    """(N, F) features of (N, n_s, n_r) density grids; ``areas``: the SplatBatch (for the row
    areas) or (N, n_r) row areas, None for equal cells.  Computed in float64, ``chunk``
    sectors at a time (one compiled shape)."""
    rho = np.asarray(density)
    if rho.ndim != 3 or rho.dtype.kind not in "fiu":
        raise ValidationError("density", rho.shape, "need (N, n_s, n_r) grids of numbers")
    names = feature_names(features, pca)
    if names == PROJECTION:
        raise ValidationError(
            "features", "projection", "projection features need each sector's tracer geometry: hairlut.hrir.projection_features"
        )
    rows = _row_areas(areas, rho)
    n = len(rho)
    size = min(int(chunk), 1 << (max(n, 8) - 1).bit_length())
    parts = []
    with jax.enable_x64(True):
        for start in range(0, n, size):
            part = np.asarray(rho[start : start + size], dtype=np.float64)
            area = rows[start : start + size]
            if len(part) < size:  # pad the last chunk (zeros and unit areas) to the chunk shape
                part = np.concatenate([part, np.zeros((size - len(part),) + part.shape[1:])])
                area = np.concatenate([area, np.ones((size - len(area), area.shape[1]))])
            out = _moments(jnp.asarray(part), jnp.asarray(area))
            parts.append({k: np.asarray(v)[: min(size, n - start)] for k, v in out.items()})
    mom = {k: np.concatenate([p[k] for p in parts]) if parts else np.zeros(0) for k in _ALL}
    if any(n.startswith("pc") for n in names):
        scores = pca.transform(rho)
        mom.update({f"pc{k}": scores[:, k] for k in range(pca.n_components)})
    return np.stack([mom[n] for n in names], axis=1) if len(rho) else np.zeros((0, len(names)))


@dataclass(frozen=True, eq=False)
class PCABasis:
    """Principal components of flattened density grids: ``mean`` (n_s·n_r,), ``components`` (k, n_s·n_r)."""

    grid: tuple[int, int]
    mean: np.ndarray
    components: np.ndarray

    @property
    def n_components(self) -> int:
        return len(self.components)

    @classmethod
    def fit(cls, density, n_components: int = 4) -> PCABasis:
        """Fit ``n_components`` principal components to (N ≥ 2, n_s, n_r) density grids."""
        rho = np.asarray(density, dtype=np.float64)
        if rho.ndim != 3 or len(rho) < 2:
            raise ValidationError("density", rho.shape, "need (N ≥ 2, n_s, n_r) grids to fit components")
        if (
            isinstance(n_components, bool)
            or not isinstance(n_components, (int, np.integer))
            or not 1 <= n_components <= min(len(rho), rho.shape[1] * rho.shape[2])
        ):
            raise ValidationError("n_components", n_components, "need 1 ≤ k ≤ min(N, n_s·n_r)")
        flat = rho.reshape(len(rho), -1)
        mean = flat.mean(axis=0)
        _, _, vt = np.linalg.svd(flat - mean, full_matrices=False)
        comps = vt[:n_components]
        comps *= np.where(comps.sum(axis=1, keepdims=True) < 0, -1.0, 1.0)  # deterministic signs
        return cls(rho.shape[1:], mean, comps)

    def transform(self, density) -> np.ndarray:
        """Scores (N, k) of (N, n_s, n_r) density grids on the fitted components."""
        rho = np.asarray(density, dtype=np.float64)
        if rho.shape[1:] != tuple(self.grid):
            raise ValidationError("density", rho.shape, f"the basis was fitted on {self.grid} grids")
        return (rho.reshape(len(rho), -1) - self.mean) @ self.components.T


@dataclass(frozen=True, eq=False)
class FeatureStats:
    """Per-feature mean and standard deviation: ``normalize(x) = (x − mean) / std``."""

    names: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, features, names: Sequence[str]) -> FeatureStats:
        """Mean and standard deviation of (N ≥ 2, F) feature rows, one column per name."""
        x = np.asarray(features, dtype=np.float64)
        names = tuple(names)
        if x.ndim != 2 or x.shape[1] != len(names) or len(x) < 2:
            raise ValidationError("features", x.shape, f"need (N ≥ 2, {len(names)}) feature rows")
        std = x.std(axis=0)
        floor = 1e-12 * np.maximum(np.abs(x).max(axis=0), 1.0)
        return cls(names, x.mean(axis=0), np.maximum(std, floor))

    def normalize(self, features) -> np.ndarray:
        """(x − mean) / std, per feature."""
        return (np.asarray(features, dtype=np.float64) - self.mean) / self.std

    def denormalize(self, z) -> np.ndarray:
        """The inverse of :meth:`normalize`: z · std + mean."""
        return np.asarray(z, dtype=np.float64) * self.std + self.mean

    def to_dict(self) -> dict:
        """Names, means and standard deviations as JSON-ready lists."""
        return {"names": list(self.names), "mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> FeatureStats:
        """The inverse of :meth:`to_dict`."""
        return cls(tuple(d["names"]), np.asarray(d["mean"], dtype=np.float64), np.asarray(d["std"], dtype=np.float64))
