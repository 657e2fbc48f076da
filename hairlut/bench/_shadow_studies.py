"""What ``benchmarks/light_oriented.py`` and ``benchmarks/opacity_maps.py`` measure, as documents.

:func:`light_oriented_study`: the light-oriented map (bertails §2–3, eqs 1–3) at each resolution
against the NumPy ray march (``hairlut.shadows.ray_march``) at the same resolution (the baseline)
and at a finer one (the reference), with the error float32 / float16 storage of its
transmittance grid adds.  :func:`opacity_maps_study`: opacity shadow maps (kim §6.2, eqs 6-1,
6-2) at a few (slices, texels) settings against :func:`numpy_opacity_maps` (Kim's Table 6-1 in
NumPy on the same layout: the baseline, and a check that both discretise alike) and against a
many-slice, fine-texel run of the same method.  Both run on the Sintel groom of the ``shadows``
bench part; that part measures every method against the strand-level reference instead.
"""

from __future__ import annotations

import time

import numpy as np

from ._parts import timed
from ._shadows import GROOM, LIGHT, stored

#: The opacity-map study's light (kept from its script: its README table was measured with it).
OSM_LIGHT = np.array([0.3, 1.0, 0.5])


def _rms(d) -> float:
    return float(np.sqrt(np.mean(np.square(d))))


def _header(strands, light, kappa) -> dict:
    import jax

    return {
        "jax": jax.__version__,
        "device": str(jax.devices()[0]),
        "groom": GROOM.name,
        "strands": strands.n_strands,
        "vertices": strands.n_points,
        "light": np.asarray(light).tolist(),
        "kappa": kappa,
    }


def light_oriented_study(resolutions=(32, 64, 128), reference: int = 256, kappa: float = 0.05) -> dict:
    """The light-oriented map at each of ``resolutions`` (map + ``.at`` at every vertex, best of 5 warm
    runs; the first call, with compilation, and the map alone too) beside the NumPy ray march at the
    same resolution (best of 2), both against the ray march at ``reference`` cells and quarter-cell
    steps: max and RMS |ΔT| at the vertices, hairlut against NumPy at the same N, and the max change
    float32 / float16 storage of the transmittance grid makes.  Returns the script's JSON document."""
    from hairlut.geometry import read_strands
    from hairlut.shadows import light_oriented_map, ray_march

    strands = read_strands(GROOM)
    pts = strands.points
    out = _header(strands, LIGHT, kappa)
    out["length"] = float(strands.lengths().sum())
    t0 = time.perf_counter()
    ref = ray_march(pts, LIGHT, kappa, strands, reference, step=0.25)
    out["reference"] = {
        "resolution": reference,
        "step_cells": 0.25,
        "time_s": time.perf_counter() - t0,
        "min_T": float(ref.min()),
        "mean_T": float(ref.mean()),
    }

    def ours(res):
        return light_oriented_map(strands, LIGHT, resolution=res, kappa=kappa)

    rows = []
    for res in resolutions:
        t0 = time.perf_counter()
        ours(res).at(pts)
        t_first = time.perf_counter() - t0
        t_map, m = timed(lambda: ours(res), repeat=5)
        t_all, T = timed(lambda: ours(res).at(pts), repeat=5)
        t_np, B = timed(lambda: ray_march(pts, LIGHT, kappa, strands, res), repeat=2)
        d32 = float(np.abs(stored(m, np.float32).at(pts) - T).max())
        d16 = float(np.abs(stored(m, np.float16).at(pts) - T).max())
        rows.append(
            {
                "resolution": res,
                "grid": "×".join(map(str, m.shape)),
                "hairlut_s": t_all,
                "hairlut_map_s": t_map,
                "hairlut_first_s": t_first,
                "numpy_s": t_np,
                "speedup": t_np / t_all,
                "max": float(np.abs(T - ref).max()),
                "rms": _rms(T - ref),
                "numpy_max": float(np.abs(B - ref).max()),
                "numpy_rms": _rms(B - ref),
                "vs_numpy_max": float(np.abs(T - B).max()),
                "vs_numpy_rms": _rms(T - B),
                "float32_max": d32,
                "float16_max": d16,
            }
        )
    out["results"] = rows
    return out


