"""Evaluated cluster geometry: frames, sections and positions P(t, v, u) for a batch (eqs 1–3).

:class:`ClusterGeometry` builds, once per batch and in float64, each cluster's arc-length
table and rotation-minimising frame table (see ``_frames``), then answers queries:

- ``sections(t)``: origin, tangent, reference r, binormal b and A, B, q at t, per cluster;
- ``positions(t, v, u)``: eq 1 for every cluster at broadcast parameters;
- ``positions_of(cluster, t, v, u)``: eq 1 for per-item cluster indices;
- ``derivatives(t, v, u)``: P with ∂P/∂t and ∂P/∂u (analytic, see ``_frames``), for meshes.

t is the relative arc length along T(t) ∈ [0, 1]; v ∈ [0, 1] the radial fraction of
the ellipse; u the phase in radians.  Everything returned is float64 NumPy.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ValidationError
from . import _frames
from .cluster import ClusterBatch, ClusterSpec, MacroCluster

DEFAULT_FRAME_SAMPLES = 257


class Section(NamedTuple):
    """A cross-section's frame and ellipse (eq 1): vectors (..., 3), scalars (...).

    ``normal`` is the rotation-minimising reference r, ``binormal`` = tangent × r;
    ``a``, ``b``, ``twist`` are A(t), B(t), q(t).
    """

    origin: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    binormal: np.ndarray
    a: np.ndarray
    b: np.ndarray
    twist: np.ndarray

    def take(self, *index) -> Section:
        """The sections at ``index`` (NumPy indexing of the leading axes)."""
        return Section(*(f[index] for f in self))

    def point(self, v, u) -> np.ndarray:
        """Eq 1 at these sections: (…, 3); v and u broadcast against the scalar fields' shape."""
        phi = self.twist + u
        return (
            self.origin
            + (v * self.a * np.cos(phi))[..., None] * self.normal
            + (v * self.b * np.sin(phi))[..., None] * self.binormal
        )


# These kernels run once per batch or query and are cheap; XLA's backend optimisation
# would double their compile time (seconds on CPU) to save milliseconds, so it is off.
_QUICK = {"xla_backend_optimization_level": 0}


@partial(jax.jit, compiler_options=_QUICK)
def _arc(arrs):
    return jax.vmap(_frames.arc_table)(arrs)


@partial(jax.jit, static_argnames=("n_frames",), compiler_options=_QUICK)
def _build(arrs, n_frames):
    return jax.vmap(lambda tab: _frames.build_frames(tab, n_frames))(arrs)


@partial(jax.jit, compiler_options=_QUICK)
def _sections(tables, t):
    return jax.vmap(_frames.section)(tables, t)


def _point(sec: dict, v, u) -> np.ndarray:
    """Eq 1 from a kernel's section dict: T + v·(A cos(q + u)·r + B sin(q + u)·b)."""
    return Section(*(sec[k] for k in Section._fields)).point(v, u)


def _point_derivatives(sec: dict, length, v, u):
    """P, ∂P/∂t, ∂P/∂u of eq 1, analytically.

    With L the length, κ = dT̂/ds and the rotation-minimising law dr/ds = −(r·κ) T̂
    (likewise b): ∂T/∂t = L T̂, ∂r/∂t = −L (r·κ) T̂; A′, B′, q′ come from their splines.
    """
    tan, r, b, kappa = sec["tangent"], sec["normal"], sec["binormal"], sec["kappa"]
    big_l = np.asarray(length)[..., None]
    dr = -big_l * np.sum(r * kappa, -1, keepdims=True) * tan
    db = -big_l * np.sum(b * kappa, -1, keepdims=True) * tan
    phi = sec["twist"] + u
    c, s = np.cos(phi), np.sin(phi)
    a_, b_, da, dbb, dq = sec["a"], sec["b"], sec["da"], sec["db"], sec["dtwist"]
    dt = (
        big_l * tan
        + (v * (da * c - a_ * dq * s))[..., None] * r
        + (v * (dbb * s + b_ * dq * c))[..., None] * b
        + (v * a_ * c)[..., None] * dr
        + (v * b_ * s)[..., None] * db
    )
    du = (-v * a_ * s)[..., None] * r + (v * b_ * c)[..., None] * b
    return _point(sec, v, u), dt, du


def as_batch(clusters) -> ClusterBatch:
    """A ClusterBatch from a batch, a spec, a macro-cluster, or a sequence of specs."""
    if isinstance(clusters, ClusterBatch):
        return clusters
    if isinstance(clusters, ClusterSpec):
        return ClusterBatch.stack([clusters])
    if isinstance(clusters, MacroCluster):
        return clusters.batch()
    if isinstance(clusters, Sequence) and clusters:
        return ClusterBatch.stack(list(clusters))
    raise ValidationError("clusters", type(clusters).__name__, "give a ClusterBatch, ClusterSpec, MacroCluster or list of specs")


