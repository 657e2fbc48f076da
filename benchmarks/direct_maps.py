"""Direct sector maps (issue 12's ``direct`` method) against tracing each sector on its own.

    python -m benchmarks.direct_maps [--scene tables/scenes/sintel-groom.toml] [--quick] [--json OUT]

The scene's sectors (its own clusters and strands, as ``hairlut.synth.prepare`` builds them)
are made into kernel inputs by ``scene_sector_inputs`` (density grid 32², the HRIR
recipe's trace and Phong settings: 32 px, 48 steps, 1 ray per pixel, self-shadowing), and
each sector's exact θv and θl come from the scene's view and lights
(``hairlut.geometry.sector_axes`` + ``azimuths``).  Then, in the same run:

- **baseline**: ``hairlut.hrir.trace_sectors`` called once per non-empty sector at that
  sector's own angles (how ``benchmarks/satf_accuracy.py`` builds its truth today; empty
  sectors are skipped there too);
- **direct**: ``direct_sector_maps``, every sector in one jitted kernel (empty sectors
  skipped), at the same settings: with the tracer's light-depth grid it reproduces the baseline
  to float32 rounding; with its default lookup (the light march read directly) it differs by
  that one interpolation; then with finer sampling (2 rays per pixel; 2× steps);
- **direct α only**: the same kernel with no lights (no shading work);
- **converged**: the direct kernel at 4 rays per pixel, 2× steps and a 64² grid, the
  reference the finer settings are also measured against (issue 12, item 2).

Errors: α and re rel-L2 (‖Δ‖/‖ref‖ over all sectors, lights and pixels) and the per-sector
coverage rel-L2 (each sector's pixel-mean α).  Times: best of 3 after a warm-up (the first
call's compile time reported separately); the baseline runs once (it is the slow one).
Prints a table and writes JSON (``--json OUT``; benchmarks/results/direct_maps.json by default).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ._common import best_of, emit, table

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "tables" / "scenes" / "sintel-groom.toml"
TRACE = {"trace": {"pixels": 32, "steps": 48}}


def _direct_api():
    from hairlut.march import direct_sector_maps, scene_sector_inputs

    return direct_sector_maps, scene_sector_inputs


def scene_inputs(scene_path: Path, rec: dict, grid=None):
    """density, geometry, θv, θl of every sector of every cluster of the scene."""
    from hairlut.geometry import ClusterGeometry, azimuths, build_sectors, sector_axes
    from hairlut.scene import load_scene, scene_clusters

    _, scene_sector_inputs = _direct_api()
    scene = load_scene(scene_path)
    if grid is not None:
        rec = {**rec, "sectors": {**rec["sectors"], "grid": [grid, grid]}}
    out = {"density": [], "geometry": [], "theta_v": [], "theta_l": []}
    for spec, strands in scene_clusters(scene):
        geom = ClusterGeometry(spec)
        tb = build_sectors(geom, strands, np.zeros(strands.n_strands, np.int64))
        d, g = scene_sector_inputs(tb, rec)
        tv, tl = azimuths(*sector_axes(geom, tb), scene.view, scene.lights)
        for k, v in zip(out, (d, g, tv, tl)):
            out[k].append(v)
    return {k: np.concatenate(v) for k, v in out.items()}


def rel(x, ref) -> float:
    return float(np.linalg.norm(x - ref) / max(np.linalg.norm(ref), 1e-30))


def errors(a, r, a_ref, r_ref) -> dict:
    """α, re and coverage errors; re's are None when ``r`` holds no lights (α only)."""
    shaded = r.size > 0
    r_ref = r_ref[:, : r.shape[1]]
    return {
        "alpha_rel_l2": rel(a, a_ref),
        "re_rel_l2": rel(r, r_ref) if shaded else None,
        "coverage_rel_l2": rel(a.mean(-1), a_ref.mean(-1)),
        "alpha_max_abs": float(np.abs(a - a_ref).max()),
        "re_max_abs": float(np.abs(r - r_ref).max()) if shaded else None,
    }


