"""3D light-oriented density/shadow map (bertails §2–3).

The map is a uniform grid of cubic cells in the light frame R = (O, X_map, Y_map, Z_map)
with X_map = L, the unit direction *toward* the light (§2.1).  Each build:

1. density (§3.1): every segment is resampled at ``SUBSTEPS`` points per cell edge and each
   sample adds its share of the segment length to its cell; ``density`` is hair length per
   unit volume (length / ds³), so the total mass is the total strand length exactly;
2. transmittance (§3.2, eqs 1–3): along each column (j, k) the optical depth at a cell
   centre is the mass of the cells nearer the light plus half of the cell itself,

       τ(i) = ds · (Σ_{i' > i} ρ(i') + ρ(i) / 2),      Trans(i) = exp(−κ τ(i)),

   i.e. eq (3) with f = κ, evaluated at cell centres rather than back faces.  Because ρ is
   per unit volume and τ = ∫ ρ dl, the opacity does not depend on the grid step; κ has units
   of length (the light-blocking width of a fibre);
3. filtering (§3.3): ``LightOrientedMap.at`` interpolates Trans trilinearly between cell
   centres.  Points beyond the grid's back face take the last slice's value; points beside
   the grid or in front of it see no hair (Trans = 1).

Unlike §2.2 (a fixed box sized by the longest strand) the grid is fitted to the hair's bounding
box in the light frame each call; its *shape* depends only on ``resolution`` and ``padding``,
so animated hair re-uses one compiled kernel.  The frame's roll about L is fixed by L alone
(Duff et al. 2017 branchless basis), so a fixed light gives a temporally stable grid.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..geometry.strands import Strands
from ..validate import check_int, direction
from ..validate import points as check_points
from ._light import check_kappa, light_frame
from ._volume import trilinear

HIGHEST = jax.lax.Precision.HIGHEST  # stated, not inherited: XLA would use TF32 on NVIDIA GPUs

SUBSTEPS = 4  # density samples per cell edge along a segment
MAX_CELLS = 1 << 27


@functools.partial(jax.jit, static_argnames=("shape", "n_sub"))
def _map_kernel(a, b, frame, origin, ds, kappa, shape, n_sub):
    """Segments (E, 3) → (density, transmittance), both ``shape``, in the light frame."""
    pa, pb = jnp.matmul(a, frame.T, precision=HIGHEST), jnp.matmul(b, frame.T, precision=HIGHEST)
    length = jnp.linalg.norm(b - a, axis=1)
    f = (jnp.arange(n_sub) + 0.5) / n_sub
    samples = pa[:, None, :] + f[None, :, None] * (pb - pa)[:, None, :]  # (E, n_sub, 3)
    dims = jnp.array(shape)
    idx = jnp.clip(jnp.floor((samples - origin) / ds).astype(jnp.int32), 0, dims - 1)
    flat = (idx[..., 0] * shape[1] + idx[..., 1]) * shape[2] + idx[..., 2]
    mass = jnp.broadcast_to((length / n_sub)[:, None], flat.shape)
    density = jnp.zeros(shape[0] * shape[1] * shape[2], a.dtype).at[flat.ravel()].add(mass.ravel())
    density = density.reshape(shape) / ds**3
    # the light is toward +X_map: accumulate from the last slice (nearest the light) backwards
    ahead = jnp.flip(jnp.cumsum(jnp.flip(density, 0), 0), 0)  # Σ_{i' ≥ i}
    depth = (ahead - 0.5 * density) * ds
    return density, jnp.exp(-kappa * depth)


@jax.jit
def _query_kernel(occlusion, coords):
    """Trilinear (§3.3, :func:`~hairlut.shadows.trilinear`) of 1 − Trans at continuous cell coordinates:
    zero beside the grid, clamped along the light axis (in front of the map: Trans = 1; behind it: the last cell)."""
    coords = coords.at[:, 0].set(jnp.clip(coords[:, 0], 0.0, occlusion.shape[0] - 1.0))
    return 1.0 - trilinear(occlusion, coords)


@dataclass(frozen=True, eq=False)
class LightOrientedMap:
    """A light-oriented shadow map (bertails §2).

    ``frame`` rows are (X_map = light, Y_map, Z_map); ``origin`` is the map-frame position of
    the outer corner of cell (0, 0, 0) and ``spacing`` the cell edge ds; cell (i, j, k) has its
    centre at ``origin + (i, j, k) · ds + ds / 2`` and index i grows toward the light.
    ``density`` is hair length per unit volume, ``transmittance`` Trans at cell centres.
    """

    frame: np.ndarray  # (3, 3)
    origin: np.ndarray  # (3,) map coordinates
    spacing: float
    density: np.ndarray  # (nx, ny, nz)
    transmittance: np.ndarray  # (nx, ny, nz)
    kappa: float

    @property
    def light(self) -> np.ndarray:
        return self.frame[0]

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.density.shape

    def to_map(self, points) -> np.ndarray:
        """World points (..., 3) → map-frame coordinates (the mapping Ψ of §2.2, before flooring)."""
        return np.asarray(points, np.float64) @ self.frame.T

    def to_grid(self, points) -> np.ndarray:
        """World points → continuous cell coordinates (cell i's centre at i)."""
        return (self.to_map(points) - self.origin) / self.spacing - 0.5

    def at(self, points) -> np.ndarray:
        """(n,) filtered transmittance in [0, 1] at world points (n, 3) (§3.3)."""
        pts = check_points(points)
        with jax.enable_x64(True):
            occ = jnp.asarray(1.0 - self.transmittance)
            return np.clip(np.asarray(_query_kernel(occ, jnp.asarray(self.to_grid(pts)))), 0.0, 1.0)


def _check_resolution(resolution) -> tuple[int, int, int]:
    items = (resolution,) * 3 if isinstance(resolution, (int, np.integer)) else resolution
    try:
        items = tuple(items)
    except TypeError:
        raise errors.ValidationError("resolution", resolution, "need an int or (nx, ny, nz)") from None
    if len(items) != 3:
        raise errors.ValidationError("resolution", resolution, "need an int or 3 ints, each in [1, 1024]")
    return tuple(check_int(n, "resolution", 1, 1024) for n in items)


def light_oriented_map(strands: Strands, light, *, resolution=64, kappa: float, padding: int = 2) -> LightOrientedMap:
    """Build the light-oriented density and transmittance map of ``strands`` (bertails §2–3).

    ``light`` is the direction toward the (distant) light (normalised here).  ``resolution`` cells (an int
    or one count per map axis X_map, Y_map, Z_map) span the hair's extent along each map axis
    with cubic cells, the longest extent relative to its count fixing ds; the grid adds one
    cell plus ``padding`` cells on each side, so its shape is ``resolution + 1 + 2·padding``.
    ``kappa`` (≥ 0, a length) scales optical depth: Trans = exp(−κ ∫ ρ dl) (eq 1).
    """
    if not isinstance(strands, Strands):
        raise errors.ValidationError("strands", type(strands).__name__, "need a hairlut.geometry.Strands")
    if strands.n_strands == 0:
        raise errors.ValidationError("strands", 0, "need at least one strand")
    L = direction(light, "light")
    res = _check_resolution(resolution)
    padding = check_int(padding, "padding", 0, 64)
    kappa = check_kappa(kappa)
    shape = tuple(n + 1 + 2 * int(padding) for n in res)
    if np.prod(shape, dtype=np.int64) > MAX_CELLS:
        raise errors.ValidationError("resolution", resolution, f"the grid {shape} exceeds {MAX_CELLS} cells")

    x, y, depth = light_frame(L)
    frame = np.stack([-depth, y, x])  # rows (X_map = light, Y_map, Z_map), right-handed (§2.1)
    pts = np.asarray(strands.points, np.float64)
    local = pts @ frame.T
    lo, hi = local.min(0), local.max(0)
    ds = float(np.max((hi - lo) / np.array(res))) or 1.0
    origin = 0.5 * (lo + hi) - 0.5 * ds * np.array(shape)
    seg = strands.segments
    a, b = pts[seg[:, 0]], pts[seg[:, 1]]
    longest = float(np.linalg.norm(b - a, axis=1).max()) if len(seg) else 0.0
    n_sub = 1 << max(0, int(np.ceil(np.log2(max(1.0, np.ceil(longest / ds * SUBSTEPS))))))  # power of two: few recompiles
    with jax.enable_x64(True):
        density, trans = _map_kernel(
            jnp.asarray(a), jnp.asarray(b), jnp.asarray(frame), jnp.asarray(origin), ds, kappa, shape, n_sub
        )
        density, trans = np.asarray(density), np.asarray(trans)
    return LightOrientedMap(frame, origin, ds, density, trans, kappa)
