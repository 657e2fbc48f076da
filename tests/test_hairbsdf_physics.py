"""The hair BSDF's physics and its converged tables (issue 28, deliverables 1 and 2), as pbrt-v4 tests its HairBxDF.

What is checked, and the bounds:

* **White furnace** (σ_a = 0): ∫_{S²} f |cos| dω_i = 1 at *every* offset h (not only on average over h), for
  outgoing directions from pole to pole (sin θ_o = ±1 included), h = ±1 included, roughness β_m, β_n ≥ 0.05, by a
  deterministic tensor Gauss–Legendre rule in (θ_i, φ_i) graded about every lobe (``furnace``, which does not use
  the BSDF's factorisation).  Bound: |1 − E| ≤ 1e-6 with the rule's own error estimate (|Q_16 − Q_8|) ≤ 1e-5;
  measured |1 − E| ≤ 1e-11.  With absorption the same integral equals Σ_p A_p (the reference's), to 1e-9.
* **Sampled furnace**: each importance-sampled weight Σ_p M_p A_p N_p / pdf is 1 to rounding when σ_a = 0 (pbrt
  samples M_p and N_p exactly and picks p by A_p), so the estimate is 1 with zero variance; with absorption the
  estimate agrees with Σ_p A_p within 5 standard errors (fixed key).
* **Consistency**: the importance-sampled estimate agrees with a uniform-sphere estimate of the same integral
  within 5 combined standard errors (pbrt's SamplingConsistency), roughness ≥ 0.3.
* **Reciprocity**: the model is not reciprocal in general (pbrt §9.9.6: A_p and N_p use θ_o only, and the tilt
  rotates θ_o only; pbrt's own reciprocity test is disabled).  What holds, and is tested: with α = 0, d'Eon's M_p
  is symmetric in (θ_i, θ_o) for every pair of directions, and each lobe satisfies
  M_p A_p N_p (ωo, ωi; h) = M_p A_p N_p (ωi, ωo; −h) whenever cos θ_i = cos θ_o; with α = 2° the lobes differ.
* The JAX kernel equals the plain NumPy reference to float64 rounding, scaled by the problem's conditioning
  (|Δ| ≤ 1e-9 |ref| + 1e-12 × the largest lobe of the sample: the exponent of M_p carries a 1/v ≈ 1e5 factor).
* σ_a ↔ colour round trip (Chiang eq. 9), melanin, hostile inputs (ValidationError naming the key).
* Tables: the mean energies with σ_a = 0 sum to 1; A_f + A_b equals the total energy; the factorised h quadrature
  against SciPy quadratures of the reference's functions; narrow lobes' shifts and widths; coverage against the
  closed-form single-strand case and against an independent raster Monte Carlo of random strands; bitwise
  independence of the row split; the Unreal-style Monte Carlo is deterministic and converges where it can.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from hairlut.errors import ValidationError
from hairlut.hairbsdf import _bsdf as B
from hairlut.hairbsdf import _integrals as I
from hairlut.hairbsdf import _reference as R

RNG_SEED = 20160505


def _dirs_with(sin_theta, phi):
    c = np.sqrt(np.maximum(0.0, 1.0 - np.asarray(sin_theta) ** 2))
    return np.stack(np.broadcast_arrays(sin_theta, c * np.cos(phi), c * np.sin(phi)), axis=-1)


# ----------------------------------------------------------------------------- furnaces


def test_white_furnace_at_every_direction_offset_and_roughness():
    so = np.array([-1.0, -0.7, 0.0, 0.3, 0.9, 0.999, 1.0])[:, None, None]
    h = np.array([-1.0, -0.4, 0.0, 0.8, 1.0])[None, :, None]
    bm = np.array([0.05, 0.05, 0.3, 1.0])[None, None, :]
    bn = np.array([0.05, 1.0, 0.3, 0.05])[None, None, :]
    e, err = I.furnace(so, h, bm, bn, 0.0, nodes=16)
    assert np.all(np.isfinite(e))
    assert np.abs(1.0 - e).max() <= 1e-6, np.abs(1.0 - e).max()
    assert err.max() <= 1e-5, err.max()


@pytest.mark.slow
def test_white_furnace_fine_sweep():
    """Roughness 0.05 … 1 in both parameters, 21 outgoing directions, 9 offsets."""
    so = np.linspace(-1.0, 1.0, 21)[:, None, None, None]
    h = np.linspace(-1.0, 1.0, 9)[None, :, None, None]
    b = np.array([0.05, 0.1, 0.2, 0.4, 0.7, 1.0])
    e, err = I.furnace(so, h, b[None, None, :, None], b[None, None, None, :], 0.0, nodes=16)
    assert np.abs(1.0 - e).max() <= 1e-6 and err.max() <= 1e-5


def test_furnace_with_absorption_is_the_sum_of_the_attenuations():
    so = np.array([-0.6, 0.2, 0.95])[:, None]
    h = np.array([-0.9, 0.1, 1.0])[None, :]
    e, err = I.furnace(so, h, 0.2, 0.4, 0.7, nodes=16)
    ref = np.vectorize(lambda s, hh: R.albedo(s, hh, 0.7))(so, h)
    assert np.abs(e - ref).max() <= 1e-9 + err.max() and err.max() <= 1e-6


def test_sampling_weights_are_one_without_absorption():
    rng = np.random.default_rng(RNG_SEED)
    n = 4096
    wo = rng.normal(size=(n, 3))
    u = rng.uniform(size=(n, 4))
    h = rng.uniform(-1, 1, n)
    bm, bn = rng.uniform(0.02, 1.0, n), rng.uniform(0.02, 1.0, n)
    wi, pdf, lobes = B.sample(wo, u, h, 0.0, bm, bn)
    w = lobes.sum(-1)[..., 0] / pdf
    assert np.all(np.isfinite(wi)) and np.all(pdf > 0)
    assert np.abs(w - 1.0).max() <= 1e-12
    # the returned pdf is the pdf of the returned direction
    assert np.allclose(B.pdf(wo, wi, h, 0.0, bm, bn), pdf, rtol=1e-10)


@pytest.mark.parametrize(("beta_m", "beta_n"), [(0.3, 0.3), (0.6, 0.3), (0.3, 0.8)])
def test_sampled_furnace_and_consistency_with_uniform_sampling(beta_m, beta_n):
    """Importance sampling (pbrt) and uniform sphere sampling estimate the same albedo, Σ_p A_p, at fixed h."""
    rng = np.random.default_rng(RNG_SEED)
    n = 1 << 15
    so, phi_o, h, sigma = 0.35, 0.4, 0.3, np.array([0.25, 1.0])
    wo = _dirs_with(so, phi_o)[None]
    exact = np.array([R.albedo(so, h, s) for s in sigma])
    wi, pdf, lobes = B.sample(wo, rng.uniform(size=(n, 4)), h, sigma, beta_m, beta_n)
    w = lobes.sum(-1) / pdf[:, None]
    est, se = w.mean(0), w.std(0) / math.sqrt(n)
    assert np.all(np.abs(est - exact) <= 5 * se + 1e-12), (est, exact, se)
    zu = rng.uniform(-1, 1, n)
    wu = _dirs_with(zu, rng.uniform(0, 2 * math.pi, n))
    g = B.lobes(wo, wu, h, sigma, beta_m, beta_n).sum(-1) * (4 * math.pi)
    est_u, se_u = g.mean(0), g.std(0) / math.sqrt(n)
    assert np.all(np.abs(est_u - est) <= 5 * math.hypot(1, 1) * np.maximum(se_u, se)), (est_u, est, se_u, se)


# ----------------------------------------------------------------------------- reciprocity


def test_what_reciprocity_holds():
    rng = np.random.default_rng(RNG_SEED)
    n = 64
    so = rng.uniform(-1, 1, n)
    wo = _dirs_with(so, rng.uniform(-math.pi, math.pi, n))
    sign = np.where(rng.uniform(size=n) < 0.5, -1.0, 1.0)
    wi = _dirs_with(sign * so, rng.uniform(-math.pi, math.pi, n))  # cos θ_i = cos θ_o
    h = rng.uniform(-1, 1, n)
    sa = rng.uniform(0, 2, (n, 1))
    bm, bn = rng.uniform(0.1, 1, n), rng.uniform(0.1, 1, n)
    a = B.lobes(wo, wi, h, sa, bm, bn, alpha=0.0)
    b = B.lobes(wi, wo, -h, sa, bm, bn, alpha=0.0)
    assert np.allclose(a, b, rtol=1e-9, atol=1e-13 * a.max())
    tilted = B.lobes(wo, wi, h, sa, bm, bn, alpha=2.0) - B.lobes(wi, wo, -h, sa, bm, bn, alpha=2.0)
    assert np.abs(tilted).max() > 1e-3 * a.max()
    # M_p alone is symmetric for any pair of directions when α = 0
    ti, to = rng.uniform(-1.5, 1.5, (2, n))
    v = rng.uniform(1e-4, 3.0, n)
    import jax

    with jax.enable_x64(True):
        m1 = np.asarray(B.longitudinal(np.sin(ti), np.cos(ti), np.sin(to), np.cos(to), v))
        m2 = np.asarray(B.longitudinal(np.sin(to), np.cos(to), np.sin(ti), np.cos(ti), v))
    assert np.allclose(m1, m2, rtol=1e-13, atol=0)


# ----------------------------------------------------------------------------- kernel against reference


def _close_to_reference(got, ref, mn):
    """|Δ| ≤ 1e-9 |ref| + 1e-14 (1 + M_p N_p): a rounding of A_p (≤ 1) is amplified by M_p N_p, which reaches 1/v
    at the poles (where the lobe's cos θ_i dθ_i measure vanishes)."""
    return np.abs(got - ref) <= 1e-9 * np.abs(ref) + 1e-14 * (1.0 + mn)


_unit = st.floats(-1.0, 1.0)
_edge = st.sampled_from([-1.0, 1.0, 0.0])


@settings(max_examples=60)
@given(
    so=st.one_of(_unit, _edge),
    si=st.one_of(_unit, _edge),
    phi=st.floats(-math.pi, math.pi),
    h=st.one_of(_unit, _edge),
    beta_m=st.floats(0.01, 1.0),
    beta_n=st.floats(0.01, 1.0),
    sigma=st.floats(0.0, 5.0),
    alpha=st.floats(-5.0, 5.0),
)
def test_kernel_equals_the_reference(so, si, phi, h, beta_m, beta_n, sigma, alpha):
    wo = _dirs_with(so, 0.3)[None]
    wi = _dirs_with(si, phi)[None]
    got = B.lobes(wo, wi, [h], [[sigma]], [beta_m], [beta_n], alpha=alpha)
    ref = R.lobes(wo, wi, [h], [[sigma]], [beta_m], [beta_n], alpha=alpha)
    mn = R.lobes(wo, wi, [h], [[sigma]], [beta_m], [beta_n], alpha=alpha, unattenuated=True)
    assert np.all(np.isfinite(got))
    assert np.all(_close_to_reference(got, ref, mn)), (got, ref)


def test_poles_and_grazing_offsets_are_finite():
    e = np.array([-1.0, 0.0, 1.0])
    wo = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0.6, 0.0, 0.8]])
    wi = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0], [-0.6, 0.8, 0.0]])
    b = np.array([0.001, 0.05, 1.0])[:, None]  # batch (roughness 3, offset 3, wo 4, wi 4), σ_a 0 and 3 as channels
    args = (wo[:, None, :], wi[None, :, :], e[:, None, None, None], np.array([0.0, 3.0]), b[..., None, None], b[..., None, None])
    got = B.lobes(*args)
    assert np.all(np.isfinite(got))
    assert np.all(_close_to_reference(got, R.lobes(*args), R.lobes(*args, unattenuated=True)))
    assert np.all(np.isfinite(B.f(*args))) and np.all(np.isfinite(B.pdf(*args)))
    u = np.array([[0.0, 0.0, 0.0, 0.0], [0.999, 0.999, 0.5, 0.999], [0.5, 1e-300, 0.25, 1e-300]])
    wi_s, pdf, lob = B.sample(
        wo[:, None, :], u, e[:, None, None, None], np.array([0.0, 3.0]), b[..., None, None], b[..., None, None]
    )
    assert np.all(np.isfinite(wi_s)) and np.all(np.isfinite(pdf)) and np.all(np.isfinite(lob))


