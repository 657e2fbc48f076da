"""Light frames and κ shared by the light-space shadow methods (bertails §2.1, kim ch. 6); directions and
points are checked by :mod:`hairlut.validate`."""

from __future__ import annotations

import numpy as np

from .. import errors
from ..validate import check_real, direction


def light_frame(light, up=None) -> np.ndarray:
    """(3, 3) rows x, y, depth: depth = −light; y = ``up`` made orthogonal to it (default: the world axis
    +y, or +z / +x when the light is nearly vertical); x = y × depth.  Rotating light and up rotates the frame."""
    w = -direction(light, "light")
    if up is None:
        candidates = (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
        up_d = next(c for c in candidates if abs(c @ w) < 0.9)
    else:
        up_d = direction(up, "up")
    v = up_d - (up_d @ w) * w
    if np.linalg.norm(v) < 1e-6:
        raise errors.ValidationError("up", up, "must not be parallel to the light direction")
    v /= np.linalg.norm(v)
    return np.stack([np.cross(v, w), v, w])


def check_kappa(kappa) -> float:
    """The extinction scale κ: a finite real ≥ 0."""
    return check_real(kappa, "kappa", 0)
