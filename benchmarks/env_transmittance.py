"""Environment term with self-shadowing: where its clamped texels come from (transmittance bands, de-ringing).

    python -m benchmarks.env_transmittance [--scene tables/scenes/sky-clusters.toml] [--bands 3 5 8] [--json OUT]

The environment term of a texel is E = Σ_j b_j (kd f_dif Cd_j + ks Cs_j) (xing eq 2 through the contracted
tables; ``hairlut.synth``'s environment module), b the strands' voxel SH transmittance truncated to
``bands`` transmittance bands.  For each transmittance band count (the SH tables baked through the
registry with the plan's recipe and only ``bands.transmittance`` changed; the scene prepared through the
public API) this prints the share of texels with E < 0 in some channel (clamped to 0 by the renderer) and the
relative RMS of the clamped E against the most-band run.  It also measures a per-texel de-ringing: scale
b's bands l ≥ 1 by the largest s ∈ [0, 1] that keeps E ≥ 0 in every channel (s = 0 leaves
b₀ (kd f Cd₀ + ks Cs₀), the direction-averaged visibility), and reports its clamped share (texels
where even s = 0 is negative: the band-0 term itself rings) and error.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from ._common import emit, table

ROOT = Path(__file__).resolve().parents[1]


def environment_parts(sc, bands: int, cache: Path) -> dict:
    """The prepared environment of ``sc`` with ``bands`` transmittance bands: raw E (..., 3), b₀-only E and
    the l ≥ 1 part (so E = e0 + rest), and the SH-table bake seconds."""
    from hairlut.bake import registry
    from hairlut.planner import plan
    from hairlut.synth import prepare

    step = plan(sc, cache / "plan").step("sh_tables")
    recipe = {**step.recipe, "bands": {**step.recipe["bands"], "transmittance": int(bands)}}
    t0 = time.perf_counter()
    path, _ = registry.ensure("sh_tables", recipe, cache, **step.inputs)
    bake_s = time.perf_counter() - t0
    env = prepare(sc, sh=str(path)).environment
    m = sc.material
    theta = np.arccos(np.clip(env.tangent @ np.asarray(sc.view, np.float64), -1.0, 1.0))
    x = env.ks * np.asarray(env.contracted.cs(env.tangent, theta))  # (..., n, 3)
    if np.any(env.diffuse):
        x = x + m["kd"] * np.asarray(m["hair_color"]) * np.asarray(env.contracted.cd(env.tangent))
    e0 = env.b[..., :1] * x[..., 0, :]
    rest = np.einsum("...j,...jc->...c", env.b[..., 1:], x[..., 1:, :])
    return {"e0": e0, "rest": rest, "bake_s": bake_s}


def dering(e0, rest):
    """E with each texel's bands l ≥ 1 scaled by the largest s ∈ [0, 1] that keeps every channel ≥ 0."""
    neg = rest < 0
    s = np.where(neg, np.clip(e0 / np.where(neg, -rest, 1.0), 0.0, 1.0), 1.0).min(-1, keepdims=True)
    return e0 + s * rest, s


def main(argv=None):
    from hairlut.recipes import load_toml
    from hairlut.scene import resolve_scene

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, default=ROOT / "tables" / "scenes" / "sky-clusters.toml")
    ap.add_argument("--bands", type=int, nargs="+", default=[3, 5, 8], help="transmittance bands (the last: the reference)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    given = load_toml(args.scene)
    sc = resolve_scene(
        {**given, "render": {**given.get("render", {}), "method": "direct"}}, args.scene.parent, source=str(args.scene)
    )
    if sc.environment is None or not sc.environment["self_shadow"]:
        raise SystemExit(f"{args.scene}: needs an environment light with self_shadow = true")
    with tempfile.TemporaryDirectory() as tmp:
        runs = {b: environment_parts(sc, b, Path(tmp)) for b in args.bands}
    ref = runs[args.bands[-1]]
    ref_clamped = np.maximum(ref["e0"] + ref["rest"], 0.0)
    rows = []
    for b, r in runs.items():
        raw = r["e0"] + r["rest"]
        der, s = dering(r["e0"], r["rest"])
        for mode, e, clamped in (
            ("clamp", np.maximum(raw, 0.0), np.mean(np.any(raw < 0, -1))),
            ("de-ring", np.maximum(der, 0.0), np.mean(np.any(der < 0, -1))),
        ):
            rows.append(
                {
                    "transmittance_bands": b,
                    "mode": mode,
                    "clamped": float(clamped),
                    "rms_vs_ref": float(np.linalg.norm(e - ref_clamped) / np.linalg.norm(ref_clamped)),
                    "scaled_share": float(np.mean(s < 1)) if mode == "de-ring" else 0.0,
                    "sh_bake_s": r["bake_s"],
                }
            )
    print(
        f"\n## Environment term of {args.scene.name}: clamped texels and error against "
        f"{args.bands[-1]} transmittance bands (clamped)\n"
    )
    print(
        table(
            rows,
            [
                ("transmittance_bands", "transmittance bands", "d"),
                ("mode", "mode", "s"),
                ("clamped", "clamped share", ".4f"),
                ("rms_vs_ref", "rel RMS vs reference", ".4f"),
                ("scaled_share", "texels de-ringed", ".4f"),
                ("sh_bake_s", "SH bake s", ".1f"),
            ],
        )
    )
    payload = {"scene": str(args.scene), "records": rows}
    emit("env_transmittance", payload, args.json)


if __name__ == "__main__":
    main()
