"""Stress cases for the SH side (xing §4): the basis to lmax 40, the Kajiya–Kay lobes' Legendre
coefficients for exponents 1 … 10⁴, the exact tables at tangents on the poles and the axes,
θ′ at 0, π/2 and π, bad tangents, the float32 radiance with its SH ringing counted, and the
lobes' cosine form at their edge with t ∥ ω and fractional exponents (issue 29 m16).

Every comparison is against a float64 reference through public names only:
:func:`hairlut.sh.real_sh_reference` (angles + unnormalised Legendre, a different algorithm),
:func:`hairlut.shtables.reference_r` (direct quadrature on the sphere, no Gaunt coefficients)
and :func:`zonal_reference` here (Gauss–Legendre pieces around the lobe's peak with SciPy's
Legendre polynomials, no ψ substitution and no Chebyshev series), and :func:`kk_lobe_exact` (exact
rational arithmetic and 50-digit roots).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ._tally import Case

#: Band limit the basis cases reach (the issue's "SH up to lmax 40").
LMAX = 40
#: Specular exponents swept (quick: the two ends).
EXPONENTS = (1.0, 10.0, 100.0, 1000.0, 10000.0)
EXPONENTS_QUICK = (1.0, 10000.0)
#: The exponent of the quick tables at the poles, radiance and bad-tangent cases: the fewest Chebyshev nodes
#: (the slowest compile is the θ′ series of p = 1e4, which the full run and sh.kk_exponents cover).
QUICK_P = 1.0
#: θ′ values every SH case visits: the ends and the middle of [0, π], and just inside the ends.
THETA_V = (0.0, 1e-9, np.pi / 4, np.pi / 2, 3 * np.pi / 4, np.pi - 1e-9, np.pi)
#: Bands (light diffuse, light specular, transmittance) of every table here: k_l for l ≤ 5 (the exponent,
#: the tangent and θ′ are stressed, not the band count), so one compiled kernel serves each exponent.
BANDS = (2, 5, 2)

# Tolerances: each is the bound on the case's error metric, with its reason.
#: float64 basis vs the angle-based reference, max |ΔY| / max |Y|: rounding grows ~l·ε (measured ~1e-14).
SH_F64_TOL = 1e-12
#: float32 basis, same metric: hairlut.sh's stated float32 gap to the float64 reference (≤ 1e-4 to lmax 64).
SH_F32_TOL = 1e-4
#: k_l(θ′) vs the independent quadrature, max_l |Δk_l| / k_0: the bake's Chebyshev tail is < 1e-14; 1e-9 leaves room
#: for the reference's own quadrature error at p = 10⁴.
COEFF_TOL = 1e-9
#: Rd, Rs vs direct quadrature on the sphere, max |ΔR| / max |R|: both exact up to quadrature rounding.
TABLES_TOL = 1e-9
#: float32 radiance vs float64, max |ΔI| / max |I|: the radiance's stated float32 relative error is ~1e-6.
RADIANCE_F32_TOL = 1e-5
#: The cosine form at the lobe's edge vs exact arithmetic, max |Δ| (absolute): the float64 base's rounding (a few
#: 1e-16) through x^p, at most (4e-16)^0.5 = 2e-8 at the smallest exponent.
KK_EDGE_TOL = 5e-8
#: Exponents of the edge case: fractional ones first (their power amplifies an absolute error of the base the most).
KK_EDGE_P = (0.5, 0.75, 1.0, 2.5, 49.0)
#: How far past the normal plane of t the edge case puts v (t·v = −tilt): the lobe's base is about that.
KK_EDGE_TILT = (0.0, 1e-16, 2e-8, 1e-6, 1e-3)


def axis_tangents() -> np.ndarray:
    """±x, ±y, ±z and two tangents a hair's breadth (1e-12 rad) from the poles, unit length."""
    e = np.eye(3)
    near = np.array([[1e-12, 0.0, 1.0], [0.0, -1e-12, -1.0]])
    t = np.concatenate([e, -e, near])
    return t / np.linalg.norm(t, axis=1, keepdims=True)