def numpy_opacity_maps(strands, layout, kappa: float) -> np.ndarray:
    """τ at every vertex by Kim's Table 6-1, in NumPy, on the grid of ``layout`` (an
    :class:`hairlut.shadows.OpacityMaps` at the same setting: only its frame, origin, texel edge, near
    depth and slice spacing are used, never its Ω) with the same pieces (width 1): vertices bucketed by
    slice (loop 2), then per slice Ω_i = Ω_{i−1} + that slice's pieces (np.add.at) and a bilinear,
    depth-linear lookup of that slice's vertices in Ω_{i−1}, Ω_i (loops 3 and 4, eq 6-2)."""
    q = np.asarray(strands.points, np.float64) @ layout.frame.T
    (ox, oy), h, near = layout.origin, layout.spacing, layout.near
    n_slices, H, W = layout.shape
    dz = float(layout.depths[0] - near)
    step = 0.25 * min(h, dz)
    seg = strands.segments
    a, b = q[seg[:, 0]], q[seg[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(1, np.ceil(length / step)).astype(int)
    rep = np.repeat(np.arange(len(seg)), n)
    k = np.arange(rep.size) - np.repeat(np.cumsum(n) - n, n)
    s = a[rep] + ((k + 0.5) / n[rep])[:, None] * (b[rep] - a[rep])
    w = (length / n)[rep] / h**2
    ix = np.clip(np.floor((s[:, 0] - ox) / h).astype(int), 0, W - 1)
    iy = np.clip(np.floor((s[:, 1] - oy) / h).astype(int), 0, H - 1)
    iz = np.clip(np.floor((s[:, 2] - near) / dz).astype(int), 0, n_slices - 1)
    order = np.argsort(iz, kind="stable")
    cuts = np.searchsorted(iz[order], np.arange(n_slices + 1))
    sp = (q[:, 2] - near) / dz  # loop 2: vertices by slice
    slot = np.clip(np.floor(sp).astype(int), 0, n_slices - 1)
    porder = np.argsort(slot, kind="stable")
    pcuts = np.searchsorted(slot[porder], np.arange(n_slices + 1))
    gx, gy = (q[:, 0] - ox) / h - 0.5, (q[:, 1] - oy) / h - 0.5
    tau = np.ones(len(q))
    cur = np.zeros((H, W))

    def sample(buf, x, y):
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - x0, y - y0
        acc = np.zeros(len(x))
        for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
            xi, yi = x0 + dx, y0 + dy
            ok = (xi >= 0) & (xi < W) & (yi >= 0) & (yi < H)
            wgt = (fx if dx else 1 - fx) * (fy if dy else 1 - fy) * ok
            acc += wgt * buf[np.clip(yi, 0, H - 1), np.clip(xi, 0, W - 1)]
        return acc

    for i in range(n_slices):  # loop 3
        prev, cur = cur, cur.copy()
        sel = order[cuts[i] : cuts[i + 1]]
        np.add.at(cur, (iy[sel], ix[sel]), w[sel])
        p = porder[pcuts[i] : pcuts[i + 1]]  # loop 4
        t = np.clip(sp[p] - i, 0.0, 1.0)
        tau[p] = np.exp(-kappa * ((1 - t) * sample(prev, gx[p], gy[p]) + t * sample(cur, gx[p], gy[p])))
    return tau


def opacity_maps_study(kappa: float = 0.05, quick: bool = False) -> dict:
    """Opacity maps at (8, 32), (16, 64) [and (32, 128)] slices × texels: hairlut (maps + τ at every
    vertex, best of the timed runs after a warm-up; the first call too) and :func:`numpy_opacity_maps`,
    each against a (128, 256) [quick: (64, 128)] run of the same method; against as many slices at
    the setting's own texels ("slices only": the depth interpolation's error alone); and hairlut
    against NumPy (the same discretisation: ~0).  Returns the script's JSON document."""
    from hairlut.geometry import read_strands
    from hairlut.shadows import opacity_shadow_maps

    strands = read_strands(GROOM)
    verts = strands.points
    settings = [(8, 32), (16, 64)] if quick else [(8, 32), (16, 64), (32, 128)]
    ref_setting = (64, 128) if quick else (128, 256)
    repeat = 3 if quick else 5

    def maps(n_slices, res):
        return opacity_shadow_maps(strands, OSM_LIGHT, n_slices=n_slices, resolution=res, kappa=kappa)

    ref = maps(*ref_setting).at(verts)
    rows = []
    for n_slices, res in settings:
        t0 = time.perf_counter()
        maps(n_slices, res).at(verts)
        t_first = time.perf_counter() - t0
        t_jax, tau_j = timed(lambda: maps(n_slices, res).at(verts), repeat=repeat)
        m = maps(n_slices, res)
        t_np, tau_n = timed(lambda: numpy_opacity_maps(strands, m, kappa), repeat=repeat)
        dj, dn, dx = tau_j - ref, tau_n - ref, tau_j - tau_n
        dd = tau_j - maps(ref_setting[0], res).at(verts)
        rows.append(
            {
                "setting": f"{n_slices} × {res}",
                "maps": "×".join(map(str, m.shape)),
                "t_jax": t_jax * 1e3,
                "t_first": t_first * 1e3,
                "t_np": t_np * 1e3,
                "speedup": t_np / t_jax,
                "max_jax": float(np.abs(dj).max()),
                "rms_jax": _rms(dj),
                "max_np": float(np.abs(dn).max()),
                "rms_np": _rms(dn),
                "max_depth": float(np.abs(dd).max()),
                "rms_depth": _rms(dd),
                "max_cross": float(np.abs(dx).max()),
                "mean_tau": float(tau_j.mean()),
            }
        )
    return {
        **_header(strands, OSM_LIGHT, kappa),
        "reference": {"n_slices": ref_setting[0], "resolution": ref_setting[1]},
        "quick": quick,
        "repeat": repeat,
        "rows": rows,
    }


def footprint_study(divisors=(64, 128, 256, 512, 1024), every: int = 2) -> dict:
    """The shadows part's maps (its full sweep of light-oriented cells and opacity-map settings) against the
    strand-level reference at footprints σ = extent / d for each d of ``divisors``, at every ``every``-th
    vertex: RMS and mean signed ΔT per map and footprint, each map's cell, and the reference's mean
    τ = −ln T split into the points' own strands and the others (``strand_transmittance(exclude=)``)."""
    from hairlut.geometry import read_strands
    from hairlut.shadows import light_frame, light_oriented_map, opacity_shadow_maps

    from ._shadows import KAPPA, LOM_CELLS, OSM_SETTINGS, strand_transmittance

    strands = read_strands(GROOM)
    pts = np.asarray(strands.points, np.float64)[::every]
    owner = np.repeat(np.arange(strands.n_strands), np.asarray(strands.counts))[::every]
    span = float(np.ptp(np.asarray(strands.points, np.float64) @ light_frame(LIGHT).T, axis=0).max())
    maps = {f"light-oriented map, {n} cells": light_oriented_map(strands, LIGHT, resolution=n, kappa=KAPPA) for n in LOM_CELLS}
    maps.update(
        {
            f"opacity maps, {s} slices × {n}": opacity_shadow_maps(
                strands, LIGHT, n_slices=s, resolution=n, kappa=KAPPA, width=1.0
            )
            for s, n in OSM_SETTINGS
        }
    )
    got = {k: m.at(pts) for k, m in maps.items()}
    rows = {k: {"cell": float(m.spacing), "rms": [], "bias": []} for k, m in maps.items()}
    own, others = [], []
    for d in divisors:
        ref = strand_transmittance(strands, LIGHT, pts, KAPPA, span / d)
        rest = strand_transmittance(strands, LIGHT, pts, KAPPA, span / d, exclude=owner)
        own.append(float(np.mean(np.log(rest) - np.log(ref))))
        others.append(float(np.mean(-np.log(rest))))
        for k, t in got.items():
            rows[k]["rms"].append(_rms(t - ref))
            rows[k]["bias"].append(float(np.mean(t - ref)))
    return {
        **_header(strands, LIGHT, KAPPA),
        "points": len(pts),
        "extent": span,
        "divisors": list(divisors),
        "tau_own": own,
        "tau_others": others,
        "maps": rows,
    }
