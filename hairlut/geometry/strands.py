"""Hair strands as ragged polylines: one flat point array plus points-per-strand counts.

Strand ``i`` is ``points[offsets[i]:offsets[i + 1]]``.  Per-point attributes
(``thickness``, ``transparency``, ``color``, ``movable``) have one row per
point; ``uv`` has one row per strand.  Every attribute but ``points`` and
``counts`` is optional (``None``).  ``movable`` is the TressFX pinning flag
(the w component of a .tfx vertex; False where the vertex is pinned).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ValidationError

_TAIL = {"thickness": (), "transparency": (), "color": (3,), "movable": ()}
_PER_POINT = tuple(_TAIL)
OPTIONAL = ("thickness", "transparency", "color", "uv", "movable")


def _float_array(field: str, value, shape_tail: tuple[int, ...]) -> np.ndarray:
    """``value`` as a native float32 (if given as float32) or float64 array of shape (N, *shape_tail)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu":
        raise ValidationError(field, arr.dtype, "must hold real numbers")
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != shape_tail:
        want = "(N" + "".join(f", {n}" for n in shape_tail) + ")"
        raise ValidationError(field, arr.shape, f"shape must be {want}")
    dtype = np.float32 if arr.dtype.kind == "f" and arr.dtype.itemsize == 4 else np.float64
    return np.ascontiguousarray(arr, dtype=dtype)


def _first_bad(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask.reshape(len(mask), -1).any(axis=1))[0])


