"""B-splines for the cluster model (satf §3.2: T(t), A(t), B(t), q(t) are B-splines, eqs 1–2).

A :class:`BSpline` holds control points (n, d), a knot vector (n + p + 1) and the
degree p.  Knots are validated (finite, non-decreasing, interior multiplicity ≤ p so
the curve is continuous, non-empty domain) and the domain [knots[p], knots[n]] is
rescaled to [0, 1].  The default knot vector is clamped and uniform, so the curve
starts at the first control point and ends at the last; :func:`uniform_knots` gives the
unclamped uniform vector.

Evaluation is Cox–de Boor, written once for NumPy and JAX: :func:`basis` gives the
(M, n) matrix of basis functions (or of their ``deriv``-th derivatives) at M
parameters, so values are ``basis(x) @ control``; under JAX it traces with the knots
as data.  The cluster kernels use the cheaper polynomial-piece form
(:func:`piecewise`, evaluated by :func:`eval_piecewise` in JAX with Horner's rule):
one compiled kernel serves every cluster of a batch, whose pieces are stacked.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ValidationError

MAX_DEGREE = 3


def clamped_uniform_knots(n: int, degree: int) -> np.ndarray:
    """Clamped uniform knots on [0, 1] for ``n`` control points: p+1 zeros, uniform interior, p+1 ones."""
    interior = np.linspace(0.0, 1.0, n - degree + 1)[1:-1]
    return np.concatenate([np.zeros(degree + 1), interior, np.ones(degree + 1)])


def uniform_knots(n: int, degree: int) -> np.ndarray:
    """Unclamped uniform knots for ``n`` control points, rescaled so the domain is [0, 1]."""
    k = np.arange(n + degree + 1, dtype=np.float64)
    return (k - degree) / (n - degree)


def _finite_array(field: str, value, dim: int | None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError(field, value, "must hold real numbers") from None
    if dim is None:
        if arr.ndim == 0:
            arr = arr.reshape(1)
        if arr.ndim != 1:
            raise ValidationError(field, arr.shape, "a 1-D spline takes a 1-D array of control values")
        arr = arr[:, None]
    elif arr.ndim != 2 or arr.shape[1] != dim:
        raise ValidationError(field, arr.shape, f"control points must have shape (n, {dim})")
    if arr.shape[0] < 1:
        raise ValidationError(field, arr.shape, "needs at least one control point")
    bad = ~np.isfinite(arr)
    if bad.any():
        row = int(np.flatnonzero(bad.any(axis=1))[0])
        raise ValidationError(field, arr[row].tolist(), f"non-finite (NaN or inf) coordinate at control point {row}")
    return arr


@dataclass(frozen=True, eq=False)
class BSpline:
    """A validated B-spline; ``control`` is (n, d) float64, ``knots`` (n + degree + 1) on domain [0, 1].

    ``BSpline.make`` is the checked constructor: 1-D control values (``dim=None``) are
    stored as (n, 1); ``degree`` defaults to min(3, n - 1); ``field`` names the
    parameter in a :class:`ValidationError`.
    """

    control: np.ndarray
    knots: np.ndarray
    degree: int

    @classmethod
    def make(cls, control, knots=None, degree: int | None = None, *, field: str = "spline", dim: int | None = None) -> BSpline:
        """The checked constructor (see the class docstring): finite control points, a clamped uniform knot vector
        on [0, 1] when ``knots`` is None."""
        ctrl = _finite_array(field, control, dim)
        n = ctrl.shape[0]
        if degree is None:
            degree = min(MAX_DEGREE, n - 1)
        if not isinstance(degree, (int, np.integer)) or isinstance(degree, bool) or not 0 <= degree <= MAX_DEGREE:
            raise ValidationError(f"{field}.degree", degree, f"the degree must be an integer in 0..{MAX_DEGREE}")
        degree = int(degree)
        if n < degree + 1:
            raise ValidationError(field, ctrl.shape, f"a degree-{degree} spline needs at least {degree + 1} control points")
        if knots is None:
            kv = clamped_uniform_knots(n, degree)
        else:
            kv = _check_knots(f"{field}.knots", knots, n, degree)
        return cls(ctrl, kv, degree)

    @property
    def n_control(self) -> int:
        return self.control.shape[0]

    @property
    def dim(self) -> int:
        return self.control.shape[1]

    def transformed(self, rotation: np.ndarray, translation: np.ndarray) -> BSpline:
        """The spline under x ↦ R x + d (exact: B-splines are affine-invariant)."""
        return BSpline(self.control @ np.asarray(rotation).T + np.asarray(translation), self.knots, self.degree)

    def __call__(self, x, deriv: int = 0) -> np.ndarray:
        """(M, d) values (or derivatives) at parameters ``x`` in [0, 1], float64."""
        xs = np.atleast_1d(np.asarray(x, dtype=np.float64))
        return evaluate(xs, self.knots, self.control, self.degree, int(deriv), xp=np)


def _check_knots(field: str, knots, n: int, degree: int) -> np.ndarray:
    kv = np.asarray(knots, dtype=np.float64)
    if kv.ndim != 1 or kv.size != n + degree + 1:
        raise ValidationError(field, kv.shape, f"need n + degree + 1 = {n + degree + 1} knots for {n} control points")
    if not np.isfinite(kv).all():
        raise ValidationError(field, kv.tolist(), "knots must be finite")
    step = np.diff(kv)
    if (step < 0).any():
        i = int(np.flatnonzero(step < 0)[0])
        raise ValidationError(field, kv.tolist(), f"knots must be non-decreasing (knot {i + 1} < knot {i})")
    lo, hi = kv[degree], kv[n]
    if not hi > lo:
        raise ValidationError(field, kv.tolist(), f"empty domain: knot[{degree}] must be < knot[{n}]")
    inner = kv[degree + 1 : n]
    if inner.size:
        _, mult = np.unique(inner, return_counts=True)
        if degree > 0 and mult.max() > degree:
            raise ValidationError(
                field, kv.tolist(), f"an interior knot repeats more than degree = {degree} times (the curve would break)"
            )
    return (kv - lo) / (hi - lo)


def _safe_div(num, den, xp):
    ok = den > 0
    return xp.where(ok, num / xp.where(ok, den, 1.0), 0.0)


def basis(x, knots, degree: int, n: int, deriv: int = 0, xp=jnp):
    """(M, n) B-spline basis functions (or their ``deriv``-th derivatives) at ``x`` ∈ [0, 1].

    Cox–de Boor with half-open spans, except that x = 1 falls in the last non-empty
    span; 0/0 terms are 0.  ``xp`` is ``jax.numpy`` (traceable; ``degree``, ``n`` and
    ``deriv`` static) or ``numpy``.
    """
    x = xp.clip(xp.asarray(x), 0.0, 1.0)
    k = knots.shape[0]
    kw = {"method": "compare_all"} if xp is jnp else {}
    span = xp.clip(xp.searchsorted(knots, x, side="right", **kw) - 1, degree, n - 1)
    nb = (xp.arange(k - 1)[None, :] == span[:, None]).astype(x.dtype)
    if deriv > degree:
        return xp.zeros((x.shape[0], n), x.dtype)
    xx = x[:, None]
    top = degree - deriv
    for p in range(1, degree + 1):
        m = k - 1 - p
        ui, uip, ui1, uip1 = knots[:m], knots[p : p + m], knots[1 : m + 1], knots[p + 1 : p + 1 + m]
        left, right = nb[:, :m], nb[:, 1 : m + 1]
        if p <= top:
            nb = _safe_div(xx - ui, uip - ui, xp) * left + _safe_div(uip1 - xx, uip1 - ui1, xp) * right
        else:
            nb = p * (_safe_div(left, uip - ui, xp) - _safe_div(right, uip1 - ui1, xp))
    return nb


def evaluate(x, knots, control, degree: int, deriv: int = 0, xp=jnp):
    """(M, d) values or derivatives of the spline at ``x`` (jnp: traceable, vmappable over knots/control)."""
    b = basis(x, knots, degree, control.shape[0], deriv, xp)
    return jnp.matmul(b, control, precision=jax.lax.Precision.HIGHEST) if xp is jnp else b @ control


def fit_bspline(x, values, n_control: int, degree: int = 3, *, field: str = "values") -> BSpline:
    """Least-squares clamped-uniform B-spline through samples ``values`` (M, d) or (M,) at ``x`` ∈ [0, 1]."""
    xs = np.asarray(x, dtype=np.float64)
    vals = np.asarray(values, dtype=np.float64)
    flat = vals.ndim == 1
    vals2 = vals[:, None] if flat else vals
    if xs.ndim != 1 or vals2.shape[0] != xs.size:
        raise ValidationError(field, vals.shape, f"need one sample per parameter ({xs.size})")
    if n_control < degree + 1 or xs.size < n_control:
        raise ValidationError("n_control", n_control, f"need degree + 1 ≤ n_control ≤ {xs.size} samples")
    knots = clamped_uniform_knots(n_control, degree)
    mat = basis(xs, knots, degree, n_control, xp=np)
    ctrl, *_ = np.linalg.lstsq(mat, vals2, rcond=None)
    return BSpline.make(ctrl[:, 0] if flat else ctrl, knots, degree, field=field, dim=None if flat else vals2.shape[1])


def piecewise(spline: BSpline, n_span: int | None = None) -> dict[str, np.ndarray]:
    """The spline as polynomial pieces, for cheap kernels.

    ``breaks`` (n_span + 1,) are the knots; ``coeffs`` (n_span, 4, d) hold, for each
    non-empty span [a, b), the power coefficients in y = (x − a)/(b − a) (zeros for empty
    spans and above the degree); ``inv_width`` (n_span,) is 1/(b − a) (0 for empty
    spans); ``spans`` (2,) the first and last non-empty span, where x = 0 and x = 1 fall.
    ``n_span`` ≥ K − 1 pads with unused spans starting at 2 (beyond the domain), so
    splines of any size and degree can share one compiled kernel.
    """
    kv, p = spline.knots, spline.degree
    n_span = kv.size - 1 if n_span is None else int(n_span)
    if n_span < kv.size - 1:
        raise ValidationError("n_span", n_span, f"need at least {kv.size - 1} spans")
    coeffs = np.zeros((n_span, MAX_DEGREE + 1, spline.dim))
    inv_width = np.zeros(n_span)
    nonempty = np.flatnonzero(np.diff(kv) > 0)
    y = np.linspace(0.0, 1.0, p + 1)
    vander = y[:, None] ** np.arange(p + 1)[None, :]
    a, b = kv[nonempty], kv[nonempty + 1]
    xs = (a[:, None] + (b - a)[:, None] * y[None, :]).ravel()
    vals = spline(np.clip(xs, 0.0, 1.0)).reshape(nonempty.size, p + 1, spline.dim)
    coeffs[nonempty, : p + 1] = np.linalg.solve(vander[None], vals)
    inv_width[nonempty] = 1.0 / (b - a)
    breaks = np.concatenate([kv, np.full(n_span + 1 - kv.size, 2.0)])
    return {
        "breaks": breaks,
        "coeffs": coeffs,
        "inv_width": inv_width,
        "spans": np.array([nonempty[0], nonempty[-1]], dtype=np.int32),
    }


def eval_piecewise(x, breaks, coeffs, inv_width, spans, deriv=0):
    """Values or derivatives from :func:`piecewise` arrays (Horner; traceable).

    ``deriv`` an int gives (M, d); a tuple of orders gives a tuple of them, sharing
    the span search.
    """
    x = jnp.asarray(x)
    n_span, q, d = coeffs.shape
    k = jnp.sum(breaks[None, 1:-1] <= x[:, None], axis=1)  # searchsorted(breaks, x, "right") - 1
    k = jnp.clip(k, spans[0], spans[1])
    # one matmul against a one-hot row replaces three gathers (much cheaper to compile)
    table = jnp.concatenate([coeffs.reshape(n_span, q * d), breaks[:-1, None], inv_width[:, None]], axis=1)
    # HIGHEST: a TF32 product would round the table's coefficients to 10 bits
    row = jnp.matmul((k[:, None] == jnp.arange(n_span)[None, :]).astype(x.dtype), table, precision=jax.lax.Precision.HIGHEST)
    c = row[:, : q * d].reshape(-1, q, d)
    y = (x - row[:, q * d]) * row[:, q * d + 1]
    iw = row[:, q * d + 1 : q * d + 2]
    p = coeffs.shape[1] - 1
    outs = []
    for order in (deriv,) if isinstance(deriv, int) else tuple(deriv):
        acc = jnp.zeros(c.shape[:1] + c.shape[2:], x.dtype)
        for j in range(p, order - 1, -1):
            fall = float(np.prod(np.arange(j - order + 1, j + 1))) if order else 1.0
            acc = acc * y[:, None] + fall * c[:, j]
        outs.append(acc * iw**order if order else acc)
    return outs[0] if isinstance(deriv, int) else tuple(outs)
