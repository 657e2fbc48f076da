"""Part ``maps``: every map method's texel maps against a converged truth
(``benchmarks/map_accuracy.py``), and the online step of one view of the paper's model,
hairlut's JAX against a NumPy implementation of the same steps (``benchmarks/online_frame.py``); both
run as subprocesses."""

from __future__ import annotations

from ._figure import Figure
from ._parts import Context
from ._scripts import ROOT, run_script, script_missing

PART = "maps"


def unavailable() -> str | None:
    return script_missing("map_accuracy.py") or script_missing("online_frame.py")


def _knobs(text: str) -> dict:
    """map_accuracy's knob string ("views=64, terms=4") as a dict; free text stays whole."""
    pairs = [p.split("=", 1) for p in str(text).split(", ")]
    return dict(pairs) if all(len(p) == 2 for p in pairs) else {"knobs": text}


def accuracy(ctx: Context) -> list[Figure]:
    scene = ROOT / "tables" / "scenes" / ("two-clusters.toml" if ctx.quick else "sintel-groom.toml")
    args = ["--scene", str(scene)] + (["--quick", "--no-satf"] if ctx.quick else [])
    doc = run_script("map_accuracy.py", args, ctx.workdir / "map_accuracy.json", timeout=900 if ctx.quick else 1500)
    figs = []
    recs = doc["records"]
    base = next((i for i, r in enumerate(recs) if r["method"] == "direct"), 0)
    for i, r in enumerate(recs):
        figs.append(Figure(PART, f"{scene.stem}: texel maps against a converged truth", f"{r['method']} ({r['knobs']})",
                           r["frame_ms"] / 1e3, r.get("re_rel_l2"), "re rel-L2",
                           _knobs(r["knobs"]), baseline=i == base, paper=r["method"] == "satf",
                           extra={k: r.get(k) for k in ("alpha_rel_l2", "coverage_rel_l2", "alpha_bias", "bake_s", "bytes")}))
    ctx.note(PART, f"map accuracy: benchmarks/map_accuracy.py on {scene.name}"
                   f"{' --quick --no-satf (the SATF database bake is left to the full run)' if ctx.quick else ''}; "
                   f"truth traced in {doc.get('truth_seconds', float('nan')):.1f} s; time = the maps of one view; "
                   "baseline: the direct method (each sector projected at the exact view)")
    return figs


def view(ctx: Context) -> list[Figure]:
    doc = run_script("online_frame.py", ["--quick"] if ctx.quick else [], ctx.workdir / "online_frame.json",
                     timeout=900 if ctx.quick else 1500)
    table = "online view: JAX against the NumPy implementation of the same steps"
    st = doc.get("stats", {})
    figs = [Figure(PART, table, "NumPy view (eqs 6–14)", doc["frame_ms"]["numpy"] / 1e3, None, "max |Δ composite|",
                   baseline=True),
            Figure(PART, table, "hairlut.synth.render_view (JAX)", doc["frame_ms"]["jax"] / 1e3, doc["max_abs_diff"],
                   "max |Δ composite|", {k: st.get(k) for k in ("clusters", "layers", "hsvs")}, paper=not ctx.quick)]
    for r in doc.get("shadow_methods", []):
        figs.append(Figure(PART, "online view per shadow method", r["method"], r["ms"] / 1e3, None, "error (see shadows)",
                           {"build_s": r.get("build_s"), "relit_s": r.get("relit_s")}, baseline=r["method"] == "smap",
                           paper=r["method"] == "smap"))
    ctx.note(PART, f"online view: benchmarks/online_frame.py{' --quick' if ctx.quick else ''}: {st.get('clusters')} clusters, "
                   f"{st.get('hsvs')} HSVs; the NumPy implementation is the reference (error 0 by definition); the paper's "
                   "human model (17 clusters × 3 layers, s_t = 64, s_u = 16) in the full run only; the shadow methods' "
                   "table has times only (their accuracy is the shadows part)")
    return figs


def run(ctx: Context) -> list[Figure]:
    return accuracy(ctx) + view(ctx)