def _directions(n_random: int, seed: int = 0) -> np.ndarray:
    """The axis tangents, the diagonals of the octants and the equator, and ``n_random`` random directions."""
    rng = np.random.default_rng(seed)
    diag = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
    equator = np.stack([np.cos(np.linspace(0, 2 * np.pi, 13)), np.sin(np.linspace(0, 2 * np.pi, 13)), np.zeros(13)], 1)
    r = rng.normal(size=(n_random, 3))
    d = np.concatenate([axis_tangents(), diag, equator, r])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _sh_reference(lmax, dirs):
    from ..sh import real_sh_reference

    return real_sh_reference(lmax, dirs)


def _basis(dtype):
    def body(tally, ctx):
        from ..sh import real_sh

        d = _directions(48 if ctx.quick else 2000)
        ref = np.asarray(ctx.reference(LMAX, d), np.float64)
        got = tally.finite(f"Y (lmax {LMAX}, {np.dtype(dtype).name})", real_sh(LMAX, d.astype(dtype)))
        err = np.abs(got - ref).max(axis=0) / np.abs(ref).max()
        tally.compare(f"lmax {LMAX} at {len(d)} directions", got, ref)
        l_of = np.floor(np.sqrt(np.arange(err.size))).astype(int)
        worst_l = int(l_of[np.argmax(err)])
        axes = np.abs(got[:8] - ref[:8]).max() / np.abs(ref).max()
        tally.note(f"{len(d)} directions incl. ±x ±y ±z and 1e-12 from the poles; worst at l = {worst_l}; on the axes {axes:.1e}")

    return body


def zonal_reference(p: float, theta_v: float, lmax: int, pieces: int = 64) -> np.ndarray:
    """k_l(θ′) = 2π ∫₀^π max(0, −cos(θ + θ′))^p P_l(cos θ) sin θ dθ, l ≤ lmax, by Gauss–Legendre pieces
    (``pieces`` points each) split at the lobe's support ends and at the peak θ = π − θ′ ± 2^k/√p."""
    from scipy.special import eval_legendre

    lo, hi = max(0.0, np.pi / 2 - theta_v), min(np.pi, 3 * np.pi / 2 - theta_v)
    peak, width = np.pi - theta_v, 1.0 / math.sqrt(p)
    cuts = {lo, hi, peak}
    for k in range(-2, 8):
        cuts.update({peak - 2.0**k * width, peak + 2.0**k * width})
    cuts = np.array(sorted(c for c in cuts if lo <= c <= hi))
    x, w = np.polynomial.legendre.leggauss(pieces)
    a, b = cuts[:-1, None], cuts[1:, None]
    theta = (0.5 * (b - a) * (x + 1) + a).ravel()
    weight = (0.5 * (b - a) * w).ravel()
    f = np.maximum(-np.cos(theta + theta_v), 0.0) ** p * np.sin(theta) * weight
    return 2 * np.pi * np.array([np.sum(f * eval_legendre(l, np.cos(theta))) for l in range(lmax + 1)])


@functools.lru_cache(maxsize=8)
def _tables(p: float):
    from ..shtables import compute

    d, s, t = BANDS
    return compute({"kernel": {"p": p}, "bands": {"light_diffuse": d, "light_specular": s, "transmittance": t}})["tables"]


