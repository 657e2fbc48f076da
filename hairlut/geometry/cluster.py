"""Generalized disk hair clusters (satf §3.1–3.2): validated specs, batches and macro-clusters.

A cluster H = Modeling(T(t), A(t), B(t), q(t)) (eq 2): an ellipse with half-axes A(t),
B(t) and self-twist phase q(t) swept along the 3-D B-spline trajectory T(t) in its
normal plane (eq 1).  The shells are the surfaces v = ``layer_radii[k]`` (fractions of
the ellipse, v ∈ [0, 1] as in eq 1); shell k is the volume between the previous
surface (the core, v = ``core_radius``, for k = 0) and surface k.  Eq 3 samples
t in s_t steps, u in s_u steps of 2π/s_u and v in s_v steps; here the v steps subdivide
each shell (mapped affinely onto it), so s_v = 1 gives one track per layer.

A :class:`ClusterBatch` stacks specs of equal structure (layer count and sampling; the
splines are padded to a common number of polynomial pieces, so control-point counts and
degrees may differ) so one compiled kernel serves them all; a
:class:`MacroCluster` is one geometry plus per-member rigid transforms (§3.1).
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import numpy as np

from ..errors import ValidationError
from ._bspline import BSpline, piecewise
from .cluster_defaults import STRUCTURE_DEFAULTS as _D


def _spline(field: str, value, dim: int | None) -> BSpline:
    if isinstance(value, Mapping):
        unknown = set(value) - {"control", "knots", "degree"}
        if unknown or "control" not in value:
            raise ValidationError(field, sorted(value), "a spline mapping has 'control' and optional 'knots', 'degree'")
        return BSpline.make(value["control"], value.get("knots"), value.get("degree"), field=field, dim=dim)
    if isinstance(value, BSpline):
        if dim is not None and value.dim != dim:
            raise ValidationError(field, value.control.shape, f"control points must have shape (n, {dim})")
        if dim is None and value.dim != 1:
            raise ValidationError(field, value.control.shape, "a 1-D spline takes (n, 1) control values")
        return value
    return BSpline.make(value, field=field, dim=dim)


def _sampling(field: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValidationError(field, value, "the sampling count must be an integer ≥ 1 (eq 3)")
    if value < 1:
        raise ValidationError(field, value, "the sampling count must be ≥ 1 (eq 3)")
    return int(value)


def default_normal(tangent: np.ndarray) -> np.ndarray:
    """A unit vector ⟂ ``tangent``: the coordinate axis least aligned with it, orthogonalised."""
    t = tangent / np.linalg.norm(tangent)
    axis = np.eye(3)[int(np.argmin(np.abs(t)))]
    r = axis - (axis @ t) * t
    return r / np.linalg.norm(r)


@dataclass(frozen=True, eq=False)
class ClusterSpec:
    """Parameters of one cluster (eqs 1–3); validated on construction (raises ``ValidationError``).

    ``trajectory``: (n, 3) control points, a :class:`BSpline`, or a mapping
    {"control", "knots", "degree"} (clamped uniform knots and degree min(3, n − 1) by
    default); ``half_axis_a``, ``half_axis_b``: 1-D control values (> 0) or a scalar, in the
    same forms; ``twist``: q control values (radians).  ``normal0`` fixes the first frame's reference direction (default: the
    coordinate axis least aligned with T'(0)); frames follow by rotation minimisation.
    """

    trajectory: object
    half_axis_a: object
    half_axis_b: object
    twist: object = 0.0
    layer_radii: Sequence[float] = _D["layer_radii"]  # defaults: .cluster_defaults, the one place they are set
    core_radius: float = _D["core_radius"]
    s_t: int = _D["s_t"]
    s_v: int = _D["s_v"]
    s_u: int = _D["s_u"]
    normal0: object = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        traj = _spline("trajectory", self.trajectory, 3)
        if traj.n_control < 2:
            raise ValidationError("trajectory", traj.control.shape, "a trajectory needs at least 2 control points")
        steps = np.linalg.norm(np.diff(traj.control, axis=0), axis=1)
        if not (steps > 0).all():
            i = int(np.flatnonzero(steps <= 0)[0])
            raise ValidationError(
                "trajectory", traj.control[i].tolist(), f"control points {i} and {i + 1} coincide (the curve would stop)"
            )
        set_(self, "trajectory", traj)
        for name in ("half_axis_a", "half_axis_b"):
            sp = _spline(name, getattr(self, name), None)
            if not (sp.control > 0).all():
                bad = float(sp.control[sp.control <= 0][0])
                raise ValidationError(name, bad, "half-axis control values must be > 0 (a radius cannot be negative)")
            set_(self, name, sp)
        set_(self, "twist", _spline("twist", self.twist, None))
        radii = np.atleast_1d(np.asarray(self.layer_radii, dtype=np.float64))
        if radii.ndim != 1 or radii.size < 1:
            raise ValidationError("layer_radii", self.layer_radii, "give at least one layer radius")
        if not np.isfinite(radii).all():
            raise ValidationError("layer_radii", radii.tolist(), "layer radii must be finite")
        if (radii <= 0).any() or (radii > 1).any():
            raise ValidationError("layer_radii", radii.tolist(), "layer radii are fractions of the ellipse, in (0, 1]")
        if (np.diff(radii) <= 0).any():
            raise ValidationError("layer_radii", radii.tolist(), "layer radii must be strictly increasing")
        set_(self, "layer_radii", radii)
        core = float(self.core_radius)
        if not np.isfinite(core) or core < 0:
            raise ValidationError("core_radius", self.core_radius, "the core radius must be finite and ≥ 0")
        if core >= radii[0]:
            raise ValidationError("core_radius", core, f"the core must lie inside the first layer (< {radii[0]})")
        set_(self, "core_radius", core)
        for name in ("s_t", "s_v", "s_u"):
            set_(self, name, _sampling(name, getattr(self, name)))
        set_(self, "normal0", self._resolve_normal0())

    def _resolve_normal0(self) -> np.ndarray:
        t0 = self.trajectory(0.0, deriv=1)[0]
        if self.normal0 is None:
            return default_normal(t0)
        n0 = np.asarray(self.normal0, dtype=np.float64)
        if n0.shape != (3,) or not np.isfinite(n0).all():
            raise ValidationError("normal0", self.normal0, "must be a finite 3-vector")
        t = t0 / np.linalg.norm(t0)
        r = n0 - (n0 @ t) * t
        if np.linalg.norm(r) < 1e-9 * max(np.linalg.norm(n0), 1e-300):
            raise ValidationError("normal0", n0.tolist(), "must not be parallel to the trajectory's start tangent")
        return r / np.linalg.norm(r)

    @property
    def n_layers(self) -> int:
        return int(self.layer_radii.size)

    def structure(self) -> tuple:
        """What must agree for specs to share a batch: (layer count, s_t, s_v, s_u)."""
        return (self.n_layers, self.s_t, self.s_v, self.s_u)

    def transformed(self, rotation, translation) -> ClusterSpec:
        """This cluster moved rigidly: x ↦ R x + d (trajectory and normal0 move; A, B, q stay)."""
        rot, d = check_rigid(rotation, translation)
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        kw["trajectory"] = self.trajectory.transformed(rot, d)
        kw["normal0"] = rot @ self.normal0
        return ClusterSpec(**kw)

    def track_bounds(self) -> np.ndarray:
        """(L·s_v + 1,) radial boundaries v of the tracks: each shell [prev, layer] cut in s_v equal steps."""
        edges = np.concatenate([[self.core_radius], self.layer_radii])
        steps = np.linspace(0.0, 1.0, self.s_v + 1)[:-1]
        inner = (edges[:-1, None] + (edges[1:] - edges[:-1])[:, None] * steps[None, :]).ravel()
        return np.concatenate([inner, edges[-1:]])


def check_rigid(rotation, translation) -> tuple[np.ndarray, np.ndarray]:
    """Validate a rotation (3, 3), orthonormal with det +1, and a translation (3,)."""
    rot = np.asarray(rotation, dtype=np.float64)
    d = np.asarray(translation, dtype=np.float64)
    if rot.shape != (3, 3) or not np.isfinite(rot).all():
        raise ValidationError("rotation", getattr(rot, "shape", rotation), "must be a finite 3×3 matrix")
    if np.abs(rot @ rot.T - np.eye(3)).max() > 1e-9 or np.linalg.det(rot) < 0:
        raise ValidationError("rotation", rot.tolist(), "must be a proper rotation (orthonormal, det +1)")
    if d.shape != (3,) or not np.isfinite(d).all():
        raise ValidationError("translation", translation, "must be a finite 3-vector")
    return rot, d


@dataclass(frozen=True, eq=False)
class ClusterBatch:
    """C clusters of equal structure (:meth:`ClusterSpec.structure`), stacked for the kernels."""

    specs: tuple[ClusterSpec, ...]

    def __post_init__(self) -> None:
        specs = tuple(self.specs)
        if not specs:
            raise ValidationError("specs", [], "a batch needs at least one cluster")
        for i, s in enumerate(specs):
            if not isinstance(s, ClusterSpec):
                raise ValidationError(f"specs[{i}]", type(s).__name__, "must be a ClusterSpec")
            if s.structure() != specs[0].structure():
                raise ValidationError(
                    f"specs[{i}]",
                    s.structure(),
                    f"structure differs from specs[0] {specs[0].structure()} (layer count, s_t, s_v, s_u must agree)",
                )
        object.__setattr__(self, "specs", specs)

    @classmethod
    def stack(cls, specs: Sequence[ClusterSpec]) -> ClusterBatch:
        """A batch of the given cluster specs, in order."""
        return cls(tuple(specs))

    def __len__(self) -> int:
        return len(self.specs)

    @property
    def n_clusters(self) -> int:
        return len(self.specs)

    def arrays(self) -> dict[str, np.ndarray]:
        """Stacked arrays for the kernels: each spline's polynomial pieces (``<spline>_breaks``,
        ``_coeffs``, ``_inv_width``, ``_spans``; see ``_bspline.piecewise``), ``normal0``,
        ``layer_radii``, ``core_radius`` and ``track_bounds``."""
        out = {}
        for name in ("trajectory", "half_axis_a", "half_axis_b", "twist"):
            need = max(getattr(s, name).knots.size - 1 for s in self.specs)
            pieces = [piecewise(getattr(s, name), max(16, 1 << (need - 1).bit_length())) for s in self.specs]
            for key in pieces[0]:
                out[f"{name}_{key}"] = np.stack([pc[key] for pc in pieces])
        out["normal0"] = np.stack([s.normal0 for s in self.specs])
        out["layer_radii"] = np.stack([s.layer_radii for s in self.specs])
        out["core_radius"] = np.array([s.core_radius for s in self.specs])
        out["track_bounds"] = np.stack([s.track_bounds() for s in self.specs])
        return out

    @property
    def n_layers(self) -> int:
        return self.specs[0].n_layers

    @property
    def sampling(self) -> tuple[int, int, int]:
        """(s_t, s_v, s_u) of eq 3, shared by the batch."""
        s = self.specs[0]
        return s.s_t, s.s_v, s.s_u


@dataclass(frozen=True, eq=False)
class MacroCluster:
    """One cluster geometry shared by M members, each placed by a rigid transform (§3.1)."""

    spec: ClusterSpec
    rotations: np.ndarray
    translations: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.spec, ClusterSpec):
            raise ValidationError("spec", type(self.spec).__name__, "must be a ClusterSpec")
        rots = np.asarray(self.rotations, dtype=np.float64)
        ds = np.asarray(self.translations, dtype=np.float64)
        if rots.ndim != 3 or ds.ndim != 2 or len(rots) != len(ds) or len(rots) < 1:
            raise ValidationError("rotations", (rots.shape, ds.shape), "need (M, 3, 3) rotations and (M, 3) translations, M ≥ 1")
        for i in range(len(rots)):
            try:
                check_rigid(rots[i], ds[i])
            except ValidationError as exc:
                raise ValidationError(f"{exc.field}s[{i}]", exc.value, exc.reason) from None
        object.__setattr__(self, "rotations", rots)
        object.__setattr__(self, "translations", ds)

    def members(self) -> list[ClusterSpec]:
        """The macro cluster's member clusters: its spec under each rigid transform (rotation, translation)."""
        return [self.spec.transformed(r, d) for r, d in zip(self.rotations, self.translations)]

    def batch(self) -> ClusterBatch:
        """The members as one :class:`ClusterBatch`."""
        return ClusterBatch.stack(self.members())
