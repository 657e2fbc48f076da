"""Part ``sh``: the SH convolution tables (xing §4), bake and per-vertex radiance.

Bake: the paper's cube-map quadrature of the convolution integrals (ω on n × n × 6 texels, the
paper's own n = 7) against hairlut's exact Legendre–Gaunt form, both at the paper's grid (t on
cube texel centres, θ′ in steps of π/8, p = 49, 64 light and 9 transmittance coefficients);
error: max |ΔR| over Rd and Rs against ``hairlut.shtables.reference_r`` (direct quadrature split
at the kernel's kinks, independent of both).  Radiance: I = Σ_j b_j (Kd Cd + Ks Cs) at random
(t, θ′) from dense Cd/Cs grids (the shader's way: bilinear on the cube face, linear in θ′; the
paper's grid is 7 × 7 × 6 and 9 θ′) against the exact contracted form in float64, and the exact
form evaluated in float32.
"""

from __future__ import annotations

import functools
import time

import jax
import jax.numpy as jnp
import numpy as np

from ._figure import Figure
from ._parts import Context, timed

P = 49.0
HIGHEST = jax.lax.Precision.HIGHEST
PART = "sh"

_FACE_AXES = np.array(
    [  # (major, sc, tc) per cube face, as in hairlut.envlight
        [[1, 0, 0], [0, 0, -1], [0, -1, 0]],
        [[-1, 0, 0], [0, 0, 1], [0, -1, 0]],
        [[0, 1, 0], [1, 0, 0], [0, 0, 1]],
        [[0, -1, 0], [1, 0, 0], [0, 0, -1]],
        [[0, 0, 1], [1, 0, 0], [0, -1, 0]],
        [[0, 0, -1], [-1, 0, 0], [0, -1, 0]],
    ],
    np.float64,
)


@functools.partial(jax.jit, static_argnames=("n",))
def dense_radiance(t, tv, b, cd, cs, kd, ks, *, n: int):
    """Radiance from dense tables, the shader's way: bilinear fetch of Cd/Cs (6n², …) on the tangent's
    cube face and linear in θ′ (cs: (6n², S, 9, C)), then Σ_j b_j (Kd Cd + Ks Cs) (xing eq 16)."""
    axis = jnp.argmax(jnp.abs(t), axis=-1)
    major = jnp.take_along_axis(t, axis[:, None], 1)[:, 0]
    face = 2 * axis + (major < 0)
    fa = jnp.asarray(_FACE_AXES, t.dtype)[face]
    ma = jnp.abs(major)
    u = jnp.einsum("ni,ni->n", t, fa[:, 1], precision=HIGHEST) / ma
    v = jnp.einsum("ni,ni->n", t, fa[:, 2], precision=HIGHEST) / ma
    x = jnp.clip((u + 1) * n / 2 - 0.5, 0, n - 1)
    y = jnp.clip((v + 1) * n / 2 - 0.5, 0, n - 1)
    x0, y0 = jnp.floor(x).astype(jnp.int32), jnp.floor(y).astype(jnp.int32)
    x1, y1 = jnp.minimum(x0 + 1, n - 1), jnp.minimum(y0 + 1, n - 1)
    fx, fy = x - x0, y - y0
    base = face * n * n
    steps = cs.shape[1] - 1
    q = jnp.clip(tv / jnp.pi * steps, 0, steps)
    q0 = jnp.clip(jnp.floor(q).astype(jnp.int32), 0, steps - 1)
    fq = q - q0
    out = 0.0
    for i, w in (
        (base + y0 * n + x0, (1 - fx) * (1 - fy)),
        (base + y0 * n + x1, fx * (1 - fy)),
        (base + y1 * n + x0, (1 - fx) * fy),
        (base + y1 * n + x1, fx * fy),
    ):
        c_s = cs[i, q0] * (1 - fq)[:, None, None] + cs[i, q0 + 1] * fq[:, None, None]
        out = out + w[:, None] * jnp.einsum("nj,njc->nc", b, kd * cd[i] + ks * c_s, precision=HIGHEST)
    return out


def _max_err(a, b) -> float:
    return float(np.abs(np.asarray(a, np.float64) - b).max())


