"""The paper's planar ray tracing as a straightforward float64 NumPy loop over rays (satf §5.1, eq 5).

The baseline and reference for :func:`hairlut.hrir._tracer.trace_kernel`: the same
discretisation (frame, pixels, midpoint steps, bilinear density, chain-rule gradient,
Phong), but each ray of each (view, light) is traced on its own (its K samples in
NumPy) and accumulated literally by eq 5, sample after sample, stopping when
α_acc > 1 − eps.  Self-shadowing, when asked, marches from each sample toward the
light (steps of Δs) instead of using the tracer's resampled grid, so the two agree
only to discretisation error there.
"""

from __future__ import annotations

import numpy as np

from ..march import GEOM

_G = {k: i for i, k in enumerate(GEOM)}


def _bilerp(grid, fi, fj):
    n, m = grid.shape[:2]
    fi = np.clip(fi, 0.0, n - 1.0)
    fj = np.clip(fj, 0.0, m - 1.0)
    i0 = np.clip(np.floor(fi).astype(int), 0, max(n - 2, 0))
    j0 = np.clip(np.floor(fj).astype(int), 0, max(m - 2, 0))
    i1, j1 = np.minimum(i0 + 1, n - 1), np.minimum(j0 + 1, m - 1)
    a, b = (fi - i0)[..., None], (fj - j0)[..., None]
    return (1 - a) * (1 - b) * grid[i0, j0] + a * (1 - b) * grid[i1, j0] + (1 - a) * b * grid[i0, j1] + a * b * grid[i1, j1]


class _Sector:
    """One sector's density and geometry, sampled at local points."""

    def __init__(self, rho, g):
        rho = np.asarray(rho, np.float64)
        self.g = {k: float(g[i]) for k, i in _G.items()}
        n_s, n_r = rho.shape
        rs = np.gradient(rho, axis=0) * n_s if n_s > 1 else np.zeros_like(rho)
        rr = np.gradient(rho, axis=1) * n_r if n_r > 1 else np.zeros_like(rho)
        self.fields = np.stack([rho, rs, rr], axis=-1)
        self.scale = np.abs(rho).max()

    def sample(self, q):
        """Density (K,), inside (K,), ∇ρ direction in the local frame (K, 2) and ok-mask at points q (K, 2)."""
        g = self.g
        cb, sb = np.cos(g["beta"]), np.sin(g["beta"])
        e = np.array([g["cx"], g["cy"]]) + q @ np.array([[cb, sb], [-sb, cb]])
        u = e / np.array([1.0, g["aspect"]])
        v = np.hypot(u[:, 0], u[:, 1])
        phi = np.arctan2(u[:, 1], u[:, 0])
        s = np.mod(phi - g["phase"], 2 * np.pi) / g["du"]
        r = (v - g["v0"]) / (g["v1"] - g["v0"])
        inside = (s < 1) & (r >= 0) & (r <= 1)
        n_s, n_r = self.fields.shape[:2]
        f = _bilerp(self.fields, s * n_s - 0.5, r * n_r - 0.5)
        grad = np.zeros((len(q), 2))
        ok = inside & (f[:, 1] ** 2 + f[:, 2] ** 2 > (1e-5 * self.scale) ** 2) & (v > 0)
        for k in np.flatnonzero(ok):
            cp, sp = np.cos(phi[k]), np.sin(phi[k])
            jac = np.array(
                [
                    [-g["du"] * v[k] * sp, (g["v1"] - g["v0"]) * cp],
                    [g["du"] * v[k] * g["aspect"] * cp, (g["v1"] - g["v0"]) * g["aspect"] * sp],
                ]
            )
            ge = np.linalg.solve(jac.T, f[k, 1:])  # ∇ρ in ellipse coordinates
            grad[k] = [cb * ge[0] + sb * ge[1], -sb * ge[0] + cb * ge[1]]
        ok &= np.hypot(grad[:, 0], grad[:, 1]) > 0
        return np.where(inside, f[:, 0], 0.0), inside, grad, ok


def _depth_to_light(sec: _Sector, point, l, ds, reach):
    """Optical depth from ``point`` to the light along +l (midpoint steps of ``ds``)."""
    n = int(np.ceil(reach / ds))
    pts = point[None, :] + ((np.arange(n) + 0.5) * ds)[:, None] * l[None, :]
    rho, *_ = sec.sample(pts)
    return sec.g["sigma_t"] * rho.sum() * ds