# ----------------------------------------------------------------------------- absorption, validation


def test_sigma_a_from_colour_round_trip_and_melanin():
    c = np.linspace(0.01, 1.0, 50)
    for beta_n in (0.05, 0.3, 1.0):
        sa = B.sigma_a_from_colour(c, beta_n)
        assert np.allclose(B.colour_from_sigma_a(sa, beta_n), c, rtol=1e-13, atol=0)
        assert np.allclose(sa, [R.sigma_a_from_colour(x, beta_n) for x in c], rtol=1e-13)
    assert B.sigma_a_from_colour(1.0, 0.3) == 0.0
    assert np.allclose(B.sigma_a_from_concentration(1.3, 0.2), [0.419 * 1.3 + 0.187 * 0.2, 0.697 * 1.3 + 0.08, 1.37 * 1.3 + 0.21])


@pytest.mark.parametrize(
    ("call", "key"),
    [
        (lambda: B.lobes([1, 0, 0], [0, 1, 0], 0.0, -0.1, 0.3, 0.3), "sigma_a"),
        (lambda: B.lobes([1, 0, 0], [0, 1, 0], 0.0, 0.1, 0.0, 0.3), "beta_m"),
        (lambda: B.lobes([1, 0, 0], [0, 1, 0], 0.0, 0.1, 0.3, 1.5), "beta_n"),
        (lambda: B.lobes([1, 0, 0], [0, 1, 0], 0.0, 0.1, float("nan"), 0.3), "beta_m"),
        (lambda: B.lobes([1, 0, 0], [0, 1, 0], 1.5, 0.1, 0.3, 0.3), "h"),
        (lambda: B.lobes([0, 0, 0], [0, 1, 0], 0.0, 0.1, 0.3, 0.3), "wo"),
        (lambda: B.lobes([1, 0, 0], [0, 1, 0], 0.0, 0.1, 0.3, 0.3, eta=1.0), "eta"),
        (lambda: B.sigma_a_from_colour(float("nan"), 0.3), "colour"),
        (lambda: B.sigma_a_from_colour([0.5, 0.0], 0.3), "colour"),
        (lambda: B.sigma_a_from_concentration(-1.0), "eumelanin"),
        (lambda: I.mean_energy(0.5, 0.3, float("nan")), "absorption"),
        (lambda: I.mean_energy(0.5, 1.2, 0.5), "roughness"),
        (lambda: I.mean_energy(0.5, 0.3, -1.0, absorption_kind="sigma_a"), "absorption"),
        (lambda: I.tables({"roughness": (-0.1, 1.0)}), "axes.roughness"),
        (lambda: I.tables({"absorption": (0.0, float("nan"))}), "axes.absorption"),
        (lambda: I.tables({"absorption_kind": "melanin"}), "axes.absorption_kind"),
        (lambda: I.tables(resolution={"roughness": 0}), "resolution.roughness"),
        (lambda: I.tables(quadrature={"nodes": 7}), "quadrature.nodes"),
        (lambda: I.tables(model={"eta": -2.0}), "model.eta"),
        (lambda: I.coverage(-1.0, 0.1), "strand_count"),
        (lambda: I.coverage(3.0, float("inf")), "radius_px"),
    ],
)
def test_hostile_inputs_name_the_key(call, key):
    with pytest.raises(ValidationError) as exc:
        call()
    assert exc.value.field == key