def _coeffs(tally, ctx):
    from ..shtables import band_truncation_error, specular_band_rule

    exps = EXPONENTS_QUICK if ctx.quick else EXPONENTS
    for p in exps:
        tables = _tables(p)
        got = tally.finite(f"k_l p={p:g}", tables.specular_coeffs(np.array(THETA_V)))
        for i, tv in enumerate(THETA_V):
            ref = np.asarray(ctx.reference(p, tv, tables.lmax_s), np.float64)
            k0 = float(ref[0]) or 1.0
            tally.compare(f"p={p:g} θ′={tv:.4g}", got[i], ref, scale=abs(k0))
            # a non-negative lobe: k_0 ≥ 0 and |k_l| ≤ k_0 (|P_l| ≤ 1)
            tally.within(f"k_0 p={p:g} θ′={tv:.4g}", got[i, :1], 0.0, None)
            tally.within(f"|k_l|/k_0 p={p:g} θ′={tv:.4g}", np.abs(got[i]) - got[i, 0], None, 0.0, slack=1e-12 * abs(k0))
    p = max(exps)
    rule = specular_band_rule(p)
    if ctx.quick:
        tally.note(
            f"p={p:g}: the √p rule asks {rule} light bands (recipes allow ≤ 65; the full run reports the truncation error there)"
        )
        return
    capped = min(rule, 65)
    tally.note(
        f"p={p:g}: the √p rule asks {rule} light bands, recipes allow ≤ 65; at {capped} the lobe's "
        f"truncation error is {band_truncation_error(p, capped):.2f} (a band limit, not a rounding fault)"
    )


def _tables_body(tally, ctx):
    exps = (QUICK_P,) if ctx.quick else EXPONENTS
    t = axis_tangents()
    tv = np.array(THETA_V)
    for p in exps:
        tb = _tables(p)
        rd = tally.finite(f"Rd p={p:g}", tb.rd(t))
        rs = tally.finite(f"Rs p={p:g}", tb.rs(t[:, None, :], tv[None, :]))
        ld, ls, lt = (b - 1 for b in BANDS)
        ref_d = np.stack([ctx.reference(ti, 0.0, p, ld, lt, specular=False) for ti in t])
        ref_s = np.stack([[ctx.reference(ti, v, p, ls, lt) for v in tv] for ti in t])
        tally.compare(f"Rd p={p:g}", rd, ref_d)
        tally.compare(f"Rs p={p:g}", rs, ref_s)
    tally.note(f"{len(t)} tangents (axes, 1e-12 from the poles) × {len(tv)} θ′ in [0, π]")


def _r_reference(t, theta_v, p, lmax_i, lmax_j, specular=True):
    from ..shtables import reference_r

    return reference_r(t, theta_v, p, lmax_i, lmax_j, specular=specular)


def _light(lmax: int) -> np.ndarray:
    """SH coefficients of a narrow positive light (a lobe max(0, ω·s)^32 toward s), by quadrature."""
    from ..sh import project_function

    s = np.array([0.3, -0.5, 0.81])
    s /= np.linalg.norm(s)
    return np.asarray(project_function(lambda w: np.maximum(w @ s, 0.0) ** 32, lmax, L=4 * (lmax + 1)))


def _radiance(tally, ctx):
    p = QUICK_P if ctx.quick else 100.0
    tb = _tables(p)
    a = _light(BANDS[1] - 1)
    con = tb.contract(a)
    rng = np.random.default_rng(3)
    n = 256 if ctx.quick else 8192
    t = np.concatenate([axis_tangents(), rng.normal(size=(n, 3))])
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    tv = np.concatenate([np.repeat(np.array(THETA_V), 2)[: len(axis_tangents())], rng.uniform(0, np.pi, n)])
    b = np.zeros((len(t), tb.bands.n_trans))
    b[:, 0] = math.sqrt(4 * np.pi)  # T ≡ 1: unshadowed
    i64 = tally.finite("I float64", con.radiance(b, t, tv))
    i32 = tally.finite("I float32", con.radiance(b, t, tv, dtype="float32"))
    tally.compare("I float32 vs float64", i32, ctx.reference(i64))
    # the float64 radiance itself, at the axis tangents, against Σ a_i b_j (Rd + Rs) from sphere quadrature
    ld, ls, lt = (k - 1 for k in BANDS)
    ref = [
        a[: (ld + 1) ** 2] @ _r_reference(ti, v, p, ld, lt, specular=False) @ bi[: (lt + 1) ** 2]
        + a[: (ls + 1) ** 2] @ _r_reference(ti, v, p, ls, lt) @ bi[: (lt + 1) ** 2]
        for ti, v, bi in zip(t[:8], tv[:8], b[:8])
    ]
    e64 = tally.compare("I float64 at the axes vs quadrature", i64[:8], np.array(ref))
    tally.note(f"float64 radiance at ±x ±y ±z and the poles vs Σ a b (Rd + Rs) by sphere quadrature: {e64:.1e}")
    neg = i64 < 0
    tally.count("ringing (I < 0)", int(neg.sum()))
    tally.note(
        f"p={p:g}, {BANDS[1]} light bands, a positive lobe light, T ≡ 1: {int(neg.sum())} of {neg.size} radiances < 0 "
        f"(SH ringing, min {float(i64.min()):.2e} against max {float(i64.max()):.2e})"
    )


