"""Writing and reading the ``hair_bsdf`` HDF5 asset and its parts.

Layout (schema 2, every table at the root, so ``xarray.open_dataset(path, engine="h5netcdf")`` opens the
whole file as one Dataset with the axes as coordinates)::

    /sin_theta, /roughness, /absorption      axes of the grid tables (texel-centre nodes)
    /radius, /strands                        axes of the coverage table
    /A_f … /beta_b, /R … /residual           (sin_theta, roughness, absorption) values, the storage dtype
    /<name>_error                            the same dims: a bound of |stored − exact| per entry
    /sigma_a                                 (roughness, absorption) σ_a at each node (float64)
    /coverage, /coverage_error               (radius, strands)

Each ``<name>_error`` is the quadrature's own estimate of the entry's error plus the rounding of the stored
value, rounded up to its dtype: the stored value lies within it of the exact integral.

The grid tables (``sin_theta`` first) are what a bake splits (:mod:`hairlut.bake.sharding`): a
``hair_bsdf_shard`` file (a part in ``<out>.parts/``, or the output of ``--shard``) holds the sin θ rows
[sin_theta_start, sin_theta_stop) of them; a virtual asset maps them over the parts and stores the rest itself
(:func:`whole_tables`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import errors
from ..assets import Axis, Variable, read_table, write_table
from ._kind import KIND, SHARD_KIND
from ._recipe import grid_axes, quantities

GRID_DIMS = ("sin_theta", "roughness", "absorption")
COVERAGE_DIMS = ("radius", "strands")

_LONG = {
    "A_f": "average forward attenuation A_f: the energy into the front half of azimuth (Zinke et al. 2008, eq. 12)",
    "A_b": "average backward attenuation A_b: the energy into the back half of azimuth (Zinke et al. 2008, eq. 12)",
    "alpha_f": "average longitudinal shift of forward scattering, radians (Zinke et al. 2008, §4)",
    "alpha_b": "average longitudinal shift of backward scattering, radians (Zinke et al. 2008, §4)",
    "beta_f": "average longitudinal standard deviation of forward scattering, radians (Zinke et al. 2008, §4)",
    "beta_b": "average longitudinal standard deviation of backward scattering, radians (Zinke et al. 2008, §4)",
    "R": "mean energy of the R lobe (p = 0): its directional albedo, averaged over the fibre's width",
    "TT": "mean energy of the TT lobe (p = 1)",
    "TRT": "mean energy of the TRT lobe (p = 2)",
    "residual": "mean energy of the residual lobe (every p ≥ 3)",
    "coverage": "expected covered share of a pixel by N strands at random positions and orientations",
}
_UNITS = {"alpha_f": "rad", "alpha_b": "rad", "beta_f": "rad", "beta_b": "rad"}


def stored(values, dtype) -> tuple[np.ndarray, np.ndarray]:
    """(values in ``dtype``, |stored − exact| in float64) of float64 ``values``."""
    exact = np.asarray(values, np.float64)
    kept = exact.astype(dtype)
    return kept, np.abs(kept.astype(np.float64) - exact)


def error_store(error, rounding, dtype) -> np.ndarray:
    """The stored error bound: quadrature estimate + rounding, in float32 (float64 storage: float64), rounded up."""
    total = np.asarray(error, np.float64) + rounding
    et = np.float64 if np.dtype(dtype) == np.float64 else np.float32
    kept = total.astype(et)
    return np.where(kept.astype(np.float64) < total, np.nextafter(kept, et(np.inf)), kept).astype(et)


def _axes(recipe: dict, start: int = 0, stop: int | None = None, *, grid: bool = True, coverage: bool = False) -> list[Axis]:
    ax = grid_axes(recipe)
    a = recipe["absorption"]
    out = []
    if grid:
        out += [
            Axis("sin_theta", ax["sin_theta"][start:stop], "1", "sin θ_o of the outgoing direction (cell centres)"),
            Axis("roughness", ax["roughness"], "1", "roughness β = β_m = β_n (cell centres)"),
            Axis(
                "absorption",
                ax["absorption"],
                "1" if a["axis"] == "colour" else "1/radius",
                "perceptual hair colour c (Unreal's): linear colour c², σ_a by Chiang et al. 2016, eq. 9 at β_n = roughness"
                if a["axis"] == "colour"
                else "σ_a per unit fibre radius",
            ),
        ]
    if coverage:
        out += [
            Axis("radius", ax["radius"], "px", "strand radius in pixels (cell centres)"),
            Axis("strands", ax["strands"], "1", "number of strands N crossing the pixel (cell centres)"),
        ]
    return out


def _grid_variables(recipe: dict, values: dict, errors_: dict) -> list[Variable]:
    """The grid tables (``sin_theta`` first) in the storage dtype, with their error bounds."""
    dtype = np.dtype(recipe["storage"]["dtype"])
    out = []
    for name in quantities(recipe):
        kept, rounding = stored(values[name], dtype)
        n = kept.shape
        chunks = (min(8, n[0]), n[1], n[2])
        out.append(Variable(name, kept, GRID_DIMS, _UNITS.get(name, "1"), _LONG[name], chunks=chunks))
        out.append(
            Variable(
                f"{name}_error",
                error_store(errors_[name], rounding, dtype),
                GRID_DIMS,
                _UNITS.get(name, "1"),
                f"bound of |stored − exact| of {name}: quadrature estimate plus storage rounding",
                chunks=chunks,
            )
        )
    return out


def coverage_variables(recipe: dict, values, errors_) -> list[Variable]:
    dtype = np.dtype(recipe["storage"]["dtype"])
    kept, rounding = stored(values, dtype)
    return [
        Variable("coverage", kept, COVERAGE_DIMS, "1", _LONG["coverage"]),
        Variable("coverage_error", error_store(errors_, rounding, dtype), COVERAGE_DIMS, "1", "bound of |stored − exact|"),
    ]


def whole_tables(recipe: dict, coverage: tuple | None, max_error: float | None, sigma_a=None):
    """(axes, variables, attrs): everything a ``hair_bsdf`` asset stores besides its grid tables: the axes, σ_a
    at the grid's (roughness, absorption) nodes (``sigma_a``, when it has grid tables), the coverage table
    (``coverage``: (values, errors) or None) and the largest error."""
    grid = bool(quantities(recipe))
    axes = _axes(recipe, grid=grid, coverage=coverage is not None)
    variables = []
    if grid:
        variables.append(
            Variable("sigma_a", np.asarray(sigma_a, np.float64), ("roughness", "absorption"), "1/radius", "σ_a at each node")
        )
    if coverage is not None:
        variables += coverage_variables(recipe, *coverage)
    attrs = {"max_error": float(max_error)} if max_error is not None else {}
    return axes, variables, attrs


def write_asset(path, recipe: dict, grid: tuple[dict, dict] | None, coverage: tuple | None, sigma_a=None) -> Path:
    """Write the ``hair_bsdf`` asset: ``grid`` = ({name: values}, {name: errors}) of every sin θ row (float64),
    ``coverage`` = (values, errors) or None, ``sigma_a`` at the grid's nodes."""
    grid_vars = _grid_variables(recipe, *grid) if grid else []
    axes, variables, _ = whole_tables(recipe, coverage, None, sigma_a)
    return write_table(path, KIND, recipe, axes, grid_vars + variables, attrs={"max_error": _largest(grid_vars + variables)})


