"""Opacity shadow maps (Kim thesis §6.2, Kim & Neumann 2001) for a directional light.

The hair is sliced by N planes perpendicular to the light at depths
D_1 < … < D_N (uniform slicing, Fig. 6-4a; D_0 is the depth of the hair point
nearest the light and D_N of the farthest).  Map i stores

    Ω_i(x, y) = ∫ σ_t dl from the light to depth D_i                   (6-1)

i.e. all hair nearer the light than D_i, "rendered" into a texel grid in the
light's image plane.  A point p at depth d ∈ [D_{i-1}, D_i] gets Ω by bilinear
sampling of Ω_{i-1} and Ω_i at its (x, y) and linear interpolation in depth
(6-2); its transmittance is τ = exp(−κΩ) (Table 6-1, line 16).

Units (Beer–Lambert, so Ω does not depend on the sampling step or the slice
count): every segment is cut into pieces no longer than ``spacing`` and each
piece deposits ``length × width / texel_area`` at its midpoint.  Ω is thus the
projected fibre area per unit map area: the mean number of fibres a ray meets
when the fibres lie across it.  ``width`` is the fibre width (per point from
``Strands.thickness`` when present, else 1.0, in which case Ω is hair length per
unit area and κ plays the part of the effective fibre width).  The thesis's
alpha per primitive (footnote 11) is ``κ × width × length / texel_area``.

Two jitted kernels: building (scatter-add of the pieces into (slice, y, x) bins,
then a cumulative sum along the slice axis) and the lookup of ``OpacityMaps.at``.
Computation is in float64.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..validate import check_int, check_real
from ..validate import points as check_points
from ._light import check_kappa, light_frame
from ._volume import trilinear

HIGHEST = jax.lax.Precision.HIGHEST  # stated, not inherited: XLA would use TF32 on NVIDIA GPUs

PADDING = 1  # empty texels around the hair's footprint, so bilinear lookups fall to Ω = 0 outside it


@dataclass(frozen=True, eq=False)
class OpacityMaps:
    """Opacity maps Ω (n_slices, H, W) on a light-aligned grid.

    ``frame`` rows are the unit axes (x, y, depth) of the light's image plane:
    ``frame[2]`` points away from the light, so depth = p·frame[2] grows along
    the light's rays.  Texel (j, i) covers ``origin + ([i, i+1], [j, j+1]) × spacing``
    in (x, y).  ``maps[k]`` holds Ω at depth ``depths[k]``; Ω = 0 at ``near``.
    """

    frame: np.ndarray  # (3, 3)
    origin: np.ndarray  # (2,) x, y of the grid corner
    spacing: float  # texel edge (world units)
    near: float  # D_0
    depths: np.ndarray  # (n_slices,) D_1 … D_N
    maps: np.ndarray  # (n_slices, H, W) Ω_i
    kappa: float

    @property
    def light(self) -> np.ndarray:
        """Unit direction toward the light."""
        return -self.frame[2]

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.maps.shape

    def opacity(self, points) -> np.ndarray:
        """Ω at world points (n, 3): bilinear in (x, y), linear between slices (6-2); 0 in front, Ω_N behind."""
        pts = check_points(points)
        dz = float(self.depths[0] - self.near)
        with jax.enable_x64(True):
            return np.asarray(
                _lookup(
                    jnp.asarray(pts),
                    jnp.asarray(self.maps),
                    jnp.asarray(self.frame),
                    jnp.asarray(self.origin),
                    self.spacing,
                    self.near,
                    dz,
                )
            )

    def at(self, points) -> np.ndarray:
        """(n,) transmittance τ = exp(−κΩ) ∈ [0, 1] toward the light at world points (n, 3)."""
        return np.exp(-self.kappa * self.opacity(points))


@functools.partial(jax.jit, static_argnames=("shape", "total"))
def _build(a, b, width, count, frame, origin, h, near, dz, shape, total):
    """Ω maps from segments a→b (E, 3) cut into ``count`` (E,) equal pieces (``total`` ≥ Σ count, static)."""
    n_slices, H, W = shape
    pa, pb = jnp.matmul(a, frame.T, precision=HIGHEST), jnp.matmul(b, frame.T, precision=HIGHEST)  # light frame: (x, y, depth)
    weight = jnp.linalg.norm(b - a, axis=1) * width / count / (h * h)
    seg = jnp.repeat(jnp.arange(a.shape[0]), count, total_repeat_length=total)
    start = jnp.cumsum(count) - count
    k = jnp.arange(total) - start[seg]
    real = jnp.arange(total) < jnp.sum(count)
    f = ((k + 0.5) / count[seg])[:, None]
    q = pa[seg] + f * (pb[seg] - pa[seg])
    ix = jnp.clip(jnp.floor((q[:, 0] - origin[0]) / h).astype(jnp.int32), 0, W - 1)
    iy = jnp.clip(jnp.floor((q[:, 1] - origin[1]) / h).astype(jnp.int32), 0, H - 1)
    iz = jnp.clip(jnp.floor((q[:, 2] - near) / dz).astype(jnp.int32), 0, n_slices - 1)
    bins = jnp.zeros(shape, a.dtype).at[iz, iy, ix].add(jnp.where(real, weight[seg], 0.0))
    return jnp.cumsum(bins, axis=0)


@jax.jit
def _lookup(points, maps, frame, origin, h, near, dz):
    n_slices, H, W = maps.shape
    q = jnp.matmul(points, frame.T, precision=HIGHEST)
    stack = jnp.concatenate([jnp.zeros((1, H, W), maps.dtype), maps])  # Ω(D_0) = 0
    s = jnp.clip((q[:, 2] - near) / dz, 0.0, n_slices)  # depth in slices, held at D_0 and D_N beyond them
    gx, gy = (q[:, 0] - origin[0]) / h - 0.5, (q[:, 1] - origin[1]) / h - 0.5  # texel centres at integers
    # (6-2): bilinear in (x, y), zero outside the maps, and linear in depth between the slices
    return trilinear(stack, jnp.stack([s, gy, gx], axis=-1))


def _bucket(n: int) -> int:
    """n rounded up to 1/8 of its power of two, so that small changes in hair length reuse the compiled kernel."""
    if n <= 64:
        return 64
    step = 1 << (n.bit_length() - 4)
    return -(-n // step) * step


def map_grid(q: np.ndarray, n_slices: int, resolution: int):
    """The maps' layout for hair points ``q`` (n, 3) in the light frame: texel origin (x, y), texel
    edge h (``resolution`` texels over the longer side of the footprint, plus PADDING around), the
    near depth, the slice spacing and the map shape (H, W)."""
    lo, hi = q.min(0), q.max(0)
    ext = hi - lo
    h = float(max(ext[0], ext[1])) / resolution or 1.0
    shape = tuple(int(np.floor(ext[i] / h)) + 1 + 2 * PADDING for i in (1, 0))
    return lo[:2] - PADDING * h, h, float(lo[2]), float(ext[2]) / n_slices or h, shape


def opacity_shadow_maps(
    strands,
    light,
    *,
    n_slices: int = 16,
    resolution: int = 128,
    kappa: float = 1.0,
    width: float | None = None,
    spacing: float | None = None,
    up=None,
) -> OpacityMaps:
    """Opacity shadow maps of ``strands`` (a :class:`hairlut.geometry.Strands`) for a directional light.

    ``light`` points toward the light.  ``resolution`` texels span the longer side of the hair's
    footprint in the light's image plane (plus one empty texel around it); ``n_slices`` uniform
    slices span its depth.  Segments are cut into pieces of at most ``spacing`` (default: a quarter of
    the smaller of the texel edge and the slice spacing).  See the module doc for the units of Ω.
    """
    from ..geometry import Strands

    if not isinstance(strands, Strands):
        raise errors.ValidationError("strands", type(strands).__name__, "need a hairlut.geometry.Strands")
    if strands.n_strands == 0:
        raise errors.ValidationError("strands", repr(strands), "need at least one strand")
    frame = light_frame(light, up)
    n_slices = check_int(n_slices, "n_slices", 1, 4096)
    resolution = check_int(resolution, "resolution", 1, 8192)
    kappa = check_kappa(kappa)
    width = None if width is None else check_real(width, "width", 0)
    spacing = None if spacing is None else check_real(spacing, "spacing", 0, lo_open=True)

    pts = np.asarray(strands.points, np.float64)
    origin, h, near, dz, (H, W) = map_grid(pts @ frame.T, n_slices, resolution)
    step = float(spacing) if spacing is not None else 0.25 * min(h, dz)

    seg = strands.segments
    a, b = pts[seg[:, 0]], pts[seg[:, 1]]
    if width is not None:
        wid = np.full(len(seg), float(width))
    elif strands.thickness is not None:
        th = np.asarray(strands.thickness, np.float64)
        wid = 0.5 * (th[seg[:, 0]] + th[seg[:, 1]])
    else:
        wid = np.ones(len(seg))
    count = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / step)).astype(np.int64)
    if count.sum() > 2**31 - 1:
        raise errors.ValidationError("spacing", step, f"would cut the hair into {count.sum()} pieces")
    with jax.enable_x64(True):
        maps = _build(
            jnp.asarray(a),
            jnp.asarray(b),
            jnp.asarray(wid),
            jnp.asarray(count),
            jnp.asarray(frame),
            jnp.asarray(origin),
            h,
            near,
            dz,
            shape=(n_slices, H, W),
            total=_bucket(int(count.sum())),
        )
        maps = np.asarray(maps)
    depths = near + dz * np.arange(1, n_slices + 1)
    return OpacityMaps(frame, origin, h, near, depths, maps, float(kappa))
