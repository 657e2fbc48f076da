"""Sector densities and features at the paper's human-model scale (satf Table 1, Fig. 7(a)).

    python -m benchmarks.sector_density [--clusters 17] [--layers 3] [--s-t 66] [--s-u 16]
                                        [--strands 14000] [--grid 32] [--numpy-budget 30]

Builds C = 17 clusters of 3 layers (51 layers), s_t = 66 and s_u = 16, i.e.
17·3·66·16 = 53,856 HSVs, and 14K generated strands (Table 1, 7(a): C# 17, L# 51, S# 14K,
H# 54K).  Every HSV has two boundary sectors (§6.2.1), so 2 × 53,856 = 107,712 sector
evaluations (neighbouring HSVs share a sector: 54,672 are distinct).

Times, for the 107,712 sectors on a 32 × 32 grid:
- hairlut: the jitted JAX density kernel (float32) plus the features (basic + moments),
  best of two runs after a warm-up run at the same shapes (first-call time reported too);
- a straightforward NumPy loop over sectors (float64, vectorised within a sector) doing
  the same density and basic features; when the full loop would take longer than
  ``--numpy-budget`` seconds it runs on a prefix of the sectors and its time is scaled
  linearly (the table says so).
Errors: max |ρ_jax − ρ_numpy| over the max density, and the max feature differences, on
the sectors the loop ran.  Grid convergence: the basic features on 8², 16² and 32² grids
against 64² (float32 densities, in chunks), as max and RMS error over the distinct sectors
some strand reaches, relative to the standard deviation of the feature on the 64² grid.

Prints a table and writes benchmarks/results/sector_density.json.
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np
from scipy.special import ndtr

from hairlut.geometry import ClusterGeometry, ClusterSpec, build_sectors, generate_strands, sector_density, sector_features

from ._common import best_of, save, table

BASIC = ("rho_st", "rho_s", "rho_t")


def head_clusters(n: int, layers: int, s_t: int, s_u: int, seed: int = 5) -> list[ClusterSpec]:
    """n hanging clusters rooted on a sphere of radius 10 (a head), 6 control points each."""
    rng = np.random.default_rng(seed)
    specs = []
    for i in range(n):
        theta, phi = rng.uniform(0.2, 1.3), 2 * np.pi * i / n + rng.uniform(-0.2, 0.2)
        root = 10 * np.array([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)])
        out = root / 10
        ctrl = [root + k * (2.5 * out + np.array([0, -4.0 * k / 5, 0])) + rng.normal(0, 0.6, 3) * (k > 0) for k in range(6)]
        radii = tuple(np.linspace(1.0 / layers, 1.0, layers) * 0.8 + 0.2)
        specs.append(
            ClusterSpec(
                np.array(ctrl),
                rng.uniform(0.8, 1.4, 4),
                rng.uniform(0.5, 1.0, 4),
                rng.uniform(-1.5, 1.5, 3),
                layer_radii=radii,
                core_radius=0.15,
                s_t=s_t,
                s_u=s_u,
            )
        )
    return specs


def numpy_sector(center, sigma, radius, v_range, area_scale, grid):
    """One sector by hand: exact cell masses (erf differences) over exact cell areas, then ρ_st, ρ_s, ρ_t."""
    n_s, n_r = grid
    es, er = np.linspace(0, 1, n_s + 1), np.linspace(0, 1, n_r + 1)

    def cdf_diff(edges, c, s):
        z = (edges[None, :] - c[:, None]) / s[:, None]
        lo, hi = z[:, :-1], z[:, 1:]
        return np.where(lo > 0, ndtr(-lo) - ndtr(-hi), ndtr(hi) - ndtr(lo))

    ws, wr = cdf_diff(es, center[:, 0], sigma[:, 0]), cdf_diff(er, center[:, 1], sigma[:, 1])
    step = (v_range[1] - v_range[0]) / n_r
    area = area_scale / n_s * step * (v_range[0] + (np.arange(n_r) + 0.5) * step)
    rho = ((np.pi * radius**2)[:, None] * ws).T @ wr / area[None, :]
    mean = (rho * area).sum() / (area.sum() * n_s)
    h_s, h_t = (rho * area).sum(1) / area.sum(), rho.mean(0)
    s, r = (np.arange(n_s) + 0.5) / n_s, (np.arange(n_r) + 0.5) / n_r
    cs = (s * h_s).sum() / h_s.sum() if h_s.sum() > 0 else 0.5
    ct = (r * h_t).sum() / h_t.sum() if h_t.sum() > 0 else 0.5
    return rho, np.array([mean, cs, ct])


def numpy_loop(sp, grid, count):
    rho = np.zeros((count,) + grid)
    feats = np.zeros((count, 3))
    for n in range(count):
        m = sp.mask[n]
        rho[n], feats[n] = numpy_sector(sp.center[n][m], sp.sigma[n][m], sp.radius[n][m], sp.v_range[n], sp.area_scale[n], grid)
    return rho, feats


def features_in_chunks(sp, grid, names, chunk=16384):
    out = []
    for start in range(0, sp.n_sectors, chunk):
        part = sp.take(slice(start, start + chunk))
        out.append(sector_features(sector_density(part, grid), part, names))
    return np.concatenate(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clusters", type=int, default=17)
    ap.add_argument("--layers", type=int, default=3)
    ap.add_argument("--s-t", type=int, default=66)
    ap.add_argument("--s-u", type=int, default=16)
    ap.add_argument("--strands", type=int, default=14000)
    ap.add_argument("--radius", type=float, default=0.02, help="strand radius (scene units; clusters are ~1 wide)")
    ap.add_argument("--grid", type=int, default=32)
    ap.add_argument("--numpy-budget", type=float, default=30.0, help="seconds the NumPy loop may take before it is scaled")
    args = ap.parse_args()
    grid = (args.grid, args.grid)

    t0 = time.perf_counter()
    geom = ClusterGeometry(head_clusters(args.clusters, args.layers, args.s_t, args.s_u))
    per = np.full(args.clusters, args.strands // args.clusters)
    per[: args.strands - per.sum()] += 1
    strands, owner = generate_strands(
        geom, per, radius=args.radius, profile="clumped", spread=0.15, clumps=8, jitter=0.04, points=32, seed=1
    )
    t_model = time.perf_counter() - t0
    t0 = time.perf_counter()
    tab = build_sectors(geom, strands, owner)
    t_sectors = time.perf_counter() - t0
    ids = tab.hsv_sectors.ravel()
    t0 = time.perf_counter()
    sp = tab.splats(ids)
    t_pack = time.perf_counter() - t0
    n = sp.n_sectors
    print(
        f"model: {geom.n_clusters} clusters, {geom.n_clusters * geom.n_layers} layers, {strands.n_strands} strands, "
        f"{tab.n_hsvs} HSVs, {n} boundary sectors ({tab.n_sectors} distinct), ≤ {sp.max_splats} splats per sector; "
        f"built in {t_model:.1f} s, sectors and crossings in {t_sectors:.1f} s, packing {t_pack:.1f} s"
    )

    def run_jax():
        rho = sector_density(sp, grid)
        return rho, sector_features(rho, sp, "moments")

    t0 = time.perf_counter()
    run_jax()
    t_warm = time.perf_counter() - t0
    t_jax, (rho_j, feat_j) = best_of(run_jax, repeat=2)
    t_jax_density, _ = best_of(lambda: sector_density(sp, grid), repeat=2)

    # NumPy loop: time a prefix, scale if the whole would exceed the budget
    probe = min(n, 2000)
    t0 = time.perf_counter()
    numpy_loop(sp, grid, probe)
    per_sector = (time.perf_counter() - t0) / probe
    count = n if per_sector * n <= args.numpy_budget else max(probe, int(args.numpy_budget / per_sector))
    t0 = time.perf_counter()
    rho_n, feat_n = numpy_loop(sp, grid, count)
    t_np = (time.perf_counter() - t0) * n / count
    scaled = count < n
    err_rho = float(np.abs(rho_j[:count] - rho_n).max() / rho_n.max())
    err_feat = np.abs(feat_j[:count, :3] - feat_n).max(axis=0)

    rows = [
        {"what": f"hairlut JAX float32 (density + 8 features), {n} sectors", "time": t_jax, "per": t_jax / n * 1e6},
        {"what": "  of which the density kernel", "time": t_jax_density, "per": t_jax_density / n * 1e6},
        {"what": "  first call (compile + run)", "time": t_warm, "per": None},
        {
            "what": f"NumPy loop float64 (density + 3 features){' — scaled from ' + str(count) + ' sectors' if scaled else ''}",
            "time": t_np,
            "per": t_np / n * 1e6,
        },
    ]
    print()
    print(table(rows, [("what", "run", "s"), ("time", "time (s)", ".2f"), ("per", "µs / sector", ".1f")]))
    print(
        f"\nspeed-up NumPy / hairlut: {t_np / t_jax:.1f}×   max |Δρ| / max ρ = {err_rho:.2e} (float32 vs float64)   "
        f"max |Δ feature| (ρ_st, ρ_s, ρ_t) = {', '.join(f'{e:.1e}' for e in err_feat)}"
    )

    # grid convergence against 64², over the distinct sectors some strand reaches
    t0 = time.perf_counter()
    reached = np.flatnonzero(np.diff(tab.splat_offsets) > 0)
    spr = tab.splats(reached)
    fine = features_in_chunks(spr, (64, 64), BASIC)
    scale = fine.std(axis=0)
    conv = []
    for g in (8, 16, 32):
        coarse = features_in_chunks(spr, (g, g), BASIC)
        d = np.abs(coarse - fine) / scale
        conv.append(
            {
                "grid": f"{g}×{g}",
                **{f"max_{k}": float(d[:, i].max()) for i, k in enumerate(BASIC)},
                **{f"rms_{k}": float(np.sqrt((d[:, i] ** 2).mean())) for i, k in enumerate(BASIC)},
            }
        )
    t_conv = time.perf_counter() - t0
    print(
        f"\nfeature error against a 64×64 grid, over the {reached.size} distinct sectors some strand reaches, "
        f"in units of each feature's standard deviation (std = {', '.join(f'{s:.3g}' for s in scale)}):"
    )
    cols = [("grid", "grid", "s")] + [(f"{a}_{k}", f"{a} {k}", ".2e") for k in BASIC for a in ("max", "rms")]
    print(table(conv, cols))

    path = save(
        "sector_density",
        {
            "jax": jax.__version__,
            "device": str(jax.devices()[0]),
            "model": {
                "clusters": geom.n_clusters,
                "layers": geom.n_clusters * geom.n_layers,
                "strands": strands.n_strands,
                "hsvs": tab.n_hsvs,
                "boundary_sectors": n,
                "distinct_sectors": tab.n_sectors,
                "max_splats": sp.max_splats,
                "grid": list(grid),
                "strand_radius": args.radius,
            },
            "setup_s": {
                "model_and_strands": t_model,
                "sectors_and_crossings": t_sectors,
                "pack": t_pack,
                "grid_convergence": t_conv,
            },
            "timing_s": {
                "hairlut_density_and_features": t_jax,
                "hairlut_density": t_jax_density,
                "hairlut_first_call": t_warm,
                "numpy_loop": t_np,
                "numpy_loop_scaled": scaled,
                "numpy_sectors_run": count,
                "speedup": t_np / t_jax,
            },
            "error": {"density_rel_max": err_rho, "features_max": dict(zip(BASIC, err_feat.tolist()))},
            "grid_convergence_vs_64": conv,
        },
    )
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
