"""The maps part's online-frame study (satf §6, Table 1): index, maps, lighting, shadow and blend of a whole model.

:func:`ring_model` builds procedural clusters around a head-sized ring (the paper's human model by default: 17
clusters × 3 layers, s_t = 64, s_u = 16, 52K HSVs).  :func:`online_frame_study` prepares it once (strands,
sectors, features, texel frames and the SATF neighbours: the view-independent index), then times a frame after
jit warm-up with ``hairlut.synth.render_view`` and with :func:`numpy_frame`, a plain NumPy implementation of the same
steps (eq 7 sweep, eqs 8–11 lighting, eqs 12–14) through the reference lookup (``hairlut.synth.fetch``: a k-NN
search per query; every sector is fetched, not only those of non-uniform HSVs).  ``render``'s stages: "maps"
(eq 6, the SATF fetches and the eq 7 sweep) and "shade" (lighting, s-map, shading and blend).  Then the shadow
seam: the same frame for each ``[shadows] method``; the light-space maps are built once in ``prepare`` for the
scene's lights ("shadow build") and re-used each frame, and a frame with new lights rebuilds them ("relit frame").
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from ._parts import timed

#: The paper's human model (satf Table 1) and the quick run's smoke-sized one: clusters, s_t, s_u, texels per
#: layer side, strands per cluster.
PAPER_MODEL = {"clusters": 17, "s_t": 64, "s_u": 16, "res": 64, "strands": 400}
QUICK_MODEL = {"clusters": 2, "s_t": 16, "s_u": 16, "res": 32, "strands": 100}


def ring_model(n_clusters: int, s_t: int, s_u: int, res: int, strands: int, shadows: str = "smap") -> dict:
    """A scene document of ``n_clusters`` procedural clusters around a head-sized ring, each with ``s_t`` × ``s_u``
    HSVs per layer, ``res``² texels per layer, ``strands`` strands per cluster and the ``shadows`` method."""
    clusters = []
    for c in range(n_clusters):
        a = 2 * np.pi * c / n_clusters
        root = [0.1 * np.cos(a), 0.1, 0.1 * np.sin(a)]
        mid = [0.13 * np.cos(a), -0.05, 0.13 * np.sin(a)]
        tip = [0.12 * np.cos(a + 0.2), -0.25, 0.12 * np.sin(a + 0.2)]
        clusters.append(
            {
                "trajectory": [root, mid, tip],
                "half_axis_a": 0.02,
                "half_axis_b": 0.012,
                "twist": [0.0, 0.5],
                "s_t": s_t,
                "s_u": s_u,
            }
        )
    return {
        "render": {"resolution": [res, res]},
        "camera": {"view": [0.0, 0.3, 1.0]},
        "lights": {"directions": [[0.5, 0.8, 1.0]]},
        "effects": {"noise": True},
        "strands": {"count": strands, "radius": 0.0015, "profile": "clumped", "spread": 0.25},
        "shadows": {"method": shadows},
        "clusters": clusters,
    }


def _sample(arr, pix):
    P = arr.shape[-1]
    f = np.clip(pix, 0.0, P - 1.0)
    i0 = np.clip(np.floor(f).astype(np.int64), 0, max(P - 2, 0))
    i1 = np.minimum(i0 + 1, P - 1)
    extra = arr.ndim - f.ndim  # trailing axes: (..., P) or (..., L, P)
    w = (f - i0).reshape(f.shape + (1,) * (extra - 1))
    g0 = np.take_along_axis(arr, i0.reshape(f.shape + (1,) * extra), -1)[..., 0]
    g1 = np.take_along_axis(arr, i1.reshape(f.shape + (1,) * extra), -1)[..., 0]
    return g0 + w * (g1 - g0)


def _sin(c):
    return np.sqrt(np.clip(1 - c * c, 0, 1))


def numpy_frame(prep) -> list[np.ndarray]:
    """The same frame in plain NumPy: maps (satf eqs 6–7), lighting (8–11), s-map, shading, blend (12–14)."""
    from hairlut.synth import fetch, param_distance, sector_angles, texels, wrap

    sc, db = prep.scene, prep.db
    m, fx = sc.material, sc.effects
    kd, ks1, ks2, p1, p2, s = (m[k] for k in ("kd", "ks_I", "ks_II", "p_I", "p_II", "shift"))
    scale, bias, amount = m["diffuse_scale"], m["diffuse_bias"], m["noise_amount"]
    hair = np.asarray(m["hair_color"])
    colours = [hair, np.asarray(m["spec_color_I"]), np.asarray(m["spec_color_II"]) * (hair if m["secondary_hair_tint"] else 1)]
    n_u, n_t = sc.config["render"]["resolution"]
    out = []
    for pc in prep.clusters:
        sp = sector_angles(pc.frames, sc.view, sc.lights)
        tx = texels(pc.table, sp, pc.spec.n_layers, (n_u, n_t), db.alpha.shape[-1])
        top, bot = pc.table.hsv_sectors[:, 0], pc.table.hsv_sectors[:, 1]
        d = param_distance(
            db, sp.features[top], sp.theta_v[top], sp.theta_l[top], sp.features[bot], sp.theta_v[bot], sp.theta_l[bot]
        )
        uni = d < m["k_threshold"]
        k = sc.config["render"]["neighbours"]
        re_s, a_s = fetch(db, sp.features, sp.theta_v, sp.theta_l, k)
        f = 0.5 * (sp.features[top] + sp.features[bot])
        tv = sp.theta_v[top] + 0.5 * wrap(sp.theta_v[bot] - sp.theta_v[top])
        tl = sp.theta_l[top] + 0.5 * wrap(sp.theta_l[bot] - sp.theta_l[top])
        re_u, a_u = fetch(db, f[uni], tv[uni], tl[uni], k)
        re1, re2, a1, a2 = re_s[top], re_s[bot], a_s[top], a_s[bot]
        re1[uni], re2[uni], a1[uni], a2[uni] = re_u, re_u, a_u, a_u
        h, g = tx.hsv, tx.gamma
        u = uni[h]
        x1, x2 = np.where(u, tx.pix_ave, tx.pix_top), np.where(u, tx.pix_ave, tx.pix_bot)
        re = (1 - g)[..., None] * _sample(re1[h], x1) + g[..., None] * _sample(re2[h], x2)  # (C, K, t, u, L)
        al = np.clip((1 - g) * _sample(a1[h], x1) + g * _sample(a2[h], x2), 0, 1)[0]
        t, n, v, ls = pc.tangent, pc.normal, sc.view, sc.lights
        cl = t @ ls.T
        light = np.zeros(t.shape[:-1] + (len(ls), 3))
        if fx["diffuse"]:
            light += kd * np.maximum(0, scale * _sin(cl) + bias)[..., None] * colours[0]
        for on, sh, p, ks, col, noisy in (
            (fx["primary"], s, p1, ks1, colours[1], False),
            (fx["secondary"], -s, p2, ks2, colours[2], fx["noise"]),
        ):
            if on:
                tt = t + sh * n
                tt /= np.linalg.norm(tt, axis=-1, keepdims=True)
                c1, c2 = tt @ ls.T, (tt @ v)[..., None]
                term = ks * np.maximum(0, _sin(c1) * _sin(c2) - c1 * c2) ** p
                if noisy:
                    term = term * (1 - amount * pc.noise)[..., None]
                light += term[..., None] * col
        light *= sc.light_colors
        outer = np.cumsum(al[::-1], 0)[::-1] - al
        tau = np.exp(-m["k_shadow"] * outer) if fx["shadow"] else np.ones_like(al)
        rgb = tau[..., None] * np.sum(light * re[0][..., None], axis=-2)
        keep = 1 - al
        above = np.concatenate([np.cumprod(keep[::-1], 0)[::-1][1:], np.ones_like(keep[:1])])
        final = np.asarray(sc.config["render"]["background"]) * np.prod(keep, 0)[..., None] + np.sum(
            rgb * (al * above)[..., None], 0
        )
        out.append(final)
    return out


def shadow_methods(prep, model: dict, runs: int = 10) -> list[dict]:
    """Frame time per shadow method on the prepared :func:`ring_model` (``model``: its keyword arguments): its maps
    built once for the scene's lights (as ``prepare`` does), then ``runs`` frames, then one frame under a new light."""
    from dataclasses import replace

    from hairlut.scene import SHADOW_METHODS, resolve_scene, scene_clusters
    from hairlut.synth import prepare_shadows, render_view

    strands = [s for _, s in scene_clusters(prep.scene)]
    points = np.stack([pc.position for pc in prep.clusters])
    rows = []
    for method in SHADOW_METHODS:
        sc = resolve_scene(ring_model(model["clusters"], model["s_t"], model["s_u"], model["res"], model["strands"], method))
        build = {}
        variant = replace(prep, scene=sc, shadows=prepare_shadows(sc, strands, points, build))
        render_view(variant)  # warm-up: compiles
        frames = [timed(lambda: render_view(variant), repeat=1) for _ in range(runs)]
        sec = np.array([t for t, _ in frames])
        best = frames[int(np.argmin(sec))][1]
        render_view(variant, lights=[[0.4, 0.9, -0.5]])  # a first relight compiles what a new map size needs
        relit, _ = timed(lambda: render_view(variant, lights=[[-0.4, 0.9, 0.5]]), repeat=1)
        render_view(variant)  # back to the scene's lights (rebuilds the maps outside the timings)
        rows.append(
            {
                "method": method,
                "build_s": build.get("shadows", 0.0),
                "ms": 1e3 * sec.min(),
                "median": 1e3 * float(np.median(sec)),
                "shade": 1e3 * best.stats["seconds"]["shade"],
                "relit_s": relit,
            }
        )
    return rows


