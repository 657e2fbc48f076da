"""Per-layer meshes of the cluster shells for the online module (satf §6.1).

Layer k's mesh tessellates the shell surface v = ``layer_radii[k]`` on the (t, u) grid
of eq 3, refined by ``t_subdiv`` and ``u_subdiv``: rows t_i = i/(s_t·t_subdiv),
columns u_j = 2πj/(s_u·u_subdiv) for j = 0 … s_u·u_subdiv (the seam column is
repeated so the texture coordinates stay continuous).  P(u,v),k and P(u,v),k+1 share
texture coordinates (§6.1): uv = (u/2π, t) on every layer.

- ``normals``: unit ∂P/∂u × ∂P/∂t, which points out of the cluster;
- ``tangents``: unit ∂P/∂t, the hair direction along the cluster (what Kajiya–Kay
  shading needs);
- ``triangles``: counter-clockwise seen from outside, shared by every cluster and layer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ValidationError
from .sweep import ClusterGeometry


@dataclass(frozen=True, eq=False)
class LayerMeshes:
    """Meshes of every layer of every cluster: per-vertex arrays (C, L, V, ·), V = rows × cols."""

    vertices: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    uv: np.ndarray
    triangles: np.ndarray
    rows: int
    cols: int

    @property
    def n_vertices(self) -> int:
        return self.rows * self.cols

    def mesh(self, cluster: int, layer: int) -> dict[str, np.ndarray]:
        """One layer's mesh as plain arrays (vertices, normals, tangents, uv, triangles)."""
        return {
            "vertices": self.vertices[cluster, layer],
            "normals": self.normals[cluster, layer],
            "tangents": self.tangents[cluster, layer],
            "uv": self.uv,
            "triangles": self.triangles,
        }


def grid_triangles(n_rows: int, n_cols: int) -> np.ndarray:
    """(2(n_rows−1)(n_cols−1), 3) int32 triangles of a row-major vertex grid, CCW for P_u × P_t outward."""
    i, j = np.meshgrid(np.arange(n_rows - 1), np.arange(n_cols - 1), indexing="ij")
    p0 = (i * n_cols + j).ravel()
    p1, p2, p3 = p0 + 1, p0 + n_cols + 1, p0 + n_cols
    tri = np.stack([np.stack([p0, p1, p2], 1), np.stack([p0, p2, p3], 1)], axis=1).reshape(-1, 3)
    return tri.astype(np.int32)


def _unit(x: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(x, axis=-1, keepdims=True)
    return x / np.where(n > 0, n, 1.0)


def layer_meshes(geometry: ClusterGeometry, *, t_subdiv: int = 1, u_subdiv: int = 1) -> LayerMeshes:
    """Tessellate every layer surface of every cluster (see the module docstring)."""
    for name, value in (("t_subdiv", t_subdiv), ("u_subdiv", u_subdiv)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValidationError(name, value, "need an integer ≥ 1")
    s_t, _, s_u = geometry.sampling
    rows, cols = s_t * t_subdiv + 1, s_u * u_subdiv + 1
    t = np.linspace(0.0, 1.0, rows)
    u = np.linspace(0.0, 2.0 * np.pi, cols)
    radii = np.stack([s.layer_radii for s in geometry.batch.specs])  # (C, L)
    n_c, n_l = radii.shape
    tt, uu = np.meshgrid(t, u, indexing="ij")
    shape = (n_c, n_l, rows, cols)
    cl = np.broadcast_to(np.arange(n_c)[:, None, None, None], shape)
    vv = np.broadcast_to(radii[:, :, None, None], shape)
    p, pt, pu = geometry.derivatives_of(cl, np.broadcast_to(tt, shape), vv, np.broadcast_to(uu, shape))
    flat = (n_c, n_l, rows * cols, 3)
    uv = np.stack([uu.ravel() / (2.0 * np.pi), tt.ravel()], axis=1)
    return LayerMeshes(
        p.reshape(flat),
        _unit(np.cross(pu, pt)).reshape(flat),
        _unit(pt).reshape(flat),
        uv,
        grid_triangles(rows, cols),
        rows,
        cols,
    )
