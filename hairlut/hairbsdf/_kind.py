"""The ``hair_bsdf`` table kind: its declaration for :mod:`hairlut.bake.registry` (light: no JAX).

The bake splits over the sin θ rows of the (sin θ, roughness, absorption) grid: a part holds rows
[start, stop) of every grid table (value and error per entry), computed entry by entry, so a row's numbers
do not depend on how the rows were grouped.  The small coverage table is computed whole by the process that
writes the asset.  A recipe without grid tables (coverage only) bakes in one go.
"""

from __future__ import annotations

import math

from ..bake.protocol import Baker, Bound, Option, Units, deferred
from ._recipe import DUAL, ENERGY, SCHEMA, grid_tables, quantities, resolve_recipe

KIND = "hair_bsdf"
SHARD_KIND = "hair_bsdf_shard"
#: sin θ rows per resumable part (``OUT.parts/``): 8 parts of Unreal's 64 rows.
BLOCK = 8
#: Start-up of a bake: compiling the quadrature's row kernels (grid and coverage), seconds.
BAKE_OVERHEAD = 10.0
#: Grid entries (every quantity of one (sin θ, roughness, absorption) node, both tables) and coverage entries per
#: second, warm: measured on the 2-core development CPU under load (~5): 64 × 64 × 16 in 3.9 s, 64 × 64 coverage
#: entries in 3.9 s (``hairlut bench --only hair_bsdf`` reports the bake's time beside its error).
GRID_RATE = 1.7e4
COVERAGE_RATE = 1.0e3
#: The file's own bytes per dataset (HDF5 headers, dimension scales, attributes), measured on small tables.
DATASET_BYTES = 4096

#: The recipe keys that drive the tables (named when a table is refused).
KEYS = ("bsdf.eta", "bsdf.alpha", "grid.roughness", "absorption.axis", "quadrature.nodes", "quadrature.levels")


def _error(name: str) -> str:
    return f"{name}_error"


def _bounds() -> tuple[Bound, ...]:
    """One line per table: the physical reason each value lies where it does."""
    out = []
    for name, why in (
        ("A_f", "the energy a fibre scatters into the front half of azimuth is at most what arrives (a passive fibre)"),
        ("A_b", "the energy a fibre scatters into the back half of azimuth is at most what arrives"),
        ("R", "the R lobe carries the Fresnel-reflected share of the energy, at most all of it"),
        ("TT", "the TT lobe carries at most the energy that enters the fibre"),
        ("TRT", "the TRT lobe carries at most the energy that enters the fibre"),
        ("residual", "the lobes p ≥ 3 carry at most the energy that enters the fibre"),
        ("coverage", "a covered share of a pixel"),
    ):
        keys = ("coverage.radius", "coverage.strands", "quadrature.coverage_nodes") if name == "coverage" else KEYS
        out.append(Bound(name, 0.0, 1.0, keys=keys, text=f"0 ≤ {name} ≤ 1: {why}"))
    for name in ("alpha_f", "alpha_b"):
        out.append(Bound(name, -math.pi / 2, math.pi / 2, keys=KEYS, text=f"|{name}| ≤ π/2: a mean longitudinal angle"))
    for name in ("beta_f", "beta_b"):
        out.append(Bound(name, 0.0, None, keys=KEYS, text=f"{name} ≥ 0: a standard deviation"))
    for name in (*DUAL, *ENERGY, "coverage"):
        out.append(Bound(_error(name), 0.0, None, keys=KEYS, text=f"{_error(name)} ≥ 0: an error bound"))
    return tuple(out)


BOUNDS = _bounds()


def estimate(recipe: dict) -> tuple[int, float]:
    """(bytes, seconds) of a bake: the stored values and errors (uncompressed) and the file's own bytes per dataset,
    and the quadrature at the measured rates (:data:`GRID_RATE`, :data:`COVERAGE_RATE`) after its compilation."""
    r = resolve_recipe(recipe)
    item = {"float16": 2, "float32": 4, "float64": 8}[r["storage"]["dtype"]]
    n_s, n_r, n_a = r["grid"]["resolution"]
    grid = n_s * n_r * n_a if grid_tables(r) else 0
    cov = math.prod(r["coverage"]["resolution"]) if r["coverage"]["bake"] else 0
    err = max(item, 4)
    datasets = 2 * len(quantities(r)) + (1 + 3 if grid else 0) + (2 + 2 if cov else 0)  # tables, errors, σ_a, axes
    nbytes = grid * len(quantities(r)) * (item + err) + cov * (item + err) + 8 * n_r * n_a + DATASET_BYTES * datasets
    return int(nbytes), BAKE_OVERHEAD + grid / GRID_RATE + cov / COVERAGE_RATE