def small_db(folder: Path, quick: bool) -> Path:
    """A small HRIR database for the frame (64 sectors when ``quick``, else 256; 16 × 16 angles, 32 px)."""
    from hairlut.hrir import bake

    out = Path(folder) / "db.h5"
    bake(
        {
            "sectors": {"count": 64 if quick else 256, "grid": [16, 16]},
            "angles": {"views": 16, "lights": 16},
            "trace": {"pixels": 32, "steps": 32, "self_shadow": False},
        },
        out,
    )
    return out


def online_frame_study(quick: bool = False, db: Path | None = None, **model) -> dict:
    """The online frame of :func:`ring_model` (``model``: ``clusters``, ``s_t``, ``s_u``, ``res``, ``strands`` over
    :data:`PAPER_MODEL`, or :data:`QUICK_MODEL` when ``quick``) with the database ``db`` (default: :func:`small_db`
    in a temporary folder): 20 JAX frames and 3 NumPy frames after a warm-up, best and median, the stage times of the
    best JAX run, the largest |JAX − NumPy| of the composite, and :func:`shadow_methods`."""
    import jax

    from hairlut.hrir import load_hrir_db
    from hairlut.scene import resolve_scene
    from hairlut.synth import prepare, render_view

    size = {**(QUICK_MODEL if quick else PAPER_MODEL), **model}
    with tempfile.TemporaryDirectory(prefix="hairlut-frame-") as tmp:
        database = load_hrir_db(Path(db) if db else small_db(Path(tmp), quick))
        sc = resolve_scene(ring_model(size["clusters"], size["s_t"], size["s_u"], size["res"], size["strands"]))
        t0 = time.perf_counter()
        prep = prepare(sc, database)
        t_prep = time.perf_counter() - t0
    render_view(prep)  # warm-up: compiles
    jax_runs = []
    for _ in range(20):
        sec, res = timed(lambda: render_view(prep), repeat=1)
        jax_runs.append((sec, {k: v for k, v in res.stats["seconds"].items() if k not in ("strands", "index")}))
    numpy_frame(prep)
    np_runs = []
    for _ in range(3):
        sec, ref = timed(lambda: numpy_frame(prep), repeat=1)
        np_runs.append((sec, {}))
    err = max(float(np.abs(c.final[..., :3] - r).max()) for c, r in zip(res.clusters, ref))
    rows = []
    for name, runs in (("hairlut.synth.render_view (JAX)", jax_runs), ("NumPy", np_runs)):
        sec = np.array([t for t, _ in runs])
        rows.append(
            {
                "impl": name,
                "runs": len(runs),
                "ms": 1e3 * sec.min(),
                "median": 1e3 * float(np.median(sec)),
                **{k: 1e3 * v for k, v in runs[int(np.argmin(sec))][1].items()},
            }
        )
    return {
        "device": str(jax.devices()[0]),
        "model": size,
        "db_sectors": len(database.features),
        "stats": res.stats,
        "prepare_s": t_prep,
        "rows": rows,
        "frame_ms": {"jax": rows[0]["ms"], "numpy": rows[1]["ms"]},
        "median_ms": {"jax": rows[0]["median"], "numpy": rows[1]["median"]},
        "max_abs_diff": err,
        "shadow_methods": shadow_methods(prep, size),
    }