# ----------------------------------------------------------------------------- the tables

SMALL_AXES = {"sin_theta_o": (-1.0, 1.0), "roughness": (0.0, 1.0), "absorption": (0.0, 1.0)}
SMALL_RES = {"sin_theta_o": 6, "roughness": 5, "absorption": 3, "radius_px": 3, "strand_count": 4}


def test_mean_energy_without_absorption_sums_to_one_and_dual_scattering_adds_up():
    """σ_a = 0 (an absorption axis of σ_a ≈ 1e-300, so T = 1 exactly): E_R + E_TT + E_TRT + E_residual = 1 within the
    entries' own error estimates (each lobe is integrated on its own nodes), and A_f + A_b = Σ_p E_p to rounding."""
    clear = {**SMALL_AXES, "absorption_kind": "sigma_a", "absorption": (0.0, 1e-299)}
    (e, ee), (d, de) = I.tables(clear, SMALL_RES, which=("mean_energy", "dual_scattering")).values()
    assert np.all(np.abs(e.sum(-1) - 1.0) <= ee.sum(-1) + 1e-13) and ee.max() <= 1e-3
    assert np.abs(d[..., 0] + d[..., 1] - 1.0).max() <= 1e-6
    out = I.tables(SMALL_AXES, SMALL_RES, which=("mean_energy", "dual_scattering"))
    (ev, _), (dv, _) = out["mean_energy"], out["dual_scattering"]
    assert np.abs(dv[..., 0] + dv[..., 1] - ev.sum(-1)).max() <= 1e-13
    assert np.all(ev >= 0) and np.all(ev.sum(-1) <= 1 + 1e-9) and np.all(np.isfinite(dv))


