"""Part ``hair_bsdf``: hairlut's converged hair BSDF tables against Unreal's Monte Carlo bake (issue 28).

In one run, on Unreal's grid (64 × 64 × 16 sin θ × roughness × absorption; ``--quick``: 16 × 16 × 4):

* the reference: hairlut's quadrature with twice the nodes in every integration axis;
* hairlut's converged tables (the bake's own quadrature), timed, and their error against the reference;
* an Unreal-style uniform Monte Carlo estimator (:func:`hairlut.hairbsdf.montecarlo_rows`: uniform sampling of
  the sphere, Unreal's sample counts) at its default counts and at 4× and 16×, timed and against the same
  reference.  The Monte Carlo runs on every ``MC_STRIDE``-th sin θ row (its error is over those rows, its time
  scaled to the whole table), so the 16× run fits a CPU;
* the whole bake (every table, the HDF5 file written) and its largest error;
* where the Monte Carlo table differs most from the reference, in the roughness × absorption plane (max over
  sin θ): a heat map.
"""

from __future__ import annotations

import time

import numpy as np

from ._figure import Figure
from ._parts import Context

PART = "hair_bsdf"
#: Monte Carlo on every MC_STRIDE-th sin θ row (its time scaled to the whole table).
MC_STRIDE = 4
SCALES = (1, 4, 16)
TABLES = {
    "dual_scattering": ("A_f", "A_b"),
    "mean_energy": ("R", "TT", "TRT"),
}


def _recipe(ctx: Context, table: str | None = None) -> dict:
    from hairlut.hairbsdf import resolve_recipe

    res = [16, 16, 4] if ctx.quick else [64, 64, 16]
    given = {"grid": {"resolution": res}, "coverage": {"bake": table is None}}
    if table is not None:
        given.update({t: {"bake": t == table} for t in TABLES})
    return resolve_recipe(given)


def _max_err(got: dict, ref: dict, names, rows=slice(None)) -> float:
    return max(float(np.abs(np.asarray(got[n], np.float64) - ref[n][rows]).max()) for n in names)


def _timed_rows(fn, *args) -> tuple[float, object]:
    start = time.perf_counter()
    out = fn(*args)
    return time.perf_counter() - start, out


def table_figures(ctx: Context, table: str) -> tuple[list[Figure], dict]:
    """One table's figures (Monte Carlo 1×, 4×, 16×; hairlut's quadrature; its storage) and the heat-map data."""
    from hairlut.hairbsdf import grid_rows, montecarlo_rows

    recipe = _recipe(ctx, table)
    n_s = recipe["grid"]["resolution"][0]
    names = TABLES[table]
    title = f"{table}: {', '.join(names)} against a quadrature with twice the nodes"
    grid_rows(recipe, 0, 1)  # compile
    sec, (values, errs) = _timed_rows(grid_rows, recipe, 0, n_s)
    ref, _ = grid_rows(recipe, 0, n_s, refine=2)
    err = _max_err(values, ref, values)
    figs = []
    rows = np.arange(0, n_s, MC_STRIDE)
    maps = {}
    montecarlo_rows(recipe, 0, 1, scale=1)  # compile
    for k in SCALES:
        mc_sec, mc = 0.0, {n: [] for n in names}
        for r in rows:
            s, got = _timed_rows(lambda r=r, k=k: montecarlo_rows(recipe, int(r), int(r) + 1, scale=k))
            mc_sec += s
            for n in names:
                mc[n].append(got[n][0])
        mc = {n: np.stack(v) for n, v in mc.items()}
        diff = np.max([np.abs(mc[n] - ref[n][rows]) for n in names], axis=0)  # (rows, roughness, absorption)
        maps[k] = diff.max(axis=0)
        figs.append(
            Figure(
                PART,
                title,
                f"Unreal-style Monte Carlo, {k}× Unreal's counts",
                mc_sec * n_s / len(rows),
                float(diff.max()),
                "max |error|",
                {"samples": f"{k}×"},
                baseline=k == 1,
                paper=k == 1,
                extra={"rows_measured": int(len(rows)), "mean_abs_error": float(diff.mean())},
            )
        )
    figs.append(
        Figure(
            PART,
            title,
            "hairlut quadrature (converged)",
            sec,
            _max_err(values, ref, names),
            "max |error|",
            {"nodes": recipe["quadrature"]["nodes"], "levels": recipe["quadrature"]["levels"]},
            extra={
                "all_quantities_error": err,
                "largest_estimated_error": max(float(e.max()) for e in errs.values()),
            },
        )
    )
    for dtype in ("float32", "float16"):
        stored = {n: values[n].astype(dtype) for n in names}
        figs.append(
            Figure(
                PART, title, f"hairlut, stored as {dtype}", None, _max_err(stored, ref, names), "max |error|", {"storage": dtype}
            )
        )
    maps["hairlut"] = np.max([np.abs(values[n] - ref[n]) for n in names], axis=(0, 1))
    ctx.note(
        PART,
        f"{table}: hairlut's quadrature against the 2× reference over every quantity ({', '.join(values)}): "
        f"max |error| {err:.2e}; its own largest error estimate {figs[-3].extra['largest_estimated_error']:.2e}",
    )
    return figs, {"recipe": recipe, "maps": maps}