def write_part(path, recipe: dict, values: dict, errors_: dict, start: int, total: int) -> Path:
    """sin θ rows [start, start + n) of a bake as a ``hair_bsdf_shard`` file."""
    n = len(next(iter(values.values())))
    variables = _grid_variables(recipe, values, errors_)
    attrs = {
        "sin_theta_start": np.int64(start),
        "sin_theta_stop": np.int64(start + n),
        "sin_theta_total": np.int64(total),
        "max_error": _largest(variables),
    }
    return write_table(path, SHARD_KIND, recipe, _axes(recipe, start, start + n), variables, attrs=attrs)


def _largest(variables: list[Variable]) -> float:
    """The largest stored error bound of ``variables``."""
    return max((float(np.max(v.data, initial=0.0)) for v in variables if v.name.endswith("_error")), default=0.0)


def read_part(path, recipe: dict) -> tuple[dict, dict, int, int, float]:
    """({name: stored values}, {name: stored errors}, start, total, max error) of a ``hair_bsdf_shard`` of
    ``recipe`` (every grid table the recipe bakes)."""
    t = read_table(path, kind=SHARD_KIND)
    try:
        start, stop, total = (int(t.attrs[f"sin_theta_{k}"]) for k in ("start", "stop", "total"))
        values = {q: t[q] for q in quantities(recipe)}
        errs = {q: t[f"{q}_error"] for q in quantities(recipe)}
        top = float(t.attrs["max_error"])
    except KeyError as exc:
        raise errors.MissingDatasetError(path, f"hair_bsdf_shard lacks {exc}") from None
    shape = (stop - start, *recipe["grid"]["resolution"][1:])
    bad = [q for q, v in values.items() if v.shape != shape] + [q for q, v in errs.items() if v.shape != shape]
    if bad:
        raise errors.CorruptAssetError(path, f"tables {bad} are not of shape {shape} (sin θ rows {start}..{stop})")
    return values, errs, start, total, top


