"""Online lighting, self-shadowing, shading and blending (satf §6.3–6.5, eqs 8–14; Scheuermann).

Conventions (DESIGN.md): t the unit hair tangent, n the unit layer normal, v toward the
viewer, l toward the light; sin(X, Y) = √(1 − (X·Y)²) for unit vectors.

- Diffuse (eq 9): kd · max(0, a·sin(t, l) + b) · f_dif, with a = 1, b = 0 giving eq 9 and
  (a, b) Scheuermann's scale and bias.
- Specular (eqs 10, 11): t̃ = (t ± s n)/‖t ± s n‖ and the Kajiya–Kay kernel
  max(0, sin(t̃, l) sin(t̃, v) − (t̃·l)(t̃·v))^p, which peaks on the mirror cone (the
  paper's "+" form is the same kernel with v pointing from the eye; the lobes are
  :mod:`hairlut.kernels`'s, the shift only moves the tangent they are evaluated at).  Primary: +s,
  exponent p_I, colour f_speI; secondary: −s, its own exponent p_II, colour f_speII
  (the hair colour when tinted), optionally modulated by a noise texture (Scheuermann).
- Lighting (eq 8) is the sum, per light, times the light's RGB.
- s-map (eq 12): τ_k = exp(−k_shadow Σ_{m>k} α_m) over the outer layers m > k (layer
  indices grow outward); the linear form max(0, 1 − k_shadow Σ α_m) as an option.
- Shading (eq 13): Ψ_k = τ_k Σ_lights Ψ^lighting_k,j · re_k,j; with a light-space shadow
  method (the light-oriented map, opacity maps: ``hairlut.shadows.light_transmittance``)
  each light has its own transmittance, Ψ_k = Σ_lights T_k,j Ψ^lighting_k,j · re_k,j.  By default
  the online module passes α_k as re_k,j (``[material] reflectance = "unit"``: the lighting per unit of
  opacity, a departure from the paper measured in ``hairlut.synth.shade_kernel``'s docstring); the
  HRIR's re with ``"hrir"``.
- Blending (eq 14): Ψ^final = Ψ^bk Π_k (1 − α_k) + Σ_k Ψ_k α_k Π_{j>k} (1 − α_j), over the
  background; the composite's alpha is 1 − Π_k (1 − α_k).

The jitted kernels take the effect switches as static arguments: a switched-off term is
not traced at all, so it costs nothing.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ..kernels import diffuse_cos, sin_between, specular_cos


def _dot(a, b):
    """a (..., 3) · b (3,) → (...), or · b (L, 3) → (..., L); spelled out, so XLA fuses it elementwise."""
    if b.ndim == 1:
        return a[..., 0] * b[0] + a[..., 1] * b[1] + a[..., 2] * b[2]
    return a[..., 0, None] * b[:, 0] + a[..., 1, None] * b[:, 1] + a[..., 2, None] * b[:, 2]


def _unit(x):
    return x / jnp.maximum(jnp.sqrt(x[..., 0] ** 2 + x[..., 1] ** 2 + x[..., 2] ** 2), 1e-12)[..., None]


def diffuse(t, l, scale, bias):
    """Eq 9's kernel, scaled and biased: max(0, scale·sin(t, l) + bias); t (..., 3), l (L, 3) → (..., L).
    sin(t, l) is the Kajiya–Kay diffuse lobe (:func:`hairlut.kernels.diffuse_cos`), the sine from the cross product
    (accurate where t ∥ l)."""
    return jnp.maximum(0.0, scale * diffuse_cos(_dot(t, l), sin_between(t[..., None, :], l)) + bias)


def specular(t, n, v, l, shift, p):
    """Eqs 10/11's kernel: the Kajiya–Kay specular lobe (:func:`hairlut.kernels.specular_cos`)
    at the shifted tangent t̃ = unit(t + shift·n): (..., L) for lights l (L, 3); the sines from cross products (the
    lobe's edge at t̃ ∥ l or t̃ ∥ v, ``hairlut.kernels``)."""
    tt = _unit(t + shift * n)
    cl, sl = _dot(tt, l), sin_between(tt[..., None, :], l)
    cv, sv = _dot(tt, v)[..., None], sin_between(tt, v)[..., None]
    return specular_cos(cl, cv, p, sl, sv)


@partial(jax.jit, static_argnames=("use_diffuse", "primary", "secondary", "noise"))
def lighting_kernel(
    t, n, v, lights, light_rgb, noise_map, mat, colours, *, use_diffuse=True, primary=True, secondary=True, noise=False
):
    """Eq 8 per texel and light: (..., L, 3).

    ``mat`` = (kd, ks_I, ks_II, p_I, p_II, shift, diffuse_scale, diffuse_bias, noise_amount);
    ``colours`` (3, 3) = f_dif, f_speI, f_speII; ``noise_map`` (...) in [0, 1].
    """
    kd, ks1, ks2, p1, p2, s, scale, bias, amount = (mat[i] for i in range(9))
    out = jnp.zeros(t.shape[:-1] + (lights.shape[0], 3), t.dtype)
    if use_diffuse:
        out = out + kd * diffuse(t, lights, scale, bias)[..., None] * colours[0]
    if primary:
        out = out + ks1 * specular(t, n, v, lights, s, p1)[..., None] * colours[1]
    if secondary:
        term = ks2 * specular(t, n, v, lights, -s, p2)
        if noise:
            term = term * (1.0 - amount * noise_map)[..., None]
        out = out + term[..., None] * colours[2]
    return out * light_rgb


def _outer(x, op, start):
    """[op over x[m] for m > k] for every k along axis 0 (K small: unrolled; layer K − 1 outermost)."""
    out, acc = [], start
    for k in range(x.shape[0] - 1, -1, -1):
        out.append(acc)
        acc = op(acc, x[k])
    return jnp.stack(out[::-1]), acc


def shadow_map(alpha, k_shadow, linear: bool = False):
    """Eq 12: τ_k from α-maps (K, ...) with layer K − 1 outermost; exp form or its linear form."""
    alpha = jnp.asarray(alpha)
    outer, _ = _outer(alpha, jnp.add, jnp.zeros_like(alpha[0]))  # Σ_{m > k} α_m
    if linear:
        return jnp.clip(1.0 - k_shadow * outer, 0.0, 1.0)
    return jnp.exp(-k_shadow * outer)


def shade(lighting, re, tau):
    """Eq 13: Ψ_k = τ_k · Σ_lights Ψ^lighting · re; lighting (K, ..., L, 3), re (K, L, ...), τ (K, ...) → (K, ..., 3)."""
    lighting, re = jnp.asarray(lighting), jnp.asarray(re)
    total = sum(lighting[..., j, :] * re[:, j, ..., None] for j in range(re.shape[1]))
    return jnp.asarray(tau)[..., None] * total


def shade_lights(lighting, re, transmittance):
    """Eq 13 with one τ per light: Ψ_k = Σ_j T_j · Ψ^lighting_j · re_j; lighting (K, ..., L, 3), re (K, L, ...),
    T (K, ..., L) → (K, ..., 3)."""
    lighting, re, tr = jnp.asarray(lighting), jnp.asarray(re), jnp.asarray(transmittance)
    return sum(tr[..., j, None] * lighting[..., j, :] * re[:, j, ..., None] for j in range(re.shape[1]))


def blend(rgb, alpha, background):
    """Eq 14 over the background: rgb (K, ..., 3), α (K, ...) → composite RGB (..., 3) and alpha (...)."""
    rgb, alpha = jnp.asarray(rgb), jnp.asarray(alpha)
    above, through = _outer(1.0 - alpha, jnp.multiply, jnp.ones_like(alpha[0]))  # Π_{j > k} (1 − α_j), Π_k
    w = (alpha * above)[..., None]
    out = jnp.asarray(background) * through[..., None] + sum(rgb[k] * w[k] for k in range(rgb.shape[0]))
    return out, 1.0 - through


def _compose(lighting, re, alpha, k_shadow, background, shadow, linear, extra=None, transmittance=None):
    if transmittance is not None:  # one τ per (texel, light) from a light-space method
        tau = transmittance
        rgb = shade_lights(lighting, re, transmittance)
    else:
        tau = shadow_map(alpha, k_shadow, linear) if shadow else jnp.ones_like(alpha)
        rgb = shade(lighting, re, tau)
    if extra is not None:  # light that does not pass through the SATF (the environment term)
        rgb = rgb + extra
    final, a = blend(rgb, alpha, background)
    return tau, rgb, final, a


@partial(jax.jit, static_argnames=("shadow", "linear"))
def compose_kernel(lighting, re, alpha, k_shadow, background, *, shadow=True, linear=False):
    """Eqs 12–14 for one cluster: returns (τ (K, ...), shaded RGB (K, ..., 3), final RGB, final A)."""
    return _compose(lighting, re, alpha, k_shadow, background, shadow, linear)


@partial(jax.jit, static_argnames=("shadow", "linear"))
def compose_clusters_kernel(
    lighting, re, alpha, k_shadow, background, extra=None, transmittance=None, *, shadow=True, linear=False
):
    """:func:`compose_kernel` over a leading cluster axis (every input gains it); ``extra``
    (C, K, ..., 3), when given, is added to each layer's shaded colour before blending;
    ``transmittance`` (C, K, ..., L), when given, replaces eq 12's τ by one τ per light
    (:func:`shade_lights`) and is returned as τ."""
    return jax.vmap(lambda li, r, a, e, tr: _compose(li, r, a, k_shadow, background, shadow, linear, e, tr))(
        lighting, re, alpha, extra, transmittance
    )


def value_noise(shape, frequency: float, seed: int) -> np.ndarray:
    """Smooth value noise in [0, 1] on a (n_t, n_u) texture, periodic in u (Scheuermann's noise texture)."""
    n_t, n_u = shape
    rng = np.random.default_rng(seed)
    cells = max(1, int(round(frequency)))
    lattice = rng.uniform(size=(cells + 1, cells))
    gu = (np.arange(n_u) + 0.5) / n_u * cells
    gt = (np.arange(n_t) + 0.5) / n_t * cells
    iu, it = np.floor(gu).astype(int), np.minimum(np.floor(gt).astype(int), cells - 1)
    fu, ft = gu - iu, gt - it
    su, st = fu * fu * (3 - 2 * fu), ft * ft * (3 - 2 * ft)
    l00 = lattice[it][:, iu % cells]
    l01 = lattice[it][:, (iu + 1) % cells]
    l10 = lattice[it + 1][:, iu % cells]
    l11 = lattice[it + 1][:, (iu + 1) % cells]
    top = l00 + (l01 - l00) * su[None, :]
    bot = l10 + (l11 - l10) * su[None, :]
    return top + (bot - top) * st[:, None]
