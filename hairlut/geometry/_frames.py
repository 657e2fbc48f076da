"""JAX kernels of the swept ellipse (eqs 1–2): arc length, rotation-minimising frames, sections.

Per cluster (vmapped over a batch):

- t is the relative arc length along T (satf §3.2).  A table of the cumulative length
  S at ``n_arc + 1`` uniform spline parameters w (5-point Gauss–Legendre per interval),
  and its linear inverse at uniform t, give a first guess refined by two Newton steps
  on S(w) − tL = 0, with S(w) integrated by Gauss–Legendre from the table node.
- Frames are rotation-minimising, by the double reflection method (Wang, Jüttler, Zheng
  and Liu 2008, "Computation of rotation minimizing frames", ACM TOG 27(1)), computed on
  ``n_frames`` uniform t samples from the first reference direction ``normal0``; the frame
  at any t is one further double-reflection step from the table node below t, so it is
  continuous in t and equals the table at the nodes.  Never Frenet frames, which flip at
  inflections.
- A section at t is (origin T(t), unit tangent, reference r, binormal b = tangent × r,
  A(t), B(t), q(t), and the derivatives that ∂P/∂t needs); eq 1 puts the point (v, u)
  at T + v·(A cos(q + u)·r + B sin(q + u)·b).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ._bspline import eval_piecewise

N_ARC = 256
_GL_X, _GL_W = (np.asarray(a) for a in np.polynomial.legendre.leggauss(5))
_NEWTON_STEPS = 2


def _norm(x):
    return jnp.sqrt(jnp.sum(x * x, axis=-1))


def _clamp(x, lo, hi):
    """Clamp without zeroing the derivative at the bounds (unlike jnp.clip)."""
    return jnp.where(x < lo, lo, jnp.where(x > hi, hi, x))


def spline(tab, name: str, x, deriv=0):
    """Values (or derivatives) of spline ``name`` at x (any shape): x.shape + (d,); a tuple
    of orders gives a tuple."""
    shape = jnp.shape(x)
    out = eval_piecewise(
        jnp.reshape(x, -1), tab[f"{name}_breaks"], tab[f"{name}_coeffs"], tab[f"{name}_inv_width"], tab[f"{name}_spans"], deriv
    )
    if isinstance(deriv, int):
        return out.reshape(shape + out.shape[-1:])
    return tuple(o.reshape(shape + o.shape[-1:]) for o in out)


def _speed(tab, w):
    return _norm(spline(tab, "trajectory", w, 1))


def arc_table(tab, n_arc: int = N_ARC):
    """(n_arc + 1,) cumulative arc length at w = 0, 1/n_arc, …, 1 (uniform in w)."""
    w = jnp.linspace(0.0, 1.0, n_arc + 1)
    a, b = w[:-1], w[1:]
    half = 0.5 * (b - a)
    nodes = (0.5 * (a + b))[:, None] + half[:, None] * jnp.asarray(_GL_X)[None, :]
    seg = half * jnp.sum(jnp.asarray(_GL_W)[None, :] * _speed(tab, nodes), axis=1)
    return jnp.concatenate([jnp.zeros(1, seg.dtype), jnp.cumsum(seg)])


def inverse_arc_table(arc: np.ndarray) -> np.ndarray:
    """(C, n + 1) first guesses of w at uniform relative arc length t = j/n (NumPy, linear)."""
    n = arc.shape[1] - 1
    w = np.linspace(0.0, 1.0, n + 1)
    return np.stack([np.interp(w * row[-1], row, w) for row in arc])


def param_of(tab, t):
    """Spline parameter w for relative arc length t ∈ [0, 1] (any shape).

    A first guess from the uniform-t table ``arc_inv``, then Newton steps on
    S(w) − tL, with S(w) = arc[k] + Gauss–Legendre from the uniform-w node k below w.
    """
    arc, inv = tab["arc"], tab["arc_inv"]
    n_arc = arc.shape[0] - 1
    t = _clamp(t, 0.0, 1.0)
    f = t * n_arc
    j = jnp.clip(jnp.floor(f).astype(jnp.int32), 0, n_arc - 1)
    w = inv[j] + (f - j) * (inv[j + 1] - inv[j])
    s = t * arc[-1]
    gx, gw = jnp.asarray(_GL_X), jnp.asarray(_GL_W)
    floor = 1e-12 * arc[-1]
    for _ in range(_NEWTON_STEPS):
        k = jnp.clip(jnp.floor(w * n_arc).astype(jnp.int32), 0, n_arc - 1)
        wk = k / n_arc
        half = 0.5 * (w - wk)
        nodes = jnp.concatenate([wk[..., None] + half[..., None] * (1.0 + gx), w[..., None]], axis=-1)
        sp = _speed(tab, nodes)
        partial = arc[k] + half * jnp.sum(gw * sp[..., :5], axis=-1)
        w = _clamp(w - (partial - s) / jnp.maximum(sp[..., 5], floor), 0.0, 1.0)
    return w


def _reflect(x0, t0, r0, x1, t1, tol2):
    """One double-reflection step: reference r0 at (x0, t0) carried to (x1, t1) (Wang et al. 2008).

    A chord shorter than √tol2 has no trustworthy direction (round-off): then r0 is only
    re-orthogonalised against t1, which is the limit of the step as x1 → x0.
    """
    v1 = x1 - x0
    c1 = jnp.sum(v1 * v1, axis=-1, keepdims=True)
    far = c1 > tol2
    safe1 = jnp.where(far, c1, 1.0)
    r_l = r0 - (2.0 / safe1) * jnp.sum(v1 * r0, -1, keepdims=True) * v1
    t_l = t0 - (2.0 / safe1) * jnp.sum(v1 * t0, -1, keepdims=True) * v1
    v2 = t1 - t_l
    c2 = jnp.sum(v2 * v2, axis=-1, keepdims=True)
    safe2 = jnp.where(c2 > 0, c2, 1.0)
    r1 = jnp.where(c2 > 0, r_l - (2.0 / safe2) * jnp.sum(v2 * r_l, -1, keepdims=True) * v2, r_l)
    r1 = jnp.where(far, r1, r0)
    r1 = r1 - jnp.sum(r1 * t1, -1, keepdims=True) * t1  # remove round-off drift
    return r1 / _norm(r1)[..., None]


def _tol2(tab):
    scale = tab["arc"][-1] + jnp.max(jnp.abs(tab["frame_x"] if "frame_x" in tab else tab["trajectory_coeffs"]))
    return (1e-9 * scale) ** 2


def _curve(tab, w):
    x, d = spline(tab, "trajectory", w, (0, 1))
    return x, d / _norm(d)[..., None]


def frame_table(tab, n_frames: int):
    """Origins, tangents and references (n_frames, 3) at uniform relative arc length."""
    t = jnp.linspace(0.0, 1.0, n_frames)
    x, tan = _curve(tab, param_of(tab, t))
    n0 = tab["normal0"]
    r0 = n0 - jnp.sum(n0 * tan[0]) * tan[0]
    r0 = r0 / _norm(r0)

    tol2 = _tol2(tab)

    def step(r, inputs):
        x0, t0, x1, t1 = inputs
        r1 = _reflect(x0, t0, r, x1, t1, tol2)
        return r1, r1

    _, rs = jax.lax.scan(step, r0, (x[:-1], tan[:-1], x[1:], tan[1:]))
    return x, tan, jnp.concatenate([r0[None], rs])


def build_frames(tab, n_frames: int):
    """``frame_x``, ``frame_tangent``, ``frame_ref`` and ``min_speed`` of one cluster (needs ``arc``, ``arc_inv``)."""
    fx, ft, fr = frame_table(tab, n_frames)
    n_arc = tab["arc"].shape[0] - 1
    return {
        "frame_x": fx,
        "frame_tangent": ft,
        "frame_ref": fr,
        "min_speed": jnp.min(_speed(tab, jnp.linspace(0.0, 1.0, 4 * n_arc + 1))),
    }


def section(tab, t):
    """Everything eq 1 needs at relative arc length t (shape X), as a dict.

    ``origin``, ``tangent``, ``normal`` (the reference r), ``binormal`` (tangent × r) and
    ``kappa`` (curvature vector dT̂/ds) are (X, 3); ``a``, ``b``, ``twist`` and their
    t-derivatives ``da``, ``db``, ``dtwist`` are (X).
    """
    t = _clamp(t, 0.0, 1.0)
    w = param_of(tab, t)
    x, d1, d2 = spline(tab, "trajectory", w, (0, 1, 2))
    tan = d1 / _norm(d1)[..., None]
    n_frames = tab["frame_x"].shape[0]
    j = jnp.clip(jnp.floor(t * (n_frames - 1)).astype(jnp.int32), 0, n_frames - 2)
    r = _reflect(tab["frame_x"][j], tab["frame_tangent"][j], tab["frame_ref"][j], x, tan, _tol2(tab))
    kappa = (d2 - jnp.sum(d2 * tan, -1, keepdims=True) * tan) / jnp.sum(d1 * d1, -1, keepdims=True)
    out = {"origin": x, "tangent": tan, "normal": r, "binormal": jnp.cross(tan, r), "kappa": kappa}
    for name, key in (("half_axis_a", "a"), ("half_axis_b", "b"), ("twist", "twist")):
        val, der = spline(tab, name, t, (0, 1))
        out[key], out["d" + key] = val[..., 0], der[..., 0]
    return out
