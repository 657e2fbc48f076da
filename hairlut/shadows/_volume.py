"""Hair density volumes: strands voxelised on an axis-aligned grid (xing §5, eq 6).

The density of a voxel is the length of hair inside it divided by the voxel
edge s, i.e. "the number of strands passing through the voxel" for strands that
cross it straight.  Each segment is resampled at ``SUBSTEPS`` points per voxel
edge and every sample deposits its share of the segment length into its voxel,
so the total deposited mass equals the total strand length / s exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..validate import check_int

SUBSTEPS = 4


@dataclass(frozen=True)
class Volume:
    """A scalar field on voxel centres: ``origin`` is the corner of voxel (0,0,0), ``size`` the edge s."""

    density: np.ndarray  # (nx, ny, nz)
    origin: np.ndarray  # (3,)
    size: float

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.density.shape

    def to_grid(self, points) -> np.ndarray:
        """World points → continuous voxel coordinates (voxel i's centre at i)."""
        return (np.asarray(points, np.float64) - self.origin) / self.size - 0.5

    def centres(self, index) -> np.ndarray:
        """World positions of the centres of the voxels at integer ``index`` (…, 3)."""
        return self.origin + (np.asarray(index, np.float64) + 0.5) * self.size


def voxelize(strands, resolution: int = 64, padding: int = 2) -> Volume:
    """Density volume of a :class:`hairlut.geometry.Strands` on a cubic-voxel grid.

    ``resolution`` voxels span the longest side of the bounding box; ``padding``
    empty voxels surround it so that rays leave the hair before the grid ends.
    """
    resolution = check_int(resolution, "resolution", 2, 1024)
    padding = check_int(padding, "padding", 0)
    pts = np.asarray(strands.points, np.float64)
    if len(pts) < 2:
        raise errors.ValidationError("strands", strands.n_points, "need at least one segment")
    lo, hi = pts.min(0), pts.max(0)
    size = float((hi - lo).max()) / resolution or 1.0
    shape = tuple(int(np.ceil((hi[i] - lo[i]) / size)) + 1 + 2 * padding for i in range(3))
    origin = lo - padding * size - 0.5 * size
    seg = strands.segments  # (E, 2) point indices
    a, b = pts[seg[:, 0]], pts[seg[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(1, np.ceil(length / size * SUBSTEPS)).astype(int)
    rep = np.repeat(np.arange(len(seg)), n)
    k = np.arange(rep.size) - np.repeat(np.cumsum(n) - n, n)
    f = ((k + 0.5) / n[rep])[:, None]
    samples = a[rep] * (1 - f) + b[rep] * f
    idx = np.floor((samples - origin) / size).astype(int)
    idx = np.clip(idx, 0, np.array(shape) - 1)
    density = np.zeros(shape)
    np.add.at(density, tuple(idx.T), (length / n)[rep] / size)
    return Volume(density, origin, size)


def gradient(density) -> jax.Array:
    """Central differences (eq 6): u·∇ρ(x) = (ρ(x+u) − ρ(x−u)) / 2, per voxel edge; zero outside. → (..., 3)."""
    p = jnp.pad(jnp.asarray(density), 1)
    return jnp.stack(
        [
            (p[2:, 1:-1, 1:-1] - p[:-2, 1:-1, 1:-1]) / 2,
            (p[1:-1, 2:, 1:-1] - p[1:-1, :-2, 1:-1]) / 2,
            (p[1:-1, 1:-1, 2:] - p[1:-1, 1:-1, :-2]) / 2,
        ],
        axis=-1,
    )


def trilinear(field, coords):
    """Sample a voxel field (nx, ny, nz[, C]) at continuous voxel coordinates (..., 3); zero outside."""
    shape = jnp.array(field.shape[:3])
    base = jnp.floor(coords)
    frac = coords - base
    base = base.astype(jnp.int32)
    out = 0.0
    for corner in range(8):
        offs = jnp.array([(corner >> 2) & 1, (corner >> 1) & 1, corner & 1])
        idx = base + offs
        inside = jnp.all((idx >= 0) & (idx < shape), axis=-1)
        w = jnp.prod(jnp.where(offs == 1, frac, 1 - frac), axis=-1) * inside
        val = field[tuple(jnp.clip(idx, 0, shape - 1)[..., i] for i in range(3))]
        out = out + (w[..., None] * val if val.ndim > w.ndim else w * val)
    return out
