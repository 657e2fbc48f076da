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
#: Monte Carlo on every MC_STRIDE-th sin θ row (its time scaled to the whole table); ``--quick``: QUICK_STRIDE.
MC_STRIDE = 8
QUICK_STRIDE = 4
#: Sample counts of the Monte Carlo runs, in multiples of Unreal's.
SCALES = (1, 4, 16)
#: The quantities each table's figures compare (Unreal's tables hold these).
TABLES = {
    "dual_scattering": ("A_f", "A_b"),
    "mean_energy": ("R", "TT", "TRT"),
}
#: Every quantity of each table (the quadrature's own error is reported over these).
EVERY = {
    "dual_scattering": ("A_f", "A_b", "alpha_f", "alpha_b", "beta_f", "beta_b"),
    "mean_energy": ("R", "TT", "TRT", "residual"),
}


def _recipe(ctx: Context, coverage: bool = False) -> dict:
    from hairlut.hairbsdf import resolve_recipe

    res = [16, 16, 4] if ctx.quick else [64, 64, 16]
    return resolve_recipe({"grid": {"resolution": res}, "coverage": {"bake": coverage}})


def _diff(got: dict, ref: dict, names, rows=slice(None)) -> np.ndarray:
    """max over ``names`` of |got − ref| per entry."""
    return np.max([np.abs(np.asarray(got[n], np.float64) - ref[n][rows]) for n in names], axis=0)


def _timed(fn, *args, **kwargs) -> tuple[float, object]:
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    return time.perf_counter() - start, out


def study(ctx: Context) -> dict:
    """Both grid tables on Unreal's grid: hairlut's quadrature (timed, warm), the 2× reference, and the Monte Carlo
    at each of :data:`SCALES` on every stride-th sin θ row (timed warm, scaled to the whole table).  The quadrature
    and the Monte Carlo each compute both tables in one pass, so one time serves both."""
    from hairlut.hairbsdf import grid_rows, montecarlo_rows

    recipe = _recipe(ctx)
    n_s = recipe["grid"]["resolution"][0]
    grid_rows(recipe, 0, 1)  # compile
    sec, (values, errs) = _timed(grid_rows, recipe, 0, n_s)
    ctx.progress(f"{PART}: quadrature {sec:.1f} s; the reference at twice the nodes")
    grid_rows(recipe, 0, 1, refine=2)
    ref_sec, (ref, _) = _timed(grid_rows, recipe, 0, n_s, refine=2)
    rows = np.arange(0, n_s, QUICK_STRIDE if ctx.quick else MC_STRIDE)
    mc = {}
    for k in SCALES:
        ctx.progress(f"{PART}: Monte Carlo at {k}× Unreal's counts on {len(rows)} of {n_s} sin θ rows")
        montecarlo_rows(recipe, 0, 1, scale=k)  # compile at this sample count
        spent, got = 0.0, []
        for r in rows:
            s, one = _timed(montecarlo_rows, recipe, int(r), int(r) + 1, scale=k)
            spent += s
            got.append(one)
        mc[k] = (spent * n_s / len(rows), {n: np.concatenate([g[n] for g in got]) for n in got[0]})
    return {"recipe": recipe, "seconds": sec, "ref_seconds": ref_sec, "values": values, "errors": errs, "ref": ref,
            "rows": rows, "mc": mc}  # fmt: skip


def table_figures(data: dict, table: str) -> list[Figure]:
    """One table's figures: Monte Carlo at 1×, 4×, 16× (the first the baseline: Unreal's own setting), hairlut's
    quadrature, and its storage in float32 and float16, each against the 2× reference."""
    names, ref, rows, recipe = TABLES[table], data["ref"], data["rows"], data["recipe"]
    title = f"{table}: {', '.join(names)} against a quadrature with twice the nodes"
    figs = []
    for k, (sec, got) in data["mc"].items():
        diff = _diff(got, ref, names, rows)
        figs.append(
            Figure(
                PART,
                title,
                f"Unreal-style Monte Carlo, {k}× Unreal's counts",
                sec,
                float(diff.max()),
                "max |error|",
                {"samples": f"{k}×"},
                baseline=k == 1,
                paper=k == 1,
                extra={"rows_measured": int(len(rows)), "mean_abs_error": float(diff.mean())},
            )
        )
    diff = _diff(data["values"], ref, names)
    figs.append(
        Figure(
            PART,
            title,
            "hairlut quadrature (converged)",
            data["seconds"],
            float(diff.max()),
            "max |error|",
            {"nodes": recipe["quadrature"]["nodes"], "levels": recipe["quadrature"]["levels"]},
            extra={
                "mean_abs_error": float(diff.mean()),
                "largest_estimated_error": max(float(data["errors"][n].max()) for n in names),
            },
        )
    )
    for dtype in ("float32", "float16"):
        stored = {n: data["values"][n].astype(dtype) for n in names}
        figs.append(
            Figure(PART, title, f"hairlut, stored as {dtype}", None, float(_diff(stored, ref, names).max()), "max |error|",
                   {"storage": dtype})
        )  # fmt: skip
    return figs