@dataclass(frozen=True, eq=False, repr=False)
class Strands:
    """A set of hair strands; validated on construction (raises ``ValidationError``)."""

    points: np.ndarray
    counts: np.ndarray
    thickness: np.ndarray | None = None
    transparency: np.ndarray | None = None
    color: np.ndarray | None = None
    uv: np.ndarray | None = None
    movable: np.ndarray | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        points = _float_array("points", self.points, (3,))
        set_(self, "points", points)
        counts = np.asarray(self.counts)
        if counts.ndim != 1 or (counts.size and counts.dtype.kind not in "iu"):
            raise ValidationError(
                "counts", counts.dtype if counts.ndim == 1 else counts.shape, "must be a 1-D integer array (points per strand)"
            )
        counts = counts.astype(np.int64)
        set_(self, "counts", counts)
        if counts.size and counts.min() < 2:
            i = int(np.argmin(counts))
            raise ValidationError("counts", int(counts[i]), f"strand {i} has fewer than 2 points")
        total = int(counts.sum())
        if total != len(points):
            raise ValidationError("counts", f"sum {total}", f"counts must add up to the {len(points)} points")
        bad = ~np.isfinite(points)
        if bad.any():
            self._raise_at("points", _first_bad(bad), "non-finite coordinate")
        for name, tail in (("thickness", ()), ("transparency", ()), ("color", (3,)), ("uv", (2,))):
            value = getattr(self, name)
            if value is None:
                continue
            arr = _float_array(name, value, tail)
            rows = len(counts) if name == "uv" else len(points)
            if len(arr) != rows:
                per = "strand" if name == "uv" else "point"
                raise ValidationError(name, arr.shape, f"needs one row per {per} ({rows})")
            if not np.isfinite(arr).all():
                self._raise_at(name, _first_bad(~np.isfinite(arr)), "non-finite value", per_strand=name == "uv")
            if name == "thickness" and (arr < 0).any():
                self._raise_at(name, _first_bad(arr < 0), "negative thickness")
            if name == "transparency" and ((arr < 0) | (arr > 1)).any():
                self._raise_at(name, _first_bad((arr < 0) | (arr > 1)), "transparency outside [0, 1]")
            set_(self, name, arr)
        if self.movable is not None:
            mov = np.asarray(self.movable)
            if mov.shape != (len(points),) or mov.dtype.kind not in "biu":
                raise ValidationError("movable", (mov.shape, str(mov.dtype)), f"must be ({len(points)},) booleans")
            set_(self, "movable", mov.astype(bool))

    def _raise_at(self, field: str, row: int, what: str, per_strand: bool = False) -> None:
        value = np.asarray(getattr(self, field))[row]
        if per_strand:
            raise ValidationError(field, value, f"{what} at strand {row}")
        strand = int(np.searchsorted(self.offsets, row, side="right") - 1)
        vertex = row - int(self.offsets[strand])
        raise ValidationError(field, value, f"{what} at point {row} (strand {strand}, vertex {vertex})")

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def from_list(cls, polylines: Sequence[np.ndarray], *, uv=None, **per_point: Sequence[np.ndarray] | None) -> Strands:
        """Strands from a list of (n_i, 3) arrays; per-point keywords are lists of per-strand arrays too."""
        unknown = set(per_point) - set(_PER_POINT)
        if unknown:
            raise ValidationError("from_list", sorted(unknown), f"unknown attributes; known: {', '.join(OPTIONAL)}")
        arrays = [np.asarray(p) for p in polylines]
        for i, p in enumerate(arrays):
            if p.ndim != 2 or p.shape[1:] != (3,):
                raise ValidationError(f"polylines[{i}]", p.shape, "each polyline must be (n, 3)")
        points = np.concatenate(arrays) if arrays else np.zeros((0, 3))
        counts = np.array([len(p) for p in arrays], dtype=np.int64)
        extra = {
            k: np.concatenate([np.asarray(a) for a in v]) if len(v) else np.zeros((0,) + _TAIL[k])
            for k, v in per_point.items()
            if v is not None
        }
        return cls(points, counts, uv=uv, **extra)

    @classmethod
    def from_padded(cls, array: np.ndarray, **attributes) -> Strands:
        """Strands from an (S, V, 3) array of S strands with V points each; attributes are flat."""
        arr = np.asarray(array)
        if arr.ndim != 3 or arr.shape[2] != 3:
            raise ValidationError("array", arr.shape, "must be (strands, points per strand, 3)")
        counts = np.full(arr.shape[0], arr.shape[1], dtype=np.int64)
        return cls(arr.reshape(-1, 3), counts, **attributes)

    # -- sizes and indexing ---------------------------------------------------------------------
    @property
    def n_strands(self) -> int:
        return len(self.counts)

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def offsets(self) -> np.ndarray:
        """(S + 1,) start index of each strand in ``points``, then ``n_points``."""
        out = np.zeros(len(self.counts) + 1, dtype=np.int64)
        np.cumsum(self.counts, out=out[1:])
        return out

    @property
    def segments(self) -> np.ndarray:
        """(E, 2) indices into ``points`` of every line segment; E = n_points - n_strands."""
        keep = np.ones(self.n_points, dtype=bool)
        keep[self.offsets[1:] - 1] = False
        start = np.flatnonzero(keep)
        return np.stack([start, start + 1], axis=1)

    def strand(self, i: int) -> np.ndarray:
        """The (n_i, 3) points of strand ``i`` (a view; negative ``i`` counts from the end)."""
        n = self.n_strands
        if not -n <= i < n:
            raise ValidationError("i", i, f"strand index out of range for {n} strands")
        i %= n
        start, stop = self.offsets[i], self.offsets[i + 1]
        return self.points[start:stop]

    def as_padded(self) -> np.ndarray:
        """(S, V, 3) view of the points when every strand has the same number V of points."""
        if self.n_strands and (self.counts != self.counts[0]).any():
            raise ValidationError(
                "counts", f"{self.counts.min()}..{self.counts.max()}", "as_padded needs the same number of points in every strand"
            )
        per = int(self.counts[0]) if self.n_strands else 0
        return self.points.reshape(self.n_strands, per, 3)

    # -- measures ----------------------------------------------------------------------------------
    def bbox(self) -> np.ndarray:
        """(2, 3) float64: the lowest and the highest x, y, z over all points."""
        if not self.n_points:
            raise ValidationError("points", "(0, 3)", "an empty set of strands has no bounding box")
        return np.stack([self.points.min(axis=0), self.points.max(axis=0)]).astype(np.float64)

    def lengths(self) -> np.ndarray:
        """(S,) float64 polyline length of each strand."""
        if not self.n_strands:
            return np.zeros(0)
        pts = self.points.astype(np.float64, copy=False)
        # consecutive points' distances, less those from a strand's last point to the next strand's first: the
        # segments' lengths in ``segments`` order, without gathering both ends of every segment
        seg_len = np.delete(np.linalg.norm(np.diff(pts, axis=0), axis=1), self.offsets[1:-1] - 1)
        first_segment = self.offsets[:-1] - np.arange(self.n_strands)
        return np.add.reduceat(seg_len, first_segment)

    def present(self) -> list[str]:
        """Names of the optional attributes this set carries."""
        return [name for name in OPTIONAL if getattr(self, name) is not None]

    def summary(self) -> dict:
        """JSON-ready counts, bounding box, length statistics and the optional attributes present."""
        out: dict = {"strands": self.n_strands, "points": self.n_points}
        if self.n_strands:
            lengths = self.lengths()
            lo, hi = self.bbox()
            out["points_per_strand"] = {
                "min": int(self.counts.min()),
                "mean": float(self.counts.mean()),
                "max": int(self.counts.max()),
            }
            out["bbox"] = {"min": lo.tolist(), "max": hi.tolist()}
            out["length"] = {"min": float(lengths.min()), "mean": float(lengths.mean()), "max": float(lengths.max())}
        out["arrays"] = {name: getattr(self, name) is not None for name in OPTIONAL}
        return out

    def __repr__(self) -> str:
        extra = "".join(f", {name}" for name in self.present())
        return f"Strands({self.n_strands} strands, {self.n_points} points, {self.points.dtype}{extra})"
