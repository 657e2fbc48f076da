"""Precision is declared, never inherited (issue 15, item 1).

XLA runs float32 matrix products and contractions in TF32 on recent NVIDIA GPUs unless the
program says otherwise, which cost 5 tests their tolerances on an H200.  Every JAX
contraction in hairlut therefore states its precision, and this file proves it on the CPU:

* :data:`KERNELS` lists every jitted kernel of the package with small abstract arguments
  (``jax.ShapeDtypeStruct``: tracing only, nothing is compiled or run).  Each is traced with
  ``.trace(...)`` and every ``dot_general`` (and convolution) equation of its jaxpr, nested
  jaxprs included (vmap, scan, map, while, cond, inner jits, custom derivatives), must carry
  ``precision=(HIGHEST, HIGHEST)``.
* A guard walks every module of the package and fails when a jitted callable exists that
  :data:`KERNELS` does not list (or :data:`NOT_KERNELS` does not explain), so a new kernel
  cannot arrive uncovered; a second guard reads the source for ``jax.jit`` so that jit
  wrappers the walk cannot see (closures, factories) are explained too.
* A source check covers the contractions outside jit (eager ``jnp.einsum`` on device arrays
  is subject to the same TF32 default): every ``jnp``/``lax`` contraction call in hairlut
  names a ``precision=``.
* The checker itself is shown to fail on a default-precision dot, so the tests can fail.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import jax
import jax.extend.core
import jax.numpy as jnp
import numpy as np
import pytest

import hairlut

ROOT = Path(hairlut.__file__).resolve().parent
HIGHEST = jax.lax.Precision.HIGHEST
f32, f64, i32 = jnp.float32, jnp.float64, jnp.int32
_CONTRACTIONS = ("dot_general", "conv_general_dilated")


def A(*shape, dtype=f32):
    """An abstract argument: shape and dtype only."""
    return jax.ShapeDtypeStruct(tuple(shape), dtype)


# ----------------------------------------------------------------------------- the checker


def _subjaxprs(value):
    if isinstance(value, jax.extend.core.ClosedJaxpr):
        yield value.jaxpr
    elif isinstance(value, jax.extend.core.Jaxpr):
        yield value
    elif isinstance(value, (tuple, list)):
        for v in value:
            yield from _subjaxprs(v)


def contractions(jaxpr):
    """Every (primitive name, precision) of the contractions in a jaxpr and the jaxprs nested in it."""
    jaxpr = getattr(jaxpr, "jaxpr", jaxpr)
    out = []
    for eqn in jaxpr.eqns:
        if eqn.primitive.name in _CONTRACTIONS:
            out.append((eqn.primitive.name, eqn.params.get("precision"), eqn.params.get("preferred_element_type")))
        for v in eqn.params.values():
            for sub in _subjaxprs(v):
                out.extend(contractions(sub))
    return out


def undeclared(jaxpr) -> list[str]:
    """The contractions whose precision is not HIGHEST on both operands."""
    bad = []
    for name, prec, _ in contractions(jaxpr):
        if not (isinstance(prec, tuple) and len(prec) == 2 and all(p == HIGHEST for p in prec)):
            bad.append(f"{name} precision={prec}")
    return bad


# ----------------------------------------------------------------------------- the kernels
#
# name -> (x64?, builder returning (args, kwargs)).  Sizes are small and arbitrary but legal:
# the static arguments pick the code paths the package uses (shadows, smoothing, specular ...).


def _map_index(C=1, s_t=2, G=2, s_u=2, K=2, n_t=4, n_u=4, k=3, neighbours=True):
    from hairlut.synth import MapIndex

    S, H = C * (s_t + 1) * G * s_u, C * s_t * G * s_u
    kk = k if neighbours else 1
    return MapIndex(
        A(2, S, 3),
        A(S, kk, dtype=i32),
        A(S, kk),
        A(H),
        A(H, kk, dtype=i32),
        A(H, kk),
        A(n_t),
        A(2, 2, C, K, n_t, n_u),
        (C, s_t, G, s_u),
        K,
        tuple(i * s_t // n_t for i in range(n_t)),
        tuple(j * s_u // n_u for j in range(n_u)),
    )


def _sweep_tables(kind: str):
    """Real cluster tables (the sweep kernels take dicts of spline pieces; their keys come from the package)."""
    from hairlut.geometry import ClusterGeometry, ClusterSpec
    from hairlut.geometry import sweep as sw

    spec = ClusterSpec(
        [[0.0, 1.0, 0.0], [0.05, 0.5, 0.1], [0.1, 0.0, 0.1], [0.1, -0.5, 0.2]], [0.3, 0.5, 0.4], [0.2, 0.3], [0.0, 1.0]
    )
    geom = ClusterGeometry([spec])

    def abstract(tree):
        return jax.tree_util.tree_map(lambda x: A(*np.shape(x), dtype=np.asarray(x).dtype), tree)

    if kind == "arc":
        return (abstract({k: v for k, v in geom.batch.arrays().items()}),), {}
    blk = geom._blocks[0]
    if kind == "build":
        return (
            abstract({k: v for k, v in blk.items() if k not in ("frame_x", "frame_tangent", "frame_ref", "min_speed")}),
            8,
        ), {}
    assert sw
    return (abstract(blk), A(len(next(iter(blk.values()))), 64, dtype=f64)), {}


def _tracer_args(shadow):
    return (A(2, 8, 8), A(2, 11), A(4), A(3), A(4)), dict(n_pix=8, n_steps=16, rays=2, shadow=shadow, smooth=True, chunk=1)


def _direct_args(shadow, shade=True):
    return (A(4, 8, 8), A(4, 11), A(4), A(4, 3), A(4)), dict(
        n_pix=8, n_steps=16, rays=1, shadow=shadow, smooth=True, block=2, shade=shade
    )


def _shading_inputs(C=2, K=2, n_t=4, n_u=4, L=2):
    tex = (C, K, n_t, n_u)
    return tex, L


def _shade_kernel_args(transmittance):
    (C, K, n_t, n_u), L = _shading_inputs()
    args = (
        A(C, K, L, n_t, n_u),
        A(C, K, n_t, n_u),
        A(C, K, n_t, n_u, 3),
        A(C, K, n_t, n_u, 3),
        A(C, K, n_t, n_u),
        A(3),
        A(L, 3),
        A(L, 3),
        A(9),
        A(3, 3),
        A(),
        A(3),
        A(C, K, n_t, n_u, 3),
        A(C, K, n_t, n_u, L) if transmittance else None,
    )
    return args, dict(effects=(True, True, True, True, True), linear=False)


def _compose_clusters_args(transmittance):
    (C, K, n_t, n_u), L = _shading_inputs()
    args = (
        A(C, K, n_t, n_u, L, 3),
        A(C, K, L, n_t, n_u),
        A(C, K, n_t, n_u),
        A(),
        A(3),
        A(C, K, n_t, n_u, 3),
        A(C, K, n_t, n_u, L) if transmittance else None,
    )
    return args, dict(shadow=True, linear=False)


def _hair_args(wi: bool):
    """Hair BSDF kernels: wo, wi or u, h, sigma_a (channels last), beta_m, beta_n, alpha, eta."""
    return (
        A(5, 3, dtype=f64),
        A(5, 3 if wi else 4, dtype=f64),
        A(5, dtype=f64),
        A(5, 3, dtype=f64),
        A(5, dtype=f64),
        A(5, dtype=f64),
        A(dtype=f64),
        A(dtype=f64),
    ), {}


KERNELS = {
    # bench
    "hairlut.bench._sh:dense_radiance": [
        (
            True,
            lambda: (
                (
                    A(5, 3, dtype=f64),
                    A(5, dtype=f64),
                    A(5, 9, dtype=f64),
                    A(24, 9, 3, dtype=f64),
                    A(24, 4, 9, 3, dtype=f64),
                    0.6,
                    0.4,
                ),
                dict(n=2),
            ),
        )
    ],
    # hair BSDF (issue 28)
    "hairlut.hairbsdf._bsdf:lobes_kernel": [(True, lambda: _hair_args(wi=True))],
    "hairlut.hairbsdf._bsdf:pdf_kernel": [(True, lambda: _hair_args(wi=True))],
    "hairlut.hairbsdf._bsdf:sample_kernel": [(True, lambda: _hair_args(wi=False))],
    "hairlut.hairbsdf._energy:bsdf_row_kernel": [
        (True, lambda: ((A(dtype=f64), A(4, dtype=f64), A(4, 3, dtype=f64), A(dtype=f64), A(dtype=f64)), dict(m=4, levels=2)))
    ],
    "hairlut.hairbsdf._energy:bsdf_point_kernel": [
        (True, lambda: ((A(3, dtype=f64), A(3, dtype=f64), A(3, dtype=f64), A(dtype=f64), A(dtype=f64)), dict(m=4, levels=2)))
    ],
    "hairlut.hairbsdf._coverage:coverage_row_kernel": [(True, lambda: ((A(dtype=f64), A(5, dtype=f64)), dict(m=4)))],
    "hairlut.hairbsdf._energy:furnace_kernel": [
        (True, lambda: (tuple(A(3, dtype=f64) for _ in range(5)) + (A(dtype=f64), A(dtype=f64)), dict(m=4)))
    ],
    "hairlut.hairbsdf._montecarlo:montecarlo_row_kernel": [
        (
            True,
            lambda: (
                (
                    A(dtype=f64),
                    A(4, dtype=f64),
                    A(4, 3, dtype=f64),
                    A(4, dtype=jnp.int64),
                    A(4, dtype=jnp.int64),
                    A(1024, 2, dtype=f64),
                    A(1024, dtype=f64),
                    A(dtype=f64),
                    A(dtype=f64),
                ),
                dict(block=64),
            ),
        )
    ],
    "hairlut.hairbsdf._montecarlo:montecarlo_coverage_kernel": [
        (True, lambda: ((A(2, dtype=jnp.uint32), A(dtype=f64), A(5, dtype=f64)), dict(trials=8, strands=4)))
    ],
    # geometry
    "hairlut.geometry.density:density_kernel": [
        (False, lambda: ((A(3, 8, 2), A(3, 8, 2), A(3, 8), A(3, 8, dtype=bool), A(3), A(3, 2), 1.0), dict(n_s=8, n_r=8))),
        (
            True,
            lambda: (
                (
                    A(3, 8, 2, dtype=f64),
                    A(3, 8, 2, dtype=f64),
                    A(3, 8, dtype=f64),
                    A(3, 8, dtype=bool),
                    A(3, dtype=f64),
                    A(3, 2, dtype=f64),
                    1.0,
                ),
                dict(n_s=8, n_r=8),
            ),
        ),
    ],
    "hairlut.geometry.features:_moments": [(False, lambda: ((A(3, 8, 8), A(3, 8)), {}))],
    "hairlut.geometry.sweep:_arc": [(True, lambda: _sweep_tables("arc"))],
    "hairlut.geometry.sweep:_build": [(True, lambda: _sweep_tables("build"))],
    "hairlut.geometry.sweep:_sections": [(True, lambda: _sweep_tables("sections"))],
    # HRIR database
    "hairlut.hrir._query:neighbours_kernel": [(False, lambda: ((A(10, 3), A(24, 3)), dict(k=4)))],
    "hairlut.hrir._query:_interpolate_kernel": [
        (False, lambda: ((A(10, 4, dtype=i32), A(10, 4), A(10), A(10), A(24, 8, 16), A(24, 8, 8, 16)), {}))
    ],
    "hairlut.hrir._tracer:trace_kernel": [(False, lambda: _tracer_args(False)), (False, lambda: _tracer_args(True))],
    "hairlut.hrir._projection:projection_kernel": [
        (False, lambda: ((A(4, 8, 8), A(4, 11)), dict(directions=2, bins=4, sub=2, n_steps=8, block=2)))
    ],
    # renderers
    "hairlut.render._raster:raster_kernel": [
        (
            False,
            lambda: (
                (A(2, 2, 9, 3), A(2, 2, 4, 4, 4), A(2, 2, dtype=i32), A(8, 2, 3, dtype=i32), A(9, 2), A(4, 4), A(3), A(3)),
                dict(size=(16, 12), tile=(8, 8), cap=64),
            ),
        )
    ],
    "hairlut.render._fragments:surface_kernel": [
        (
            False,
            lambda: (
                (A(2, 2, 9, 3), A(2, 2, dtype=i32), A(8, 2, 3, dtype=i32), A(9, 2), A(4, 4), A(3), A(3)),
                dict(size=(16, 12), tile=(8, 8), cap=64),
            ),
        )
    ],
    "hairlut.render._fragments:_cells_of": [(False, lambda: ((A(20), A(20), A(20, dtype=i32)), dict(n_t=4, n_u=5)))],
    "hairlut.render._fragments:composite_kernel": [
        (False, lambda: ((A(2, 2, 4, 5, 4), A(20, dtype=i32), A(20, 2), A(192, dtype=i32)), dict(slabs=(10, 6, 4))))
    ],
    "hairlut.render._hits:hit_kernel": [
        (False, lambda: ((A(6, 3), A(6, 3), A(9, dtype=i32), A(9, dtype=i32), A(7, 3), A(7, 3), A(7), A(7), A(7), 0.0), {}))
    ],
    "hairlut.render._light:shadow_kernel": [
        (False, lambda: ((A(2, 3), A(3), A(2, 5, dtype=i32), A(), A(7, 3), A(7, 3), A(7), A(7), A(7)), dict(depth=4)))
    ],
    "hairlut.render._strand_march:camera_rays": [
        (False, lambda: ((A(2, 2, dtype=i32), A(6, 3)), dict(tile=4, ss=2, perspective=p))) for p in (True, False)
    ],
    "hairlut.render._strand_march:strand_march_kernel": [
        (False, lambda: ((A(4, 15), A(4, 15), A(4, 15, dtype=i32), A(4, 3), A(3), A(7, 2, 3), A(4, 15, 2)), dict(perspective=p)))
        for p in (True, False)
    ],
    "hairlut.render._strand_march:step_points": [
        (
            False,
            lambda: ((A(4, 3), A(4, 3), A(4, 5, dtype=i32), A(7, 3), A(7, 3), A(7), A(7), A(7)), dict(steps=3, perspective=p)),
        )
        for p in (True, False)
    ],
    # scene tables
    "hairlut.scenemaps._fetch:fetch_kernel": [
        (False, lambda: ((A(5, 4, 16), A(5, 8, 4, 5), A(3, dtype=i32), A(3), A(3, 2)), dict(shade=True)))
    ],
    "hairlut.scenemaps._fetch:index_kernel": [(False, lambda: ((A(3, dtype=i32), A(3)), dict(half=4, views=8)))],
    "hairlut.scenemaps._fetch:terms_kernel": [
        (
            False,
            lambda: (
                (
                    A(5, 4, 16),
                    A(5, 8, 4, 5),
                    {k: A(3, dtype=i32) for k in ("ia0", "ia1", "ic0", "ic1")}
                    | {k: A(3, dtype=bool) for k in ("mirror0", "mirror1", "live")}
                    | {"w": A(3), "u": A(3)},
                    A(3),
                    A(3, 2),
                ),
                {},
            ),
        )
    ],
    # spherical harmonics
    "hairlut.sh._basis:real_sh_kernel": [
        (False, lambda: ((A(10, 3),), dict(lmax=4))),
        (True, lambda: ((A(10, 3, dtype=f64),), dict(lmax=4))),
    ],
    "hairlut.sh._quadrature:_project_kernel": [(False, lambda: ((A(3, 50), A(50, 9)), {}))],
    "hairlut.sh._quadrature:_evaluate_kernel": [(False, lambda: ((A(9), A(10, 3)), {}))],
    # shadows
    "hairlut.shadows._light_oriented:_map_kernel": [
        (
            True,
            lambda: (
                (A(20, 3, dtype=f64), A(20, 3, dtype=f64), A(3, 3, dtype=f64), A(3, dtype=f64), 0.1, 1.0),
                dict(shape=(4, 5, 6), n_sub=2),
            ),
        )
    ],
    "hairlut.shadows._light_oriented:_query_kernel": [(True, lambda: ((A(4, 5, 6, dtype=f64), A(9, 3, dtype=f64)), {}))],
    "hairlut.shadows._opacity:_build": [
        (
            True,
            lambda: (
                (
                    A(20, 3, dtype=f64),
                    A(20, 3, dtype=f64),
                    A(20, dtype=f64),
                    A(20, dtype=jnp.int64),
                    A(3, 3, dtype=f64),
                    A(3, dtype=f64),
                    0.1,
                    0.0,
                    0.1,
                ),
                dict(shape=(4, 5, 6), total=64),
            ),
        )
    ],
    "hairlut.shadows._opacity:_lookup": [
        (True, lambda: ((A(9, 3, dtype=f64), A(4, 5, 6, dtype=f64), A(3, 3, dtype=f64), A(3, dtype=f64), 0.1, 0.0, 0.1), {}))
    ],
    "hairlut.shadows._transmittance:_cast_kernel": [
        (
            True,
            lambda: (
                (
                    A(7, 3, dtype=f64),
                    A(30, 3, dtype=f64),
                    A(30, dtype=f64),
                    A(30, 9, dtype=f64),
                    A(6, 6, 6, dtype=f64),
                    A(6, 6, 6, 3, dtype=f64),
                    0.5,
                    6.0,
                    1.0,
                ),
                dict(n_steps=8),
            ),
        )
    ],
    # SH convolution tables
    "hairlut.shtables._bake:_zonal_kernel": [
        (True, lambda: ((A(dtype=f64), A(9, dtype=f64)), dict(lmax_d=4, lmax_s=4, n_d=16, n_s=32)))
    ],
    "hairlut.shtables._paper:_quadrature": [
        (
            True,
            lambda: (
                (A(5, 3, dtype=f64), A(4, dtype=f64), A(40, 3, dtype=f64), A(40, dtype=f64), A(dtype=f64)),
                dict(lmax_i=2, lmax_j=2, specular=s),
            ),
        )
        for s in (False, True)
    ],
    "hairlut.shtables._tables:_rd_kernel": [
        (True, lambda: ((A(5, 3, dtype=f64), A(16, dtype=f64), A(16, 9, 4, dtype=f64)), dict(lmax=3)))
    ],
    "hairlut.shtables._tables:_rs_kernel": [
        (
            True,
            lambda: (
                (
                    A(5, 3, dtype=f64),
                    A(5, dtype=f64),
                    A(12, 4, dtype=f64),
                    A(16, 9, 4, dtype=f64),
                ),
                dict(lmax=3, l_of_k=A(16, dtype=i32)),
            ),
        )
    ],
    "hairlut.shtables._tables:_radiance_kernel": [
        (
            True,
            lambda dt=dt: (
                (
                    A(5, 3, dtype=dt),
                    A(5, dtype=dt),
                    A(5, 4, dtype=dt),
                    A(5, dtype=dt),
                    A(5, dtype=dt),
                    A(16, dtype=dt),
                    A(16, 4, 3, dtype=dt),
                    A(12, 4, dtype=dt),
                    A(16, 4, 3, dtype=dt),
                    A(16, dtype=i32),
                ),
                dict(lmax_d=3, lmax_s=3),
            ),
        )
        for dt in (f64, f32)
    ],
    # online module
    "hairlut.march._direct:direct_kernel": [(False, lambda s=s: _direct_args(s)) for s in (False, "grid", "march")]
    + [(False, lambda: _direct_args("march", shade=False))],
    "hairlut.march._viewgrid:view_grid_kernel": [
        (
            False,
            lambda s=s: (
                (A(4, 8, 8), A(4, 11), A(2), A(3), A(4)),
                dict(n_pix=8, n_steps=16, rays=1, shadow=s, smooth=True, block=2),
            ),
        )
        for s in (False, True)
    ],
    "hairlut.march._viewgrid:bake_grid_kernel": [
        (
            False,
            lambda m=m, s=s: (
                (A(4, 8, 8), A(4, 11), A(m * m, 16) if m else A(1, 1), A(1), A(3), A(4)),
                dict(n_views=4, n_pix=8, n_steps=16, rays=1, m=m, shade_rays=0, shade_steps=0, shadow=s, smooth=True, bins=2),
            ),
        )
        for m in (0, 4)
        for s in (False, True)
    ],
    "hairlut.synth._view:params_kernel": [(False, lambda: ((_map_index(), A(3), A(2, 3), A()), dict(n_v=8, n_l=8)))],
    "hairlut.synth._view:fetch_kernel": [
        (
            False,
            lambda: (
                (
                    _map_index(),
                    A(24, 8, 16),
                    A(24, 8, 8, 16),
                    A(12),
                    A(12, 2),
                    A(8, dtype=bool),
                    A(4, dtype=i32),
                    (A(12, 2, 16), A(12, 16)),
                ),
                {},
            ),
        )
    ],
    "hairlut.synth._view:sweep_rows": [
        (False, lambda: ((_map_index(), A(12, 2, 16), A(12, 16), A(12, 2), A(8, dtype=bool), A(8, dtype=i32)), {}))
    ],
    "hairlut.synth._methods:scene_view_kernel": [
        (
            False,
            lambda: (
                (
                    _map_index(neighbours=False),
                    A(12, 16),
                    A(12, 2, 4),
                    A(12, 2),
                    A(1, 2, 4, 4, dtype=i32),
                    A(1, 2, 4, 4, dtype=i32),
                ),
                {},
            ),
        )
    ],
    "hairlut.synth._view:sweep_sectors": [
        (False, lambda: ((_map_index(neighbours=False), A(12, 16), A(12, 2, 16), A(12, 2)), {}))
    ],
    "hairlut.synth._maps:sweep_kernel": [
        (False, lambda: ((A(6, 2, 16), A(6, 2, 16), A(6, 16), A(6, 16), A(10, dtype=i32), A(10), A(10), A(10)), {}))
    ],
    "hairlut.synth._shading:lighting_kernel": [
        (
            False,
            lambda: (
                (A(4, 4, 3), A(4, 4, 3), A(3), A(2, 3), A(2, 3), A(4, 4), A(9), A(3, 3)),
                dict(use_diffuse=True, primary=True, secondary=True, noise=True),
            ),
        )
    ],
    "hairlut.synth._shading:compose_kernel": [
        (False, lambda: ((A(2, 4, 4, 2, 3), A(2, 2, 4, 4), A(2, 4, 4), A(), A(3)), dict(shadow=True, linear=lin)))
        for lin in (False, True)
    ],
    "hairlut.synth._shading:compose_clusters_kernel": [(False, lambda tr=tr: _compose_clusters_args(tr)) for tr in (False, True)],
    "hairlut.synth._synth:shade_kernel": [(False, lambda tr=tr: _shade_kernel_args(tr)) for tr in (False, True)],
}

# Jitted callables that are not kernels of their own, and why they need no entry.
NOT_KERNELS = {
    "hairlut.bake.devices:_kernel": "jit(fn) of a caller's module-level kernel (hrir's trace_kernel, listed above)",
}


def _kernel(name: str):
    mod, attr = name.split(":")
    return getattr(importlib.import_module(mod), attr)


def _modules():
    yield hairlut
    for info in pkgutil.walk_packages(hairlut.__path__, "hairlut."):
        yield importlib.import_module(info.name)


def _is_jitted(obj) -> bool:
    return callable(obj) and hasattr(obj, "trace") and hasattr(obj, "lower") and hasattr(obj, "__wrapped__")


def jitted_in_package() -> set[str]:
    """module:name of every jitted callable defined at module level anywhere in hairlut."""
    found = set()
    for mod in _modules():
        for attr, obj in vars(mod).items():
            if _is_jitted(obj) and inspect.unwrap(obj).__module__ == mod.__name__:
                found.add(f"{mod.__name__}:{attr}")
    return found


CASES = [pytest.param(name, i, id=f"{name.split(':')[1]}[{i}]") for name, cases in KERNELS.items() for i in range(len(cases))]


@pytest.mark.parametrize(("name", "case"), CASES)
def test_every_contraction_of_the_kernel_is_highest(name, case):
    x64, build = KERNELS[name][case]
    fn = _kernel(name)
    with jax.enable_x64(x64):
        args, kwargs = build()
        traced = fn.trace(*args, **kwargs)
    found = contractions(traced.jaxpr)
    bad = undeclared(traced.jaxpr)
    assert not bad, f"{name} case {case}: {len(bad)} of {len(found)} contractions inherit the default precision: {bad}"


def test_every_jitted_callable_is_covered():
    found = jitted_in_package()
    missing = sorted(found - set(KERNELS) - set(NOT_KERNELS))
    assert not missing, f"jitted kernels with no precision case in tests/test_precision.py KERNELS: {missing}"
    stale = sorted((set(KERNELS) | set(NOT_KERNELS)) - found - {n for n in NOT_KERNELS if "devices" in n})
    assert not stale, f"KERNELS lists callables that are no longer jitted module-level names: {stale}"


_JIT_TEXT = re.compile(r"\bjax\.jit\b|\bjit\(|@jit\b|from jax import[^\n]*\bjit\b")


def test_every_jit_in_the_source_is_accounted_for():
    """Modules that mention jax.jit must hold only listed kernels (or explained wrappers): catches jit
    applied inside functions (closures, factories), which the module walk cannot see."""
    listed = {n.split(":")[0] for n in (*KERNELS, *NOT_KERNELS)}
    unexplained = []
    for path in sorted(ROOT.rglob("*.py")):
        code = "\n".join(line.split("#")[0] for line in path.read_text().splitlines())
        code = re.sub(r'"""[\s\S]*?"""', "", code)
        if not _JIT_TEXT.search(code):
            continue
        mod = ".".join(("hairlut", *path.relative_to(ROOT).with_suffix("").parts)).removesuffix(".__init__")
        if mod not in listed:
            unexplained.append(mod)
    assert not unexplained, f"modules that call jax.jit but have no entry in KERNELS / NOT_KERNELS: {unexplained}"


_CONTRACTION_CALLS = {
    "einsum",
    "dot",
    "matmul",
    "tensordot",
    "dot_general",
    "inner",
    "vdot",
    "conv_general_dilated",
    "conv",
    "convolve",
    "correlate",
    "multi_dot",
}
_JAX_NAMES = {"jnp", "lax", "jax"}


def _call_root(node) -> tuple[str, str] | None:
    """('jnp', 'einsum') for jnp.einsum(...), jax.numpy.einsum, jax.lax.dot_general, lax.dot(...)."""
    f = node.func
    if not isinstance(f, ast.Attribute) or f.attr not in _CONTRACTION_CALLS:
        return None
    base = f.value
    while isinstance(base, ast.Attribute):
        base = base.value
    return (base.id, f.attr) if isinstance(base, ast.Name) and base.id in _JAX_NAMES else None


def test_every_jax_contraction_call_names_its_precision():
    """Source check, in or out of jit: jnp/lax contraction calls pass ``precision=`` (eager device
    contractions take XLA's default too).  NumPy calls (np.einsum, host ``@``) are not affected."""
    missing = []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and (root := _call_root(node)):
                if not any(k.arg == "precision" for k in node.keywords):
                    missing.append(f"{path.relative_to(ROOT.parent)}:{node.lineno} {root[0]}.{root[1]}")
    assert not missing, "JAX contractions without precision=: " + ", ".join(missing)


# ----------------------------------------------------------------------------- the checker can fail


def test_the_checker_sees_a_default_precision_dot():
    @jax.jit
    def f(a, b):
        return jax.vmap(lambda x: x @ b)(a), jax.lax.map(lambda x: jnp.einsum("i,ij->j", x, b), a)

    traced = f.trace(A(3, 4), A(4, 5))
    assert len(contractions(traced.jaxpr)) == 2
    assert len(undeclared(traced.jaxpr)) == 2


def test_the_checker_accepts_declared_precision_either_way():
    @jax.jit
    def f(a, b):
        with jax.default_matmul_precision("highest"):
            c = a @ b
        return c, jnp.matmul(a, b, precision=HIGHEST), jnp.einsum("ij,jk->ik", a, b, precision=HIGHEST)

    traced = f.trace(A(3, 4), A(4, 5))
    assert len(contractions(traced.jaxpr)) == 3
    assert undeclared(traced.jaxpr) == []


def test_the_checker_rejects_high_or_mixed_precision():
    @jax.jit
    def f(a, b):
        return (
            jnp.matmul(a, b, precision=jax.lax.Precision.HIGH),
            jnp.matmul(a, b, precision=(HIGHEST, jax.lax.Precision.DEFAULT)),
        )

    assert len(undeclared(f.trace(A(3, 4), A(4, 5)).jaxpr)) == 2


def test_the_source_check_sees_a_bare_einsum():
    tree = ast.parse(
        "import jax.numpy as jnp\nx = jnp.einsum('i,i->', a, b)\ny = jax.lax.dot_general(a, b, d, "
        "precision=p)\nz = np.einsum('i,i->', a, b)\n"
    )
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and _call_root(n)]
    assert [(_call_root(n), any(k.arg == "precision" for k in n.keywords)) for n in calls] == [
        (("jnp", "einsum"), False),
        (("jax", "dot_general"), True),
    ]