def baseline(inp, rec):
    from hairlut.hrir import trace_sectors

    d, g, tv, tl = inp["density"], inp["geometry"], inp["theta_v"], inp["theta_l"]
    N, P = len(d), rec["trace"]["pixels"]
    alpha, re = np.zeros((N, P), np.float32), np.zeros((N, tl.shape[1], P), np.float32)
    live = np.flatnonzero(d.reshape(N, -1).max(1) > 0)
    trace_sectors(d[live[:1]], g[live[:1]], rec, views=tv[live[:1]], lights=tl[live[0]])  # compile
    start = time.perf_counter()
    for i in live:
        a, r = trace_sectors(d[i : i + 1], g[i : i + 1], rec, views=tv[i : i + 1], lights=tl[i])
        alpha[i], re[i] = a[0, 0], r[0, 0]
    return alpha, re, time.perf_counter() - start


def timed(fn, repeat=3):
    start = time.perf_counter()
    fn()
    first = time.perf_counter() - start
    sec, out = best_of(fn, repeat=repeat)
    return first, sec, out


def main(argv=None):
    from hairlut.hrir import resolve_recipe

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, default=SCENE)
    ap.add_argument("--quick", action="store_true", help="skip the converged reference and the finer settings")
    ap.add_argument("--block", type=int, default=64, help="sectors vmapped together in the kernel")
    ap.add_argument("--json", type=Path, help="write the results here (default benchmarks/results/direct_maps.json)")
    args = ap.parse_args(argv)
    direct_sector_maps, _ = _direct_api()
    rec = resolve_recipe(TRACE)
    inp = scene_inputs(args.scene, rec)
    N = len(inp["density"])
    live = int((inp["density"].reshape(N, -1).max(1) > 0).sum())
    a_base, r_base, base_s = baseline(inp, rec)
    rows = [
        {
            "method": "trace_sectors loop (baseline)",
            "rays": 1,
            "steps": 48,
            "seconds": base_s,
            "speedup": 1.0,
            **errors(a_base, r_base, a_base, r_base),
        }
    ]
    conv = None
    if not args.quick:
        cin = scene_inputs(args.scene, rec, grid=64)
        _, _, conv = timed(
            lambda: direct_sector_maps(
                cin["density"], cin["geometry"], cin["theta_v"], cin["theta_l"], rec, rays=4, n_steps=96, block=args.block
            ),
            repeat=1,
        )
    settings = [("direct, tracer's shadow grid", 1, 48, False, "grid"), ("direct", 1, 48, False, "march")]
    if not args.quick:
        settings += [("direct", 2, 48, False, "march"), ("direct", 2, 96, False, "march")]
    settings.append(("direct α only", 1, 48, True, "march"))
    for name, rays, steps, alpha_only, lookup in settings:
        tl = inp["theta_l"][:, :0] if alpha_only else inp["theta_l"]
        first, sec, (a, r) = timed(
            lambda: direct_sector_maps(
                inp["density"],
                inp["geometry"],
                inp["theta_v"],
                tl,
                rec,
                rays=rays,
                n_steps=steps,
                block=args.block,
                shadow_lookup=lookup,
            )
        )
        row = {
            "method": name,
            "rays": rays,
            "steps": steps,
            "seconds": sec,
            "first_call_s": first,
            "speedup": base_s / sec,
            **errors(a, r, a_base, r_base),
        }
        if conv is not None:
            row.update({f"conv_{k}": v for k, v in errors(a, r, *conv).items()})
        rows.append(row)
    if conv is not None:
        rows[0].update({f"conv_{k}": v for k, v in errors(a_base, r_base, *conv).items()})
    print(f"\n## Direct maps of {args.scene.name}: {N} sectors ({live} non-empty), {inp['theta_l'].shape[1]} lights, 32 px\n")
    cols = [
        ("method", "method", "s"),
        ("rays", "rays/px", "d"),
        ("steps", "steps", "d"),
        ("seconds", "s", ".3f"),
        ("speedup", "× baseline", ".1f"),
        ("alpha_rel_l2", "α rel vs baseline", ".2e"),
        ("re_rel_l2", "re rel vs baseline", ".2e"),
        ("coverage_rel_l2", "coverage rel", ".2e"),
    ]
    if conv is not None:
        cols += [
            ("conv_alpha_rel_l2", "α rel vs converged", ".3f"),
            ("conv_re_rel_l2", "re rel vs converged", ".3f"),
            ("conv_coverage_rel_l2", "coverage vs converged", ".3f"),
        ]
    print(table(rows, cols))
    payload = {
        "scene": str(args.scene),
        "sectors": N,
        "live": live,
        "lights": int(inp["theta_l"].shape[1]),
        "pixels": 32,
        "block": args.block,
        "rows": rows,
    }
    emit("direct_maps", payload, args.json)


if __name__ == "__main__":
    main()