def concat(read: list) -> tuple[dict, dict]:
    """The grid tables of consecutive parts (as :func:`read_part` returns them), joined."""
    values = {q: np.concatenate([r[0][q] for r in read]) for q in read[0][0]}
    errs = {q: np.concatenate([r[1][q] for r in read]) for q in read[0][1]}
    return values, errs


def write_joined(path, recipe: dict, read: list) -> Path:
    """Consecutive parts as one ``hair_bsdf_shard`` file, their stored values and errors copied as they are."""
    values, errs = concat(read)
    attrs = {
        "sin_theta_start": np.int64(read[0][2]),
        "sin_theta_stop": np.int64(read[0][2] + len(next(iter(values.values())))),
        "sin_theta_total": np.int64(read[0][3]),
        "max_error": max(r[4] for r in read),
    }
    return write_table(path, SHARD_KIND, recipe, _axes(recipe, attrs["sin_theta_start"], attrs["sin_theta_stop"]),
                       _stored_variables(values, errs), attrs=attrs)  # fmt: skip


def _stored_variables(values: dict, errs: dict) -> list[Variable]:
    """Grid tables already in their stored dtypes (copied from parts)."""
    out = []
    for name, v in values.items():
        chunks = (min(8, v.shape[0]), *v.shape[1:])
        out.append(Variable(name, v, GRID_DIMS, _UNITS.get(name, "1"), _LONG[name], chunks=chunks))
        out.append(
            Variable(
                f"{name}_error",
                errs[name],
                GRID_DIMS,
                _UNITS.get(name, "1"),
                f"bound of |stored − exact| of {name}: quadrature estimate plus storage rounding",
                chunks=chunks,
            )
        )
    return out


def write_assembled(path, recipe: dict, read: list, coverage: tuple | None, sigma_a) -> Path:
    """Parts covering every sin θ row (and the coverage table) as one self-contained ``hair_bsdf`` asset."""
    values, errs = concat(read)
    axes, variables, _ = whole_tables(recipe, coverage, None, sigma_a)
    top = max([r[4] for r in read] + [_largest(variables)])
    return write_table(path, KIND, recipe, axes, _stored_variables(values, errs) + variables, attrs={"max_error": top})
