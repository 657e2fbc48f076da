"""Online lighting and compositing: eqs 9–14 against hand-computed values; specular switched off costs nothing."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from hairlut.synth import _shading
from hairlut.synth._shading import blend, compose_kernel, lighting_kernel, shade, shadow_map, specular


def test_eq12_exponential_and_linear():
    alpha = np.array([0.2, 0.5, 0.4]).reshape(3, 1, 1)  # layer 2 outermost
    k = 0.7
    tau = np.asarray(shadow_map(alpha, k))[:, 0, 0]
    np.testing.assert_allclose(tau, [np.exp(-k * 0.9), np.exp(-k * 0.4), 1.0], rtol=1e-6)
    lin = np.asarray(shadow_map(alpha, k, linear=True))[:, 0, 0]
    np.testing.assert_allclose(lin, [1 - k * 0.9, 1 - k * 0.4, 1.0], rtol=1e-6)
    assert float(shadow_map(alpha, 5.0, linear=True)[0, 0, 0]) == 0.0  # clamped at 0


def test_eq13_two_lights():
    lighting = np.array([[0.2, 0.4, 0.6], [0.1, 0.1, 0.0]]).reshape(1, 1, 1, 2, 3)  # (K, t, u, L, 3)
    re = np.array([0.5, 0.25]).reshape(1, 2, 1, 1)  # (K, L, t, u)
    tau = np.full((1, 1, 1), 0.8)
    out = np.asarray(shade(lighting, re, tau))[0, 0, 0]
    want = 0.8 * (0.5 * np.array([0.2, 0.4, 0.6]) + 0.25 * np.array([0.1, 0.1, 0.0]))
    np.testing.assert_allclose(out, want, rtol=1e-6)


def test_eq14_blending_order():
    rgb = np.array([[0.2, 0.3, 0.4], [0.9, 0.1, 0.5], [0.3, 0.3, 0.3]]).reshape(3, 1, 3)  # 3 layers, 1 texel
    a = np.array([0.5, 0.25, 0.6]).reshape(3, 1)
    bk = np.array([0.1, 0.2, 0.3])
    out, alpha = blend(rgb, a, bk)
    want = bk * 0.5 * 0.75 * 0.4 + rgb[0, 0] * 0.5 * 0.75 * 0.4 + rgb[1, 0] * 0.25 * 0.4 + rgb[2, 0] * 0.6
    np.testing.assert_allclose(np.asarray(out)[0], want, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(alpha)[0], 1 - 0.5 * 0.75 * 0.4, rtol=1e-6)


def test_compose_kernel_is_12_13_14():
    rng = np.random.default_rng(0)
    K, L = 3, 2
    lighting = rng.uniform(size=(K, 2, 3, L, 3)).astype(np.float32)
    re = rng.uniform(size=(K, L, 2, 3)).astype(np.float32)
    alpha = rng.uniform(size=(K, 2, 3)).astype(np.float32)
    tau, rgb, final, a = compose_kernel(lighting, re, alpha, 0.5, jnp.zeros(3), shadow=True)
    t2 = shadow_map(alpha, 0.5)
    np.testing.assert_allclose(tau, t2, rtol=1e-6)
    np.testing.assert_allclose(rgb, shade(lighting, re, t2), rtol=1e-6)
    tau_off, *_ = compose_kernel(lighting, re, alpha, 0.5, jnp.zeros(3), shadow=False)
    assert np.all(np.asarray(tau_off) == 1.0)


def _rand_unit(rng, n):
    x = rng.normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _args(rng, n=256, lights=3):
    t, nrm = _rand_unit(rng, n), _rand_unit(rng, n)
    return (
        jnp.asarray(t, jnp.float32),
        jnp.asarray(nrm, jnp.float32),
        jnp.asarray(_rand_unit(rng, 1)[0], jnp.float32),
        jnp.asarray(_rand_unit(rng, lights), jnp.float32),
        jnp.ones((lights, 3), jnp.float32),
        jnp.asarray(rng.uniform(size=n), jnp.float32),
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_reflectance_bounded_when_kd_plus_ks_le_1(seed):
    rng = np.random.default_rng(seed)
    args = _args(rng)
    kd, ks1, ks2 = rng.dirichlet([1, 1, 1])
    mat = jnp.asarray([kd, ks1, ks2, 2.0, 1.5, 0.3, 0.75, 0.25, 0.5], jnp.float32)  # Scheuermann's 0.75/0.25
    colours = jnp.asarray(rng.uniform(size=(3, 3)), jnp.float32)
    light = np.asarray(lighting_kernel(*args, mat, colours, noise=True))
    assert light.min() >= 0 and light.max() <= 1 + 1e-5
    re = rng.uniform(size=(1, 3, 256)).astype(np.float32)  # per light, ≤ 1
    alpha = rng.uniform(size=(1, 256)).astype(np.float32)
    _, rgb, final, _ = compose_kernel(light[None] / 3, re, alpha, 0.5, jnp.ones(3))
    assert np.asarray(rgb).max() <= 1 + 1e-5 and np.asarray(final).max() <= 1 + 1e-5


def test_diffuse_eq9_and_specular_peak():
    t = jnp.asarray([[1.0, 0.0, 0.0]])
    th = 0.7
    l = jnp.asarray([[np.cos(th), np.sin(th), 0.0]])
    mat = jnp.asarray([1.0, 0.0, 0.0, 1, 1, 0, 1, 0, 0], jnp.float32)
    out = lighting_kernel(
        t,
        jnp.asarray([[0.0, 0.0, 1.0]]),
        jnp.asarray([0.0, 1.0, 0.0]),
        l,
        jnp.ones((1, 3)),
        jnp.zeros(1),
        mat,
        jnp.eye(3),
        primary=False,
        secondary=False,
    )
    np.testing.assert_allclose(np.asarray(out)[0, 0], [np.sin(th), 0, 0], rtol=1e-5)
    # mirror cone θ + θ′ = π: l at θ from t, v at π − θ from t → kernel 1 (shift 0)
    v = jnp.asarray([np.cos(np.pi - th), np.sin(np.pi - th), 0.0])
    assert float(specular(t, jnp.asarray([[0.0, 0.0, 1.0]]), v, l, 0.0, 50.0)[0, 0]) == pytest.approx(1.0, abs=1e-5)


def test_specular_off_does_no_specular_work(monkeypatch):
    calls = []
    real = _shading.specular

    def counted(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(_shading, "specular", counted)
    args = _args(np.random.default_rng(2), n=8, lights=1)
    mat, colours = jnp.ones(9, jnp.float32), jnp.ones((3, 3), jnp.float32)
    fn = _shading.lighting_kernel.__wrapped__ if hasattr(_shading.lighting_kernel, "__wrapped__") else None
    assert fn is not None
    off = jax.make_jaxpr(lambda *a: fn(*a, primary=False, secondary=False))(*args, mat, colours)
    assert calls == [] and "pow" not in str(off)
    on = jax.make_jaxpr(lambda *a: fn(*a, primary=True, secondary=True))(*args, mat, colours)
    assert len(calls) == 2 and "pow" in str(on)