def _bake(name: str):
    return deferred(f"{__package__}._bake", name)


def _count(recipe: dict, **_) -> int:
    return recipe["grid"]["resolution"][0]


def describe(report: dict) -> list[str]:
    r = report["recipe"]
    g = r["grid"]
    rows = ""
    if report.get("unit_range") and report["kind"] == SHARD_KIND:
        lo, hi = report["unit_range"]
        rows = f", sin θ rows {lo}..{hi - 1} of {report['total_units']}"
    lines = [f"wrote {report['out']} ({report['kind']}{rows}, {report['bytes'] / 1024:.1f} KiB) in {report['seconds']:.2f} s"]
    tables = grid_tables(r)
    if tables:
        lines.append(
            f"  {' and '.join(tables)} on {' × '.join(map(str, g['resolution']))} (sin θ × roughness × "
            f"{r['absorption']['axis']}), {r['storage']['dtype']}"
        )
    if r["coverage"]["bake"]:
        lines.append(f"  coverage on {' × '.join(map(str, r['coverage']['resolution']))} (radius in pixels × strand count)")
    if report.get("max_error") is not None:
        lines.append(f"  largest estimated error of an entry: {report['max_error']:.2e}")
    if report.get("atlas"):
        lines.append(f"wrote {report['atlas']} (EXR atlas)")
    return lines


BAKER = Baker(
    kind=KIND,
    command="hair_bsdf",
    description="converged hair BSDF tables: dual scattering, mean lobe energy, strand coverage (Chiang 2016)",
    required=(),
    schema=SCHEMA,
    resolve_recipe=resolve_recipe,
    bake=_bake("bake_whole"),
    load=deferred(f"{__package__}._lookup", "load"),
    estimate=estimate,
    describe=describe,
    options=(
        Option(
            "atlas",
            "path",
            None,
            "Also write the tables as an EXR atlas (the 3-D tables' absorption slices tiled in 2-D; the layout in "
            "the header), as engines sample them.",
            cached=False,
        ),
    ),
    unit="sin θ rows",
    shard_kind=SHARD_KIND,
    shard_required=(),
    bounds=BOUNDS,
    assets=(("hair_bsdf_atlas", (), "EXR atlas of the hair_bsdf tables: 3-D tables as tiled 2-D slices, layout in the header"),),
    units=Units(
        "sin_theta",
        _count,
        *(_bake(f) for f in ("bake_part", "join_parts", "assemble_parts", "whole_parts")),
        block=BLOCK,
        check=_bake("check_part"),
        budget=_bake("budget"),
        index=_bake("part_index"),
        splits=lambda recipe: bool(grid_tables(recipe)),
        unsplit="a hair_bsdf recipe splits over the sin θ rows of its grid tables: bake dual_scattering or mean_energy",
        start=_bake("start"),
        report=_bake("report"),
        block_help=f"Default: {BLOCK}.",
    ),
    help="""Converged hair BSDF tables for real-time hair (Chiang et al. 2016's fibre; Zinke et al. 2008's dual
    scattering), with the estimated error of every entry.

    \b
    dual_scattering  A_f, A_b, alpha_f, alpha_b, beta_f, beta_b over (sin θ, roughness, absorption)
    mean_energy      R, TT, TRT, residual over the same grid (Unreal: 64 × 64 × 16)
    coverage         the pixel coverage of N strands over (radius in pixels, N)

    The values come from deterministic quadrature in θ and φ, not random sampling.  The HDF5 file
    opens in xarray; --atlas also writes the EXR atlas engines sample; in Python,
    `hairlut.hairbsdf.load(FILE).sample(...)` reads a value the way a GPU's bilinear sampler does.""",
    examples=(
        "hairlut bake hair_bsdf --out tables/hair_bsdf.h5 --atlas tables/hair_bsdf.exr",
        "hairlut bake hair_bsdf --set grid.resolution=[32,32,8] --set absorption.axis=sigma_a --out small.h5",
        "hairlut bake hair_bsdf --set storage.dtype=float16     # into the table cache (tables/)",
        "hairlut bake hair_bsdf --out h0.h5 --shard 0/2         # and 1/2; then",
        "hairlut merge h0.h5 h1.h5 --out hair_bsdf.h5",
    ),
)
