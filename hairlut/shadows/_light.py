"""Directions and light frames shared by the light-space shadow methods (bertails §2.1, kim ch. 6)."""

from __future__ import annotations

import numpy as np

from .. import errors


def direction(field: str, value) -> np.ndarray:
    """A finite, non-zero 3-vector, normalised (ValidationError naming ``field`` otherwise)."""
    d = np.asarray(value, np.float64) if np.asarray(value).dtype.kind in "fiu" else None
    if d is None or d.shape != (3,):
        raise errors.ValidationError(field, value, "need a direction of 3 real numbers")
    n = float(np.linalg.norm(d))
    if not np.isfinite(n) or n == 0:
        raise errors.ValidationError(field, value, "the direction must be finite and non-zero")
    return d / n


def light_frame(light, up=None) -> np.ndarray:
    """(3, 3) rows x, y, depth: depth = −light; y = ``up`` made orthogonal to it (default: the world axis
    +y, or +z / +x when the light is nearly vertical); x = y × depth.  Rotating light and up rotates the frame."""
    w = -direction("light", light)
    if up is None:
        candidates = (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
        up_d = next(c for c in candidates if abs(c @ w) < 0.9)
    else:
        up_d = direction("up", up)
    v = up_d - (up_d @ w) * w
    if np.linalg.norm(v) < 1e-6:
        raise errors.ValidationError("up", up, "must not be parallel to the light direction")
    v /= np.linalg.norm(v)
    return np.stack([np.cross(v, w), v, w])


def check_kappa(kappa) -> float:
    """The extinction scale κ: a finite real ≥ 0."""
    if isinstance(kappa, bool) or not isinstance(kappa, (int, float, np.number)) or not (np.isfinite(kappa) and kappa >= 0):
        raise errors.ValidationError("kappa", kappa, "the extinction scale κ must be a finite real ≥ 0")
    return float(kappa)


def check_points(points) -> np.ndarray:
    """Query points: a finite (n, 3) float64 array."""
    pts = np.asarray(points, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise errors.ValidationError("points", pts.shape, "need an (n, 3) array")
    if not np.isfinite(pts).all():
        raise errors.ValidationError("points", "non-finite", "points must be finite")
    return pts
