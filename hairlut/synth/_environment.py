"""Environment light on the layer texels: xing eq 2 through the contracted tables (eqs 4–5).

Per texel with tangent t, view angle θ′ = ∠(t, v) and transmittance coefficients b_j:

    E = Σ_j b_j (kd · f_dif ⊙ Cd_j(t) + ks · Cs_j(t, θ′)),   ks = ks_I + ks_II (switched terms only),

one specular lobe of exponent p_I (the SH tables' p) for both highlights, unshifted.
Without self-shadowing the environment is unoccluded: b = (√4π, 0, …).  With it, b is
the strands' voxel SH transmittance (xing §5, ``hairlut.shadows``) at the texel's
position.  9 coefficients cannot hold a sharp occlusion, so E can ring below 0; it is
clamped at 0 and the clamped fraction is reported.  ``environment.window`` (hanning or lanczos)
scales b's band l by σ_l (``hairlut.planner.window_factors``), as the planner does the light's.  E is added to each layer's shaded
colour before blending (eq 13 + E, then eq 14).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import errors

#: Sample every non-empty voxel (stride 1) for eq 7.  On the sky demo's thin clusters, stride 2's
#: first-order extrapolation b(y) + (x − y)·∇b(y) over up to two voxels drove b₀ (√4π × the mean
#: visibility) below 0 at 14 % of texels, the whole of its 9.8 % clamped share, and was 67 % rel-L2
#: from b ray-cast at the texels themselves; stride 1: b₀ ≥ 0.43, 14 %, nothing clamped.
STRIDE = 1


def self_transmittance(strands: list, points: np.ndarray, env: dict, n_trans: int) -> np.ndarray:
    """b (..., n_trans) at ``points`` (..., 3) from the voxelised strands of every cluster (xing §5)."""
    from ..geometry import Strands
    from ..shadows import transmittance, voxelize

    merged = Strands(
        np.concatenate([s.points for s in strands]),
        np.concatenate([s.counts for s in strands]),
        thickness=None if any(s.thickness is None for s in strands) else np.concatenate([s.thickness for s in strands]),
    )
    lmax = int(round(np.sqrt(n_trans))) - 1
    tr = transmittance(voxelize(merged, env["voxels"]), kappa=env["kappa"], lmax=lmax, stride=STRIDE)
    return tr.at(points.reshape(-1, 3)).reshape(points.shape[:-1] + (n_trans,))


@dataclass(frozen=True, eq=False)
class Environment:
    """The environment term of a prepared scene: the contracted tables, the texels' unit
    ``tangent`` (..., 3) and transmittance ``b`` (..., n_trans, before the window), the window's
    factors ``sigma`` (n_trans,), the view-independent diffuse part (..., 3), the specular weight
    ``ks``, the material's ``kd_rgb`` (kd · hair colour, 0 without Rd) and exponent ``p``, and the
    light bands Rd reads, ``light_diffuse`` (module docstring)."""

    contracted: object
    tangent: np.ndarray
    b: np.ndarray
    diffuse: np.ndarray
    ks: float
    self_shadow: bool
    sigma: np.ndarray
    kd_rgb: np.ndarray
    p: float
    light_diffuse: int

    def rgb(self, view) -> tuple[np.ndarray, float]:
        """E (..., 3) for a view direction (toward the viewer), clamped at 0, and the clamped fraction."""
        out = self.diffuse
        if self.ks > 0:
            out = out + self.ks * np.einsum("...j,...jc->...c", self.b * self.sigma, self._cs(view))
        clamped = float(np.mean(np.any(out < 0, axis=-1))) if out.size else 0.0
        return np.maximum(out, 0.0), clamped

    def _theta(self, view) -> np.ndarray:
        return np.arccos(np.clip(self.tangent @ np.asarray(view, np.float64), -1.0, 1.0))

    def _cs(self, view) -> np.ndarray:
        return np.asarray(self.contracted.cs(self.tangent, self._theta(view)))  # (..., n_trans, C)

    def reference(self, coeffs, view, height: int = 96) -> np.ndarray:
        """E (..., 3) unclamped for the light ``coeffs`` ((B², 3), e.g. 30 bands unwindowed) and the
        unwindowed transmittance, by :func:`hairlut.envlight.hair_radiance`'s quadrature."""
        from ..envlight import hair_radiance

        shape = self.tangent.shape[:-1]
        e = hair_radiance(
            coeffs,
            self.b.reshape(-1, self.b.shape[-1]),
            self.tangent.reshape(-1, 3),
            self._theta(view).reshape(-1),
            self.kd_rgb,
            self.ks,
            self.p,
            height=height,
        )
        return e.reshape(shape + (e.shape[-1],))


def prepare_environment(scene, sh, strands: list, tangent: np.ndarray, position: np.ndarray) -> Environment | None:
    """The :class:`Environment` of a scene with an environment light (None without one).

    ``sh``: an ``sh_tables`` path holding the scene's light (``hairlut bake --scene``)."""
    from ..shtables import SHTables

    env = scene.environment
    if env is None:
        return None
    if sh is None:
        raise errors.ValidationError(
            "sh", None, "the scene has an environment light: give its sh_tables (hairlut bake --scene SCENE bakes them)"
        )
    tables = SHTables.load(sh)
    if "light/a" not in tables.source.variables:
        raise errors.MissingDatasetError(sh, "these SH tables hold no light; bake them with the scene's light")
    fx, m = scene.effects, scene.material
    con = tables.contract(np.asarray(tables.source["light/a"], np.float64))
    t = np.asarray(tangent, np.float64)
    n = tables.bands.n_trans
    bands = int(round(np.sqrt(n)))
    sigma = np.ones(n)
    if env["self_shadow"]:
        b = self_transmittance(strands, np.asarray(position, np.float64), env, n)
        if env["window"] != "none":  # σ-factors against the 3-band transmittance's ringing
            from ..planner import window_factors

            sigma = np.repeat(window_factors(bands, env["window"]), 2 * np.arange(bands) + 1)
    else:
        b = np.zeros(t.shape[:-1] + (n,))
        b[..., 0] = np.sqrt(4 * np.pi)
    diffuse = np.zeros(t.shape[:-1] + (3,))
    kd_rgb = np.zeros(3)
    if fx["diffuse"] and tables.has_diffuse:
        kd_rgb = m["kd"] * np.asarray(m["hair_color"], np.float64)
        diffuse = kd_rgb * np.einsum("...j,...jc->...c", b * sigma, np.asarray(con.cd(t)))
    ks = (m["ks_I"] * fx["primary"] + m["ks_II"] * fx["secondary"]) if tables.has_specular else 0.0
    return Environment(
        con, t, b, diffuse, float(ks), env["self_shadow"], sigma, kd_rgb, float(m["p_I"]), tables.bands.light_diffuse
    )
