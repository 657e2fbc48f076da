"""Part ``maps``: every map method's texel maps against a converged truth (:func:`map_accuracy_study`), and the
online frame of the paper's model, hairlut's JAX frame against a NumPy implementation of the same steps
(:func:`online_frame_study`)."""

from __future__ import annotations

from ._figure import Figure
from ._map_accuracy import map_accuracy_study
from ._online_frame import online_frame_study
from ._parts import Context, example

PART = "maps"


def _knobs(text: str) -> dict:
    """A record's knob string ("views=64, terms=4") as a dict; free text stays whole."""
    pairs = [p.split("=", 1) for p in str(text).split(", ")]
    return dict(pairs) if all(len(p) == 2 for p in pairs) else {"knobs": text}


def accuracy(ctx: Context) -> list[Figure]:
    scene = example("scenes/two-clusters.toml" if ctx.quick else "scenes/sintel-groom.toml")
    methods = ("direct", "scene") if ctx.quick else ("direct", "scene", "satf")
    doc = map_accuracy_study(scene, ctx.quick, methods=methods, progress=ctx.progress)
    figs = []
    recs = doc["records"]
    base = next((i for i, r in enumerate(recs) if r["method"] == "direct"), 0)
    for i, r in enumerate(recs):
        figs.append(
            Figure(
                PART,
                f"{scene.stem}: texel maps against a converged truth",
                f"{r['method']} ({r['knobs']})",
                r["frame_ms"] / 1e3,
                r.get("re_rel_l2"),
                "re rel-L2",
                _knobs(r["knobs"]),
                baseline=i == base,
                paper=r["method"] == "satf",
                extra={k: r.get(k) for k in ("alpha_rel_l2", "coverage_rel_l2", "alpha_bias", "bake_s", "bytes")},
            )
        )
    ctx.note(
        PART,
        f"map accuracy: methods {', '.join(methods)} on {scene.name}"
        f"{' (the SATF database bake is left to the full run)' if ctx.quick else ''}; "
        f"truth traced in {doc.get('truth_seconds', float('nan')):.1f} s; time = the maps of one frame; "
        "baseline: the direct method (each sector projected at the exact view)",
    )
    return figs


def frame(ctx: Context) -> list[Figure]:
    doc = online_frame_study(ctx.quick)
    table = "online frame: JAX against the NumPy implementation of the same steps"
    st = doc.get("stats", {})
    figs = [
        Figure(PART, table, "NumPy frame (eqs 6–14)", doc["frame_ms"]["numpy"] / 1e3, None, "max |Δ composite|", baseline=True),
        Figure(
            PART,
            table,
            "hairlut.synth.render_view (JAX)",
            doc["frame_ms"]["jax"] / 1e3,
            doc["max_abs_diff"],
            "max |Δ composite|",
            {k: st.get(k) for k in ("clusters", "layers", "hsvs")},
            paper=not ctx.quick,
        ),
    ]
    for r in doc.get("shadow_methods", []):
        figs.append(
            Figure(
                PART,
                "online frame per shadow method",
                r["method"],
                r["ms"] / 1e3,
                None,
                "error (see shadows)",
                {"build_s": r.get("build_s"), "relit_s": r.get("relit_s")},
                baseline=r["method"] == "smap",
                paper=r["method"] == "smap",
            )
        )
    ctx.note(
        PART,
        f"online frame{' (quick model)' if ctx.quick else ''}: {st.get('clusters')} clusters, "
        f"{st.get('hsvs')} HSVs; the NumPy frame is the reference (error 0 by definition); the paper's "
        "human model (17 clusters × 3 layers, s_t = 64, s_u = 16) in the full run only; the shadow methods' "
        "table has times only (their accuracy is the shadows part)",
    )
    return figs


def run(ctx: Context) -> list[Figure]:
    return accuracy(ctx) + frame(ctx)