def _bad_tangents(tally, ctx):
    from ..sh import real_sh

    tb = _tables(QUICK_P)
    con = tb.contract(np.ones(tb.bands.n_light_specular))
    bad = {"zero": [0.0, 0.0, 0.0], "non-unit": [0.0, 0.0, 2.0], "NaN": [np.nan, 0.0, 1.0], "Inf": [np.inf, 0.0, 0.0]}
    b = np.zeros((1, tb.bands.n_trans))
    b[:, 0] = 1.0
    for name, t in bad.items():
        t = np.array([t])
        tally.rejects(f"real_sh({name})", lambda: real_sh(4, t))
        tally.rejects(f"rd({name})", lambda: tb.rd(t))
        tally.rejects(f"rs({name})", lambda: tb.rs(t, np.array([0.5])))
        tally.rejects(f"radiance({name})", lambda: con.radiance(b, t, np.array([0.5])))
    tally.rejects("real_sh(zero, normalize=True)", lambda: real_sh(4, np.zeros((1, 3)), normalize=True))
    up = np.array([[0.0, 0.0, 1.0]])
    for tv in (-0.1, np.pi + 0.1, np.nan):
        tally.rejects(f"rs(θ′={tv})", lambda: tb.rs(up, np.array([tv])))
    y = tally.finite("real_sh(non-unit, normalize=True)", real_sh(4, np.array([[0.0, 0.0, 2.0]]), normalize=True))
    tally.compare("normalize=True equals the unit direction", y, np.asarray(real_sh(4, up)))
    tally.note("zero, non-unit, NaN and Inf tangents and θ′ outside [0, π] raise ValidationError")


def kk_lobe_exact(t, w, v, p) -> float:
    """max(0, sin θ sin θ′ − cos θ cos θ′)^p of the vectors t, ω, v as given (normalised exactly), in exact rational
    arithmetic with 50-digit roots and power: cos = a·b / |a||b|, sin² by Lagrange's identity |a × b|² =
    |a|²|b|² − (a·b)² (no float rounding before the last step; independent of hairlut.kernels)."""
    from decimal import Decimal, localcontext
    from fractions import Fraction

    T, W, V = ([Fraction(float(x)) for x in u] for u in (t, w, v))

    def dot(a, b):
        return sum(x * y for x, y in zip(a, b))

    with localcontext() as ctx:
        ctx.prec = 50

        def dec(f):
            return Decimal(f.numerator) / Decimal(f.denominator)

        def cos_sin(a, b):
            aa, bb, ab = dot(a, a), dot(b, b), dot(a, b)
            n = dec(aa * bb).sqrt()
            return dec(ab) / n, dec(aa * bb - ab * ab).sqrt() / n

        (cl, sl), (cv, sv) = cos_sin(T, W), cos_sin(T, V)
        base = sl * sv - cl * cv
        return float(base ** Decimal(float(p))) if base > 0 else 0.0