PHI = np.linspace(-math.pi / 2, math.pi / 2, 4001)


def _h_integral(fn):
    return integrate.quad(fn, -math.pi / 2, math.pi / 2, epsabs=1e-13, epsrel=1e-13, limit=400)[0]


def test_tables_against_scipy_quadratures_of_the_reference():
    """E_p = ½∫A_p dh and a_b,p = ½∫A_p c_p dh, c_p = ∫_{|φ|<π/2} N_p dφ: SciPy's adaptive quadrature over h of the
    reference's A_p, and Simpson's rule over φ of the trimmed logistic written out again (roughness ≥ 0.3, smooth)."""
    eta = 1.55
    for so, rough, colour in [(0.3, 0.3, 0.6), (0.85, 0.6, 0.9), (0.0, 0.45, 0.3)]:
        sigma = R.sigma_a_from_colour(colour * colour, rough)
        cos_o = math.sqrt(1 - so * so)
        cos_t = math.sqrt(1 - (so / eta) ** 2)
        s = R.scale(rough)

        def parts(g, p, cos_o=cos_o, cos_t=cos_t, sigma=sigma, so=so):
            h = math.sin(g)
            sgt = h * cos_o / math.sqrt(eta * eta - so * so)
            t = math.exp(-sigma * 2 * math.sqrt(1 - sgt * sgt) / cos_t)
            return 0.5 * R.ap(cos_o, eta, h, t)[p] * math.cos(g), math.asin(h), math.asin(sgt)

        energy, back = [], []
        for p in range(4):
            energy.append(_h_integral(lambda g, p=p: parts(g, p)[0]))
            if p == 3:
                back.append(0.5 * energy[-1])
                continue

            def c_p(g, p=p, s=s):
                _, go, gt = parts(g, p)
                d = np.remainder(PHI - (2 * p * gt - 2 * go + p * math.pi) + math.pi, 2 * math.pi) - math.pi
                e = np.exp(-np.abs(d) / s)
                n = e / (s * (1 + e) ** 2) / (1 / (1 + math.exp(-math.pi / s)) - 1 / (1 + math.exp(math.pi / s)))
                return integrate.simpson(n, x=PHI)

            back.append(_h_integral(lambda g, p=p: parts(g, p)[0] * c_p(g)))
        e, ee = I.mean_energy(so, rough, colour)
        d, de = I.dual_scattering(so, rough, colour)
        assert np.abs(e - energy).max() <= max(1e-8, ee.max()), (e, energy)
        assert abs(d[1] - sum(back)) <= max(1e-8, de[1]) and abs(d[0] - (sum(energy) - sum(back))) <= max(1e-8, de[0])