def bake_figure(ctx: Context) -> float:
    """The whole bake (every table, the HDF5 file written), timed; its seconds."""
    from hairlut.bake import registry

    recipe = _recipe(ctx)
    start = time.perf_counter()
    rep = registry.bake("hair_bsdf", recipe, ctx.workdir / "hair_bsdf.h5")
    sec = time.perf_counter() - start
    ctx.note(
        PART,
        f"the whole bake (dual_scattering, mean_energy and coverage on {' × '.join(map(str, recipe['grid']['resolution']))}, "
        f"the HDF5 file written): {sec:.2f} s, {rep['bytes'] / 2**20:.2f} MiB, largest error bound {rep['max_error']:.2e}",
    )
    return sec


def heat_map(maps: dict, recipe: dict):
    """A drawer of the roughness × absorption heat maps of max_sinθ |Monte Carlo − reference| (per scale) and
    of hairlut's, for :meth:`Context.image`."""

    def draw(path):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import LogNorm

        from ..assets import atomic_path

        keys = [*SCALES, "hairlut"]
        lo = max(1e-12, min(float(maps[k][maps[k] > 0].min(initial=1.0)) for k in keys))
        hi = max(float(maps[k].max()) for k in keys)
        fig, axes = plt.subplots(1, len(keys), figsize=(3.0 * len(keys) + 1, 3.4), dpi=110, sharey=True, layout="constrained")
        g, a = recipe["grid"], recipe["absorption"]
        extent = [*a[a["axis"]], *g["roughness"]]
        for ax, k in zip(axes, keys):
            im = ax.imshow(
                np.maximum(maps[k], lo), origin="lower", extent=extent, aspect="auto", norm=LogNorm(lo, hi), cmap="magma"
            )
            ax.set_title(f"Monte Carlo {k}×" if k != "hairlut" else "hairlut quadrature", fontsize=8)
            ax.set_xlabel(f"absorption ({a['axis']})", fontsize=7)
        axes[0].set_ylabel("roughness β", fontsize=7)
        fig.colorbar(im, ax=list(axes), shrink=0.85, label="max over sin θ of |error|")
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png")
        plt.close(fig)
        return path

    return draw


def run(ctx: Context) -> list[Figure]:
    figs = []
    for table in TABLES:
        got, data = table_figures(ctx, table)
        figs += got
        if table == "dual_scattering":
            ctx.image(PART, "dual_scattering: where the Monte Carlo table errs most", heat_map(data["maps"], data["recipe"]))
    bake_figure(ctx)
    ctx.note(
        PART,
        f"Monte Carlo on every {MC_STRIDE}th sin θ row (its error over those rows, its time scaled to the whole "
        "table); the reference is hairlut's quadrature with twice the nodes in every integration axis",
    )
    return figs