def bake_note(ctx: Context) -> None:
    """The whole bake (every table, the HDF5 file written), warm, timed, with its largest error bound."""
    from hairlut.bake import registry

    recipe = _recipe(ctx, coverage=True)
    rep = registry.bake(PART, recipe, ctx.workdir / "hair_bsdf.h5")
    ctx.note(
        PART,
        f"the whole bake (dual_scattering, mean_energy on {' × '.join(map(str, recipe['grid']['resolution']))} and "
        f"coverage on {' × '.join(map(str, recipe['coverage']['resolution']))}, the HDF5 file written; the row "
        f"kernels already compiled): {rep['seconds']:.2f} s, {rep['bytes'] / 2**20:.2f} MiB, largest error bound "
        f"{rep['max_error']:.2e}",
    )


def heat_map(data: dict):
    """A drawer of the roughness × absorption heat maps of max over sin θ and the table's quantities of
    |Monte Carlo − reference| (per sample count) and |hairlut − reference|, a row per table, for
    :meth:`Context.image`."""
    ref, rows, recipe = data["ref"], data["rows"], data["recipe"]
    maps = {}
    for table, names in TABLES.items():
        maps[table] = {k: _diff(got, ref, names, rows).max(axis=0) for k, (_, got) in data["mc"].items()}
        maps[table]["hairlut"] = _diff(data["values"], ref, names).max(axis=0)

    def draw(path):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import LogNorm

        from ..assets import atomic_path

        keys = [*SCALES, "hairlut"]
        every = [m for t in maps.values() for m in t.values()]
        lo = max(1e-12, min(float(m[m > 0].min(initial=1.0)) for m in every))
        hi = max(float(m.max()) for m in every)
        fig, axes = plt.subplots(
            len(maps), len(keys), figsize=(3.0 * len(keys) + 1, 3.0 * len(maps)), dpi=110, sharex=True, sharey=True,
            layout="constrained", squeeze=False,
        )  # fmt: skip
        g, a = recipe["grid"], recipe["absorption"]
        extent = [*a[a["axis"]], *g["roughness"]]
        for row, (table, m) in zip(axes, maps.items()):
            for ax, k in zip(row, keys):
                im = ax.imshow(
                    np.maximum(m[k], lo), origin="lower", extent=extent, aspect="auto", norm=LogNorm(lo, hi), cmap="magma"
                )
                who = f"Monte Carlo {k}×" if k != "hairlut" else "hairlut quadrature"
                ax.set_title(f"{table}: {who}", fontsize=7)
            row[0].set_ylabel("roughness β", fontsize=7)
        for ax in axes[-1]:
            ax.set_xlabel(f"absorption ({a['axis']})", fontsize=7)
        fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.85, label="max over sin θ of |error|")
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png")
        plt.close(fig)
        return path

    return draw


def run(ctx: Context) -> list[Figure]:
    data = study(ctx)
    figs = [f for table in TABLES for f in table_figures(data, table)]
    ctx.image(PART, "where the Monte Carlo tables err most", heat_map(data))
    for table, names in EVERY.items():
        ctx.note(
            PART,
            f"{table}: hairlut's quadrature against the 2× reference over every quantity ({', '.join(names)}): max |error| "
            f"{float(_diff(data['values'], data['ref'], names).max()):.2e}; its own largest error estimate "
            f"{max(float(data['errors'][n].max()) for n in names):.2e}",
        )
    bake_note(ctx)
    stride = QUICK_STRIDE if ctx.quick else MC_STRIDE
    ctx.note(
        PART,
        f"one pass of the quadrature computes both tables ({data['seconds']:.2f} s warm; the 2× reference "
        f"{data['ref_seconds']:.2f} s), and so does one pass of the Monte Carlo: each table's rows show that time.  "
        f"The Monte Carlo runs on every {stride}th sin θ row (its error over those rows, its warm time scaled to the "
        "whole table); the reference is hairlut's quadrature with twice the Gauss–Legendre nodes per panel in every "
        "integration axis",
    )
    return figs