def test_narrow_lobes_have_the_tilt_shifts_and_widths():
    """At low roughness, with the TT and TRT lobes absorbed away, the back half holds R alone: ᾱ_b = α (the R
    lobe's θ_h shift for pbrt's rotation of θ_o by −2α) and β̄_b = √v_0 / 2."""
    rough = 0.02
    d, de = I.dual_scattering(0.3, rough, 50.0, absorption_kind="sigma_a")
    assert abs(d[2 + 1] - math.radians(2.0)) <= 1e-4, d
    assert abs(d[4 + 1] - 0.5 * math.sqrt(B.longitudinal_variance(rough)[0])) <= 1e-4, d
    assert d[0] > 0.0 and np.all(de <= 1e-5)


def test_rows_do_not_depend_on_the_split():
    full = I.tables(SMALL_AXES, SMALL_RES)
    parts = [
        I.tables(SMALL_AXES, SMALL_RES, which=("mean_energy", "dual_scattering"), start=a, stop=b)
        for a, b in ((0, 2), (2, 3), (3, 6))
    ]
    for name in ("mean_energy", "dual_scattering"):
        for k in (0, 1):
            assert np.array_equal(np.concatenate([p[name][k] for p in parts]), full[name][k])
    cov = [I.tables(SMALL_AXES, SMALL_RES, which="coverage", start=a, stop=b)["coverage"] for a, b in ((0, 1), (1, 3))]
    for k in (0, 1):
        assert np.array_equal(np.concatenate([c[k] for c in cov]), full["coverage"][k])