def edge_vectors(n_random: int, seed: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, ω, v), each (n, 3) unit: t on the axes and at random; ω = t, −t, or t turned by 1e-12 rad; v in the
    normal plane of t tilted by each of :data:`KK_EDGE_TILT` toward −t (the lobe's edge: base ≈ the tilt)."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([axis_tangents(), rng.normal(size=(n_random, 3))])
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    side = np.cross(t, rng.normal(size=t.shape))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    rows = []
    for turn in (0.0, np.pi, 1e-12):
        w = np.cos(turn) * t + np.sin(turn) * side
        for tilt in KK_EDGE_TILT:
            v = np.cross(t, side) * np.cos(tilt) - t * np.sin(tilt)
            rows.append((t, w / np.linalg.norm(w, axis=1, keepdims=True), v / np.linalg.norm(v, axis=1, keepdims=True)))
    return tuple(np.concatenate([r[k] for r in rows]) for k in range(3))


def _kk_edge(tally, ctx):
    from ..kernels import sin_between, specular_cos

    t, w, v = edge_vectors(4 if ctx.quick else 64)
    cl, cv = np.einsum("ij,ij->i", t, w), np.einsum("ij,ij->i", t, v)
    sl, sv = sin_between(t, w), sin_between(t, v)
    alone = 0.0
    for p in KK_EDGE_P:
        ref = np.array([ctx.reference(a, b, c, p) for a, b, c in zip(t, w, v)])
        got = tally.finite(f"specular_cos p={p:g}", specular_cos(cl, cv, p, sl, sv))
        tally.within(f"specular_cos p={p:g}", got, 0.0, 1.0)
        tally.compare(f"p={p:g}, sines from the cross products", got, ref, scale=1.0)
        alone = max(alone, float(np.abs(specular_cos(cl, cv, p) - ref).max()))
    tally.note(
        f"{len(t)} (t, ω, v) with ω = t, −t, t turned 1e-12 rad and t·v = −tilt ∈ {list(KK_EDGE_TILT)}, p ∈ "
        f"{list(KK_EDGE_P)}; from the cosines alone (√((1 − c)(1 + c))) the worst error is {alone:.1e}: "
        "the sine of a rounded cosine near ±1 (why callers with vectors pass |t × ω|)"
    )


CASES = (
    Case(
        "sh.basis_f64",
        f"real_sh float64 to lmax {LMAX} vs the angle-based reference",
        SH_F64_TOL,
        "rounding grows ~l·ε in the recurrence; measured ~1e-14",
        _sh_reference,
        _basis(np.float64),
    ),
    Case(
        "sh.basis_f32",
        f"real_sh float32 to lmax {LMAX} vs the float64 reference",
        SH_F32_TOL,
        "hairlut.sh states ≤ 1e-4 to lmax 64 in float32",
        _sh_reference,
        _basis(np.float32),
    ),
    Case(
        "sh.kk_exponents",
        "specular k_l(θ′) for p = 1 … 1e4 vs independent quadrature",
        COEFF_TOL,
        "bake's Chebyshev tail < 1e-14; room for the reference's quadrature at p = 1e4",
        zonal_reference,
        _coeffs,
    ),
    Case(
        "sh.tables_poles",
        "Rd, Rs at ±x ±y ±z and the poles, θ′ ∈ {0, π/2, π} vs sphere quadrature",
        TABLES_TOL,
        "both exact up to quadrature rounding",
        _r_reference,
        _tables_body,
    ),
    Case(
        "sh.radiance_f32",
        "radiance float32 vs float64 (SH ringing counted)",
        RADIANCE_F32_TOL,
        "the radiance's stated float32 relative error is ~1e-6",
        lambda x: x,
        _radiance,
    ),
    Case(
        "sh.bad_tangents",
        "zero, non-unit, NaN tangents and θ′ outside [0, π] are rejected",
        1e-12,
        "normalize=True must give the unit direction's SH to rounding",
        None,
        _bad_tangents,
    ),
    Case(
        "sh.kk_cosine_edge",
        "Kajiya–Kay specular from cosines at t ∥ ω, the lobe's edge, p = 0.5 … 49, vs exact arithmetic",
        KK_EDGE_TOL,
        "the float64 base's rounding through x^p: ≤ 2e-8 at p = 0.5",
        kk_lobe_exact,
        _kk_edge,
    ),
)
