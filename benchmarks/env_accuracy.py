"""Environment radiance against a 30-band reference: RMS error and clamped texels (issue 12 item 4).

    python -m benchmarks.env_accuracy [--scene S.toml ...] [--bands 8 12 16] [--stride 4] [--json OUT]

For every example scene with an environment light (default: each ``tables/scenes/*.toml`` with an
``[environment]`` map), through the public API: plan, bake (a temporary cache), prepare, and the
environment term E of every texel at the scene's view (``hairlut.synth``; xing eq 2 through the
contracted SH tables), clamped at 0 as the renderer does.  The reference is the same texels' E by
brute-force quadrature (``hairlut.envlight.hair_radiance``) of the scene's light at 30 bands, no
window, times the same (unwindowed) voxel transmittance: only the light's band limit and the
window differ.  Figures: ``rms_vs_30`` = RMS(E − E_ref) / RMS(E_ref) over texels and channels,
``clamped_fraction`` = share of texels with E < 0 in some channel before the clamp, ``ms`` = the
environment term's time per frame (CPU ms of a warm ``Environment.rgb``, the tables path).

Then a sweep by the same quadrature (every ``--stride``-th texel): the light kept to B bands
(Rd reads the same bands, at least 3, as the planner's recipe
sets), windowed (none / hanning / lanczos σ-factors) on the light,
the 3-band transmittance, or both; ``ms`` is null there (no tables baked per setting).  The row
``render-vs-quadrature`` checks the two paths agree at the scene's own light.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._common import emit, table

ROOT = Path(__file__).resolve().parents[1]
WINDOWS = ("none", "hanning", "lanczos")


def _rms(e, ref) -> float:
    return float(np.sqrt(np.mean((e - ref) ** 2)) / max(np.sqrt(np.mean(ref**2)), 1e-300))


def _clamped(e) -> float:
    return float(np.mean(np.any(e < 0, axis=-1)))


def _windowed(coeffs, bands, window):
    from hairlut.planner import window_coeffs

    return window_coeffs(coeffs[: bands * bands], window)


def scene_env(path: Path, cache: Path):
    """(scene, prepared environment, plan's band figures, the 30-band light) of one scene file."""
    from hairlut.planner import bake, environment_bands, plan, reference_light
    from hairlut.synth import prepare

    p = plan(path, cache)
    assets = bake(p)
    sc = p.scene
    env = prepare(
        sc, assets.get("hrir_db", {}).get("path"), sh=assets["sh_tables"]["path"], maps=assets.get("scene_maps", {}).get("path")
    ).environment
    return sc, env, environment_bands(sc), reference_light(sc)


def default_row(name, sc, env, eb, light30, height) -> list[dict]:
    """The scene as configured, through the tables, against the 30-band quadrature; and the
    tables against the quadrature at the scene's own (windowed) light."""
    from dataclasses import replace

    from hairlut.planner import environment_light

    env.rgb(sc.view)  # compiles the contracted tables' kernels
    t0 = time.process_time()
    e, clamped = env.rgb(sc.view)
    ms = 1e3 * (time.process_time() - t0)
    ref = env.reference(light30.coeffs, sc.view, height)
    own = environment_light(sc).coeffs
    raw = env.diffuse + env.ks * np.einsum("...j,...jc->...c", env.b * env.sigma, env._cs(sc.view))
    nd = env.light_diffuse**2
    same = replace(env, ks=0.0, b=env.b * env.sigma).reference(own[:nd], sc.view, height) + replace(
        env, kd_rgb=np.zeros(3), b=env.b * env.sigma
    ).reference(own, sc.view, height)
    window = sc.environment["window"]
    return [
        {
            "scene": name,
            "bands": eb["bands"],
            "window": window,
            "on": "both" if window != "none" else "-",
            "rms_vs_30": _rms(e, ref),
            "clamped_fraction": clamped,
            "ms": ms,
            "path": "tables (default)",
            "reference_negative": _clamped(ref),
        },
        {
            "scene": name,
            "bands": eb["bands"],
            "window": window,
            "on": "-",
            "rms_vs_30": _rms(raw, same),
            "clamped_fraction": _clamped(raw),
            "ms": None,
            "path": "render-vs-quadrature",
            "reference_negative": None,
        },
    ]


def sweep(name, sc, env, light30, bands, stride, height) -> list[dict]:
    """The quadrature at each band count, window and placement, every ``stride``-th texel."""
    from dataclasses import replace

    from hairlut.planner import window_factors

    sub = replace(env, tangent=env.tangent.reshape(-1, 3)[::stride], b=env.b.reshape(-1, env.b.shape[-1])[::stride])
    ref = sub.reference(light30.coeffs, sc.view, height)
    n = env.b.shape[-1]
    nb = int(round(np.sqrt(n)))
    rows = []
    for t_window in WINDOWS:
        b = sub.b * np.repeat(window_factors(nb, t_window), 2 * np.arange(nb) + 1)
        # one quadrature per transmittance window: columns = (bands, light window, channel); Rd reads the
        # light's bands too (at least 3: hairlut.planner.sh_recipe)
        cols = [(bb, w) for bb in bands for w in WINDOWS]
        n30 = light30.coeffs.shape[0]
        dif = np.concatenate(
            [np.pad(_windowed(light30.coeffs, max(3, bb), w), ((0, n30 - max(3, bb) ** 2), (0, 0))) for bb, w in cols], axis=1
        )
        spec = np.concatenate([np.pad(_windowed(light30.coeffs, bb, w), ((0, n30 - bb * bb), (0, 0))) for bb, w in cols], axis=1)
        k = len(cols) * 3
        if bands and min(bands) >= 3:  # Rd and Rs read the same light: one set of columns
            e = replace(sub, b=b, kd_rgb=np.tile(env.kd_rgb, len(cols))).reference(spec, sc.view, height)
        else:
            e = replace(
                sub,
                b=b,
                kd_rgb=np.concatenate([np.tile(env.kd_rgb, len(cols)), np.zeros(k)]),
                ks=np.concatenate([np.zeros(k), np.full(k, env.ks)]),
            ).reference(np.concatenate([dif, spec], 1), sc.view, height)
            e = e[:, :k] + e[:, k:]
        e = e.reshape(len(e), len(cols), 3)
        for i, (bb, w) in enumerate(cols):
            if t_window != "none" and w not in ("none", t_window):
                continue
            on = {(False, False): "-", (True, False): "light", (False, True): "transmittance", (True, True): "both"}[
                (w != "none", t_window != "none")
            ]
            rows.append(
                {
                    "scene": name,
                    "bands": bb,
                    "window": w if w != "none" else t_window,
                    "on": on,
                    "rms_vs_30": _rms(np.maximum(e[:, i], 0.0), ref),
                    "clamped_fraction": _clamped(e[:, i]),
                    "ms": None,
                    "path": f"quadrature, 1/{stride} texels",
                    "reference_negative": _clamped(ref),
                }
            )
    return rows


def example_scenes() -> list[Path]:
    from hairlut.recipes import load_toml

    return [p for p in sorted((ROOT / "tables" / "scenes").glob("*.toml")) if load_toml(p).get("environment", {}).get("map")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, nargs="*", help="scene files (default: the examples with an environment)")
    ap.add_argument("--bands", type=int, nargs="+", default=[8, 12, 16], help="light bands of the sweep")
    ap.add_argument("--stride", type=int, default=8, help="the sweep's texel subsampling")
    ap.add_argument("--height", type=int, default=96, help="the quadrature's lat-long rows")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in args.scene or example_scenes():
            t0 = time.process_time()
            sc, env, eb, light30 = scene_env(path, Path(tmp))
            rows += default_row(path.name, sc, env, eb, light30, args.height)
            rows += sweep(path.name, sc, env, light30, args.bands, args.stride, args.height)
            print(f"{path.name}: {time.process_time() - t0:.0f} CPU s", file=sys.stderr)
    print("\n## Environment radiance against 30 light bands (no window), same transmittance\n")
    print(
        table(
            rows,
            [
                ("scene", "scene", "s"),
                ("path", "path", "s"),
                ("bands", "bands", "d"),
                ("window", "window", "s"),
                ("on", "on", "s"),
                ("rms_vs_30", "RMS vs 30", ".4f"),
                ("clamped_fraction", "clamped", ".4f"),
                ("ms", "CPU ms", ".1f"),
            ],
        )
    )
    emit("env_accuracy", {"records": rows, "height": args.height, "stride": args.stride}, args.json)


if __name__ == "__main__":
    main()