def _single_strand(r):
    """E[K(|X − P|)] for X, P uniform in the unit square: the distance density (0 ≤ ρ ≤ √2) times K."""

    def dens(x):
        if x <= 1.0:
            return 2 * x * (math.pi - 4 * x + x * x)
        return 2 * x * (4 * math.sqrt(x * x - 1) - (x * x + 2 - math.pi) - 4 * math.acos(1 / x))

    def k(x):
        return 1.0 if x <= r else 2 / math.pi * math.asin(r / x)

    pts = [p for p in (r, 1.0) if 0 < p < math.sqrt(2)]
    return integrate.quad(lambda x: k(x) * dens(x), 0, math.sqrt(2), points=pts, epsabs=1e-13, limit=200)[0]


def test_coverage_of_one_strand_is_the_closed_form():
    r = np.array([0.001, 0.05, 0.2, 0.5])
    c, ce = I.coverage(1.0, r)
    exact = np.array([_single_strand(x) for x in r])
    assert np.abs(c - exact).max() <= 2e-5 and ce.max() <= 1e-4, (c, exact, ce)
    # small r: 2r/π ∫_0^π f_D(0; θ) dθ = (8/π)(ln(1 + √2) − (√2 − 1)/3) r
    assert abs(c[0] / r[0] - 8 / math.pi * (math.log1p(math.sqrt(2)) - (math.sqrt(2) - 1) / 3)) <= 2e-3
    n0, _ = I.coverage(0.0, r)
    assert np.abs(n0).max() <= 1e-15


def test_coverage_against_a_raster_of_random_strands():
    rng = np.random.default_rng(RNG_SEED)
    g = (np.arange(48) + 0.5) / 48
    gx, gy = np.meshgrid(g, g, indexing="ij")
    trials = 300
    for r, n in ((0.05, 1), (0.05, 6), (0.2, 3)):
        frac = []
        for _ in range(trials):
            p = rng.uniform(size=(n, 2))
            t = rng.uniform(0, math.pi, n)
            d = np.abs((gx[..., None] - p[:, 0]) * np.sin(t) - (gy[..., None] - p[:, 1]) * np.cos(t))
            frac.append(np.mean(np.any(d <= r, axis=-1)))
        frac = np.asarray(frac)
        c, _ = I.coverage(float(n), r)
        assert abs(c - frac.mean()) <= 5 * frac.std() / math.sqrt(trials) + 1e-3, (r, n, c, frac.mean())


def test_montecarlo_baseline_is_deterministic_and_converges_where_smooth():
    axes = {**SMALL_AXES, "roughness": (0.5, 1.0), "absorption": (0.3, 1.0)}
    axes["strand_count"] = (-0.5, 3.5)  # the counts 0 … 3 (the Monte Carlo draws whole strands)
    bsdf = {"which": ("mean_energy", "dual_scattering"), "start": 4, "stop": 6}  # two sin θ_o rows of six
    a = I.montecarlo_unreal(axes, SMALL_RES, seed=3, **bsdf) | I.montecarlo_unreal(axes, SMALL_RES, seed=3, which="coverage")
    b = I.montecarlo_unreal(axes, SMALL_RES, seed=3, **bsdf) | I.montecarlo_unreal(axes, SMALL_RES, seed=3, which="coverage")
    q = I.tables(axes, SMALL_RES, **bsdf) | I.tables(axes, SMALL_RES, which="coverage")
    for name in I.TABLES:
        assert np.array_equal(a[name], b[name])
    assert np.abs(a["mean_energy"] - q["mean_energy"][0]).max() <= 0.02
    assert np.abs(a["dual_scattering"][..., :2] - q["dual_scattering"][0][..., :2]).max() <= 0.03
    assert np.abs(a["coverage"] - q["coverage"][0]).max() <= 0.08
    assert np.all((a["mean_energy"] >= 0) & (a["mean_energy"] <= 1))