class ClusterGeometry:
    """Frame and arc-length tables of a cluster batch, and eq-1 queries on them (float64)."""

    def __init__(self, clusters, *, frame_samples: int = DEFAULT_FRAME_SAMPLES):
        if isinstance(frame_samples, bool) or not isinstance(frame_samples, (int, np.integer)) or frame_samples < 2:
            raise ValidationError("frame_samples", frame_samples, "need an integer ≥ 2")
        self.batch = as_batch(clusters)
        arrays = self.batch.arrays()
        blocks = []
        with jax.enable_x64(True):
            for rows in _cluster_blocks(self.n_clusters):
                arrs = {k: v[rows] for k, v in arrays.items()}
                arc = np.asarray(_arc({k: jnp.asarray(v) for k, v in arrs.items()}))
                arrs.update(arc=arc, arc_inv=_frames.inverse_arc_table(arc))
                frames = _build({k: jnp.asarray(v) for k, v in arrs.items()}, int(frame_samples))
                blocks.append(arrs | {k: np.asarray(v) for k, v in frames.items()})
        self._blocks = blocks
        self._tables = {k: np.concatenate([b[k] for b in blocks])[: self.n_clusters] for k in blocks[0]}
        self.lengths = self._tables["arc"][:, -1].copy()
        slow = self._tables["min_speed"] <= 1e-9 * self.lengths
        if slow.any():
            i = int(np.flatnonzero(slow)[0])
            raise ValidationError(
                f"specs[{i}].trajectory",
                self.batch.specs[i].trajectory.control.tolist(),
                "the trajectory's speed vanishes somewhere (a stationary point has no tangent)",
            )
        self.track_bounds = self._tables["track_bounds"]

    # -- sizes -------------------------------------------------------------------------------
    @property
    def n_clusters(self) -> int:
        return self.batch.n_clusters

    @property
    def sampling(self) -> tuple[int, int, int]:
        return self.batch.sampling

    @property
    def n_layers(self) -> int:
        return self.batch.n_layers

    @property
    def frame_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(C, F, 3) origins, tangents and rotation-minimising references at uniform t."""
        return self._tables["frame_x"], self._tables["frame_tangent"], self._tables["frame_ref"]

    # -- queries -----------------------------------------------------------------------------
    def _run(self, fn, t, columns: int | None = None):
        """fn(tables, t) on (C, M) parameters, in blocks of fixed shapes so compiled kernels are reused:
        clusters in groups of 4 or 16, parameters in columns of 64, 512 or chunks of 4096 (chosen for ``columns``
        parameters a row when given, else M: the kernel of a wider query, so the same bits as that query's)."""
        n_c, m = t.shape
        width = next((w for w in (64, 512) if max(m, columns or 0) <= w), _CHUNK)
        cols = -(-m // width) * width
        parts = []
        with jax.enable_x64(True):
            for rows, tab in zip(_cluster_blocks(n_c), self._blocks):
                tt = np.zeros((len(rows), cols))
                tt[:, :m] = t[rows]
                jtab = {k: jnp.asarray(v) for k, v in tab.items()}
                chunks = [fn(jtab, jnp.asarray(tt[:, c0 : c0 + width])) for c0 in range(0, cols, width)]
                keep = len(np.unique(rows))
                parts.append({k: np.concatenate([np.asarray(c[k]) for c in chunks], axis=1)[:keep, :m] for k in chunks[0]})
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    def _tile(self, *arrays):
        arrs = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in arrays))
        shape = arrs[0].shape
        flat = [np.broadcast_to(a.reshape(1, -1), (self.n_clusters, a.size)) for a in arrs]
        return shape, flat

    def _section_all(self, t) -> tuple[tuple, dict]:
        shape, (tt,) = self._tile(t)
        return shape, self._run(_sections, tt)

    def sections(self, t) -> Section:
        """Section at each t for every cluster: fields shaped (C, *t.shape[, 3])."""
        shape, sec = self._section_all(t)
        return Section(*(sec[k].reshape((self.n_clusters,) + shape + sec[k].shape[2:]) for k in Section._fields))

    def positions(self, t, v, u) -> np.ndarray:
        """(C, *shape, 3) points P(t, v, u) of eq 1 for every cluster; t, v, u broadcast together."""
        _check_finite(t=t, v=v, u=u)
        t, v, u = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (t, v, u)))
        shape, sec = self._section_all(t)
        return _point(sec, v.reshape(1, -1), u.reshape(1, -1)).reshape((self.n_clusters,) + shape + (3,))

    def derivatives(self, t, v, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """P, ∂P/∂t, ∂P/∂u, each (C, *shape, 3)."""
        _check_finite(t=t, v=v, u=u)
        t, v, u = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (t, v, u)))
        shape, sec = self._section_all(t)
        out = _point_derivatives(sec, self.lengths[:, None], v.reshape(1, -1), u.reshape(1, -1))
        return tuple(o.reshape((self.n_clusters,) + shape + (3,)) for o in out)

    def _section_of(self, cluster, t) -> dict:
        """Section dict at per-item (cluster, t), flattened to (M, ...)."""
        cl = np.asarray(cluster)
        if cl.dtype.kind not in "iu":
            raise ValidationError("cluster", cl.dtype, "cluster indices must be integers")
        cl, tt = (a.ravel() for a in np.broadcast_arrays(cl, np.asarray(t, dtype=np.float64)))
        if cl.size and (cl.min() < 0 or cl.max() >= self.n_clusters):
            raise ValidationError(
                "cluster",
                int(cl.min() if cl.min() < 0 else cl.max()),
                f"cluster index out of range for {self.n_clusters} clusters",
            )
        # a section depends on (cluster, t) alone: each distinct pair is swept once (a grid of texels or mesh vertices
        # repeats every t over its u and v: 192 times in a 3-layer, 64-texel-wide grid) and handed to all its items
        by = np.lexsort((tt, cl))
        fresh = np.ones(cl.size, dtype=bool)
        fresh[1:] = (cl[by][1:] != cl[by][:-1]) | (tt[by][1:] != tt[by][:-1])
        inverse = np.empty(cl.size, dtype=np.int64)
        inverse[by] = np.cumsum(fresh) - 1
        ucl, utt = cl[by][fresh], tt[by][fresh]
        counts = np.bincount(ucl, minlength=self.n_clusters)
        width = max(int(counts.max()) if ucl.size else 0, 1)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        slot = np.arange(ucl.size) - np.repeat(starts, counts)  # ucl is sorted: each cluster's pairs in a row
        padded = np.zeros((self.n_clusters, width))
        padded[ucl, slot] = utt
        # the kernel the items would have run on, not one fitted to the fewer pairs: XLA compiles each width alone,
        # and a narrower one rounds some sections differently (~1e-14)
        sec = self._run(_sections, padded, columns=int(np.bincount(cl, minlength=self.n_clusters).max()) if cl.size else 1)
        out = {k: v[ucl, slot][inverse] for k, v in sec.items()}
        out["length"] = self.lengths[cl]
        return out

    def positions_of(self, cluster, t, v, u) -> np.ndarray:
        """(*shape, 3) points P(t, v, u) in the given clusters (per-item indices; all broadcast)."""
        _check_finite(t=t, v=v, u=u)
        cl, t, v, u = np.broadcast_arrays(np.asarray(cluster), *(np.asarray(a, dtype=np.float64) for a in (t, v, u)))
        sec = self._section_of(cl, t)
        return _point(sec, v.ravel(), u.ravel()).reshape(cl.shape + (3,))

    def derivatives_of(self, cluster, t, v, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """P, ∂P/∂t, ∂P/∂u (*shape, 3) at per-item clusters."""
        _check_finite(t=t, v=v, u=u)
        cl, t, v, u = np.broadcast_arrays(np.asarray(cluster), *(np.asarray(a, dtype=np.float64) for a in (t, v, u)))
        sec = self._section_of(cl, t)
        out = _point_derivatives(sec, sec["length"], v.ravel(), u.ravel())
        return tuple(o.reshape(cl.shape + (3,)) for o in out)

    def sections_of(self, cluster, t) -> Section:
        """Sections at per-item (cluster, t): fields shaped (*shape[, 3])."""
        shape = np.broadcast_shapes(np.shape(cluster), np.shape(t))
        sec = self._section_of(cluster, t)
        return Section(*(sec[k].reshape(shape + sec[k].shape[1:]) for k in Section._fields))


_CHUNK = 4096


def _cluster_blocks(n: int) -> list[np.ndarray]:
    """Row indices of cluster blocks: as many full blocks of 16 as fit, the rest in blocks of 4,
    the last padded by repeating cluster n − 1 (so at most 3 padded rows)."""
    starts = list(range(0, n - n % 16, 16))
    sizes = [16] * len(starts)
    for start in range(n - n % 16, n, 4):
        starts.append(start)
        sizes.append(4)
    return [np.minimum(np.arange(s0, s0 + size), n - 1) for s0, size in zip(starts, sizes)]


def _check_finite(**arrays) -> None:
    for name, a in arrays.items():
        arr = np.asarray(a, dtype=np.float64)
        if not np.isfinite(arr).all():
            raise ValidationError(name, a, "parameters must be finite")