def bake_figures(ctx: Context):
    from hairlut.envlight import cube_dirs
    from hairlut.sh import gaunt_quadrature
    from hairlut.shtables import bake_compact, paper_tables, reference_r, resolve_recipe

    t_all, _ = cube_dirs(7)
    t_dirs = t_all[:: 98 if ctx.quick else 7]
    theta_v = np.linspace(0, np.pi, 3 if ctx.quick else 9)
    ref_d = np.stack([reference_r(t, 0.0, P, 2, 2, specular=False) for t in t_dirs])
    ref_s = np.stack([[reference_r(t, tv, P, 7, 2) for tv in theta_v] for t in t_dirs])
    ctx.note(
        PART,
        f"bake reference: reference_r at {len(t_dirs)} of the paper's 294 tangents × {len(theta_v)} θ′ "
        f"(max |Rd| {np.abs(ref_d).max():.3g}, max |Rs| {np.abs(ref_s).max():.3g}); error = max |ΔR| over Rd and Rs",
    )

    def err(rd, rs):
        return max(_max_err(rd, ref_d), _max_err(rs, ref_s))

    figs = []
    for n in (7, 16) if ctx.quick else (7, 16, 32, 64):
        paper_tables(n, t_dirs, theta_v, P, 2, 7, 2)  # compile
        sec, (rd, rs) = timed(lambda: paper_tables(n, t_dirs, theta_v, P, 2, 7, 2), repeat=3)
        figs.append(
            Figure(
                PART,
                "bake: Rd, Rs against the split quadrature",
                f"paper quadrature ω {n}²×6",
                sec,
                err(rd, rs),
                "max |ΔR|",
                {"omega_n": n},
                baseline=n == 7,
                paper=n == 7,
            )
        )
    recipe = resolve_recipe({"kernel": {"p": P}, "bands": {"light_specular": 8}})

    def exact():
        gaunt_quadrature(9, 7, 2)  # uncached: the Gaunt tensor is part of the bake
        tables, _ = bake_compact(recipe)
        return tables, np.asarray(tables.rd(t_dirs)), np.asarray(tables.rs(t_dirs[:, None, :], theta_v[None, :]))

    first = time.perf_counter()
    exact()
    first = time.perf_counter() - first
    sec, (tables, rd, rs) = timed(exact, repeat=1 if ctx.quick else 3)
    figs.append(
        Figure(
            PART,
            "bake: Rd, Rs against the split quadrature",
            "hairlut Legendre–Gaunt (exact)",
            sec,
            err(rd, rs),
            "max |ΔR|",
            {"precision": "float64"},
            extra={"first_call_s": first},
        )
    )
    for dtype in ("float32", "float16"):
        figs.append(
            Figure(
                PART,
                "bake: Rd, Rs against the split quadrature",
                f"exact, stored as {dtype}",
                None,
                err(rd.astype(dtype), rs.astype(dtype)),
                "max |ΔR|",
                {"storage": dtype},
            )
        )
    return figs, tables


def radiance_inputs(n_vert: int, seed: int = 0):
    """Random per-vertex inputs of the radiance benchmark: unit tangents t (N, 3), θ′ (N,) in [0, π],
    transmittance coefficients b (N, 9) decaying with the band, and an RGB light a (64, 3) with a
    strong constant term."""
    rng = np.random.default_rng(seed)
    t = rng.normal(size=(n_vert, 3))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    tv = rng.uniform(0, np.pi, n_vert)
    b = rng.normal(size=(n_vert, 9)) * np.array([1, 0.3, 0.3, 0.3, 0.1, 0.1, 0.1, 0.1, 0.1])
    a = rng.normal(size=(64, 3)) * 0.5
    a[0] += 3.0
    return t, tv, b, a


def radiance_figures(ctx: Context, tables) -> list[Figure]:
    from hairlut.envlight import cube_dirs

    n_vert = 20_000 if ctx.quick else 1_000_000
    t, tv, b, a = radiance_inputs(n_vert)
    c = tables.contract(a)
    update, _ = timed(lambda: jax.block_until_ready(tables.contract(a + 0.01).hs), repeat=20)
    exact = np.asarray(c.radiance(b, t, tv, 0.6, 0.4))
    scale = float(np.abs(exact).max())
    table = "radiance: per-vertex I against the exact form"
    figs = []
    sec, _ = timed(lambda: jax.block_until_ready(c.radiance(b, t, tv, 0.6, 0.4)), repeat=3)
    figs.append(Figure(PART, table, "exact form in float64 (the truth)", sec, None, "max rel |ΔI|", {"precision": "float64"}))
    c.radiance(b, t, tv, 0.6, 0.4, dtype="float32")
    sec, fast = timed(lambda: jax.block_until_ready(c.radiance(b, t, tv, 0.6, 0.4, dtype="float32")), repeat=3)
    figs.append(
        Figure(PART, table, "exact form in float32", sec, _max_err(fast, exact) / scale, "max rel |ΔI|", {"precision": "float32"})
    )
    for n, steps in [(7, 9), (16, 17)] if ctx.quick else [(7, 9), (16, 9), (16, 17), (32, 33), (64, 65)]:
        dirs, _ = cube_dirs(n)
        thetas = np.linspace(0.0, np.pi, steps)
        cd = np.asarray(c.cd(dirs))
        cs = np.asarray(c.cs(dirs[:, None, :], thetas[None, :]))
        args = tuple(jnp.asarray(x) for x in (t, tv, b, cd, cs))
        dense_radiance(*args, 0.6, 0.4, n=n)
        sec, got = timed(lambda: jax.block_until_ready(dense_radiance(*args, 0.6, 0.4, n=n)), repeat=3)
        paper = (n, steps) == (7, 9)
        figs.append(
            Figure(
                PART,
                table,
                f"dense {n}²×6, {steps} θ′, interpolated",
                sec,
                _max_err(got, exact) / scale,
                "max rel |ΔI|",
                {"t_resolution": n, "theta_v_steps": steps},
                baseline=paper,
                paper=paper,
            )
        )
    ctx.note(
        PART,
        f"radiance: {n_vert:,} random (t, θ′), RGB, p = {P:g}, from one light's contracted tables; "
        f"error relative to max |I| = {scale:.3g}; dense tables in float64; a light update (new light "
        f"coefficients to contracted tables ready) takes {1e3 * update:.2f} ms",
    )
    return figs


def sh_radiance_figures(ctx: Context) -> list[Figure]:
    """The sh part's radiance table alone (no bake reference): the compact tables baked at the paper's p and
    light bands, then per-vertex I from dense tables against the exact form (what a GPU run is asked for)."""
    from hairlut.shtables import bake_compact, resolve_recipe

    with jax.enable_x64(True):
        tables, _ = bake_compact(resolve_recipe({"kernel": {"p": P}, "bands": {"light_specular": 8}}))
        return radiance_figures(ctx, tables)


def run(ctx: Context) -> list[Figure]:
    with jax.enable_x64(True):
        figs, tables = bake_figures(ctx)
        return figs + radiance_figures(ctx, tables)