def _ray(sec: _Sector, pts, d, L, phong, ds, eps, shadow):
    """One ray through ``pts`` (front to back) under the lights ``L`` (n, 2): eq 5 with early stop."""
    g = sec.g
    ka, kd, ks, p = phong
    dens, inside, grad, ok = sec.sample(pts)
    a_acc, re_acc = 0.0, np.zeros(len(L))
    for k in range(len(pts)):
        if a_acc > 1 - eps:
            break  # α_acc ≈ 1: nothing behind is visible
        if not inside[k] or dens[k] == 0:
            continue
        a = 1 - np.exp(-g["sigma_t"] * dens[k] * ds)
        n = -grad[k] / np.hypot(*grad[k]) if ok[k] else d
        nl = L @ n
        r = 2 * nl[:, None] * n[None, :] - L
        rv = r @ d
        spec = np.where((nl > 0) & (rv > 0), np.abs(rv) ** p, 0.0)
        direct = kd * np.maximum(nl, 0) + ks * spec
        if shadow:
            direct = direct * np.exp(-np.array([_depth_to_light(sec, pts[k], L[i], ds, 2 * g["extent"]) for i in range(len(L))]))
        re = ka + direct
        re_acc = re_acc + a * re * (1 - a_acc)  # eq 5
        a_acc = a_acc + a * (1 - a_acc)
    return a_acc, re_acc


def reference_hrir(
    rho,
    geom,
    views,
    lights,
    phong,
    *,
    n_pix: int,
    n_steps: int,
    rays: int = 1,
    shadow: bool = False,
    smooth: bool = True,
    eps: float = 1e-4,
    share_lights: bool = False,
):
    """alpha (V, P) and reflectance (V, L, P) of one sector by a per-ray NumPy loop (float64).

    By default every (view, light, ray) is traced on its own, as in the paper; with
    ``share_lights`` one march per (view, ray) serves all lights (NumPy over the lights).
    """
    sec = _Sector(rho, geom)
    R = sec.g["extent"]
    lanes = n_pix * rays
    ds = 2 * R / n_steps
    phong = tuple(float(x) for x in phong)
    views, lights = np.asarray(views, np.float64), np.asarray(lights, np.float64)
    L = np.stack([np.cos(lights), np.sin(lights)], -1)
    alpha = np.zeros((len(views), lanes))
    refl = np.zeros((len(views), len(lights), lanes))
    z = R - (np.arange(n_steps) + 0.5) * ds
    for iv, th in enumerate(views):
        d = np.array([np.cos(th), np.sin(th)])
        e = np.array([-d[1], d[0]])
        for j in range(lanes):
            t = -R + (j + 0.5) * 2 * R / lanes
            pts = t * e[None, :] + z[:, None] * d[None, :]
            if share_lights:
                alpha[iv, j], refl[iv, :, j] = _ray(sec, pts, d, L, phong, ds, eps, shadow)
                continue
            for il in range(len(L)):
                alpha[iv, j], re = _ray(sec, pts, d, L[il : il + 1], phong, ds, eps, shadow)
                refl[iv, il, j] = re[0]
    alpha = alpha.reshape(len(views), n_pix, rays).mean(-1)
    refl = refl.reshape(len(views), len(lights), n_pix, rays).mean(-1)
    if smooth:
        alpha, refl = gaussian_smooth(alpha, sec.g["sigma_px"]), gaussian_smooth(refl, sec.g["sigma_px"])
    return alpha, refl


def gaussian_smooth(x, sigma_px: float):
    """Convolve the last axis with a sampled Gaussian of σ = ``sigma_px`` pixels (zero padding)."""
    x = np.asarray(x, np.float64)
    n = x.shape[-1]
    s = max(float(sigma_px), 1e-6)
    m = np.arange(-n, n + 1)
    k = np.exp(-0.5 * (m / s) ** 2)
    big = np.arange(-int(np.ceil(40 * s)), int(np.ceil(40 * s)) + 1)
    k /= np.exp(-0.5 * (big / s) ** 2).sum()  # normalised on the infinite line: zero beyond the image
    out = np.zeros_like(x)
    for j in range(n):
        for i in range(n):
            out[..., i] += x[..., j] * k[i - j + n]
    return out
