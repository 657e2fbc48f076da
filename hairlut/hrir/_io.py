"""The ``hrir_db`` HDF5 asset (satf §4, §5.2), its shards, and EXR slices for inspection.

``hrir_db`` layout (axes in /axes; angles periodic with period 2π):

``features``      (sector, feature)   ρ_feature per sector (attr ``names``), the SATF index (eq 4)
``features_mean``, ``features_std`` (feature)   normalisation: z = (x − mean) / std
``projection_mean`` (projection_bin), ``projection_components`` (feature, projection_bin)
                  only for ``sectors.features = "projection"``: the basis of the projection
                  profiles the features are scores on (``hairlut.hrir._projection``); files of
                  the other feature sets have neither and still read
``alpha``         (sector, theta_v, pixel)             accumulated opacity α_acc (eq 5), smoothed
``reflectance``   (sector, theta_v, theta_l, pixel)    accumulated reflectance re_acc (premultiplied)
``density``       (sector, s, r)      the traced density grid
``geometry/<c>``  (sector)            the tracer's frame columns (``hairlut.hrir._tracer.GEOM``)
``sector/<p>``    (sector)            the sampled generation parameters

``reflectance`` is chunked one sector's (V, L, P) block at a time, the unit of a lookup.
Root attributes record the storage dtype and the largest absolute error the storage
dtype adds to each table (0 for float32: the tracer computes in float32), the frame
conventions and the feature names.  ``hrir_shard`` files (a bake's parts and the
output of ``--shard``) hold the same per-sector tables for sectors [start, stop),
in the storage dtype (with the storage errors they add), without features; :func:`assemble`
turns the whole range into an ``hrir_db`` (what a virtual ``hrir_db`` stores itself comes from
``_parts``).
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import Axis, Variable, read_table, write_exr, write_table
from ..assets.h5 import HDF5_SIGNATURE, check_file, data_fault
from ..assets.trust import finite_fault
from ..assets.virtual_write import check_virtual
from ..geometry import angle_grid as angles
from ..geometry.features import PROJECTION, FeatureStats, PCABasis, feature_names, sector_features
from ..march import GEOM
from ._kind import KIND, SHARD_KIND

PARAMS = ("strands", "radius_rel", "spread", "clumps", "aspect", "v_inner", "radial_extent", "s_u", "phase", "profile")

FRAME = (
    "local frame: origin at the sector's parametric centre, +x the outward ellipse normal (radial), "
    "+y the tangent (increasing phase); theta from +x toward the viewer / light; pixels span "
    "[-extent, extent] along the view direction rotated by +90 degrees"
)


@contextlib.contextmanager
def _source_date(epoch: int | None):
    """``created`` from SOURCE_DATE_EPOCH: the caller's, else ``epoch``, else 0 (deterministic files)."""
    old = os.environ.get("SOURCE_DATE_EPOCH")
    os.environ["SOURCE_DATE_EPOCH"] = old if old is not None else str(int(epoch or 0))
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("SOURCE_DATE_EPOCH", None)


def _axes(recipe: dict, n: int, *, sector0: int = 0) -> list[Axis]:
    V, L = recipe["angles"]["views"], recipe["angles"]["lights"]
    P = recipe["trace"]["pixels"]
    n_s, n_r = recipe["sectors"]["grid"]
    return [
        Axis(
            "sector",
            np.arange(sector0, sector0 + n, dtype=np.int64),
            "1",
            "sector index (its random draw depends on the seed and it alone)",
        ),
        Axis("theta_v", angles(V), "rad", "in-plane view angle from the local +x axis", period=2 * np.pi),
        Axis("theta_l", angles(L), "rad", "in-plane light angle from the local +x axis", period=2 * np.pi),
        Axis(
            "pixel",
            -1 + (np.arange(P) + 0.5) * 2 / P,
            "extent",
            "pixel centre along the image line, in units of the sector extent",
        ),
        Axis("s", (np.arange(n_s) + 0.5) / n_s, "1", "density cell centre along the phase"),
        Axis("r", (np.arange(n_r) + 0.5) / n_r, "1", "density cell centre along the radius"),
    ]


def _per_sector(data: dict, dtype) -> list[Variable]:
    n, V, L, P = data["reflectance"].shape
    out = [
        Variable(
            "alpha",
            data["alpha"].astype(dtype, copy=False),
            ("sector", "theta_v", "pixel"),
            "1",
            "accumulated opacity (eq 5), Gaussian-smoothed",
            chunks=(min(n, 16), V, P),
        ),
        Variable(
            "reflectance",
            data["reflectance"].astype(dtype, copy=False),
            ("sector", "theta_v", "theta_l", "pixel"),
            "1",
            "accumulated reflectance (eq 5, alpha-premultiplied), Gaussian-smoothed",
            chunks=(1, V, L, P),
        ),
        Variable(
            "density",
            data["density"].astype(np.float32),
            ("sector", "s", "r"),
            "1",
            "sector density grid (area fraction times density_scale)",
            chunks=(min(n, 64), *data["density"].shape[1:]),
        ),
    ]
    out += [
        Variable(f"geometry/{c}", data["geometry"][:, i], ("sector",), "1", f"tracer frame column {c}")
        for i, c in enumerate(GEOM)
    ]
    out += [Variable(f"sector/{p}", data["params"][p], ("sector",), "1", f"sampled sector parameter {p}") for p in PARAMS]
    return out


def storage_errors(recipe: dict, data: dict, stored: dict | None = None) -> dict:
    """The largest absolute error the recipe's storage dtype adds to the float32 α and reflectance (``stored``: the
    tables already cast).  A float32 value less its float16 rounding is exact in float32 (Sterbenz; 0 and ±inf
    aside), so float32 data is differenced in float32: the same maxima as in float64, a third of the host's time."""
    dtype = np.dtype(recipe["storage"]["dtype"])
    stored = stored or {}
    out = {}
    for k in ("alpha", "reflectance"):
        x = data[k]
        cast = stored[k] if k in stored else x.astype(dtype)
        wide = np.float32 if x.dtype == np.float32 else np.float64
        out[k] = float(np.max(np.abs(cast.astype(wide) - x)))
    return out


def write_shard(
    path, recipe: dict, data: dict, start: int, total: int, epoch: int | None = None, errors_: dict | None = None
) -> Path:
    """Write sectors [start, start + n) of a bake as an ``hrir_shard`` file, α and reflectance in the storage dtype.

    ``errors_``: the storage errors of data already cast (else measured here from float32 data)."""
    n = len(data["alpha"])
    dtype = np.dtype(recipe["storage"]["dtype"])
    stored = {k: data[k].astype(dtype, copy=False) for k in ("alpha", "reflectance")}  # cast once
    err = storage_errors(recipe, data, stored) if errors_ is None else errors_
    with _source_date(epoch):
        return write_table(
            path,
            SHARD_KIND,
            recipe,
            _axes(recipe, n, sector0=start),
            _per_sector({**data, **stored}, dtype),
            attrs={
                "sector_start": np.int64(start),
                "sector_stop": np.int64(start + n),
                "sector_total": np.int64(total),
                "storage_max_abs_error_alpha": err["alpha"],
                "storage_max_abs_error_reflectance": err["reflectance"],
            },
        )


def read_shard(path, recipe_hash: str | None = None) -> tuple[dict, int, int, dict]:
    """(data, start, total, recipe) of a shard; checks the recipe hash when given.

    ``data["errors"]`` holds the storage errors the shard records."""
    t = read_table(path, kind=SHARD_KIND)
    if recipe_hash is not None and t.recipe_hash != recipe_hash:
        raise errors.CorruptAssetError(path, "baked from a different recipe")
    try:
        start, stop, total = (int(t.attrs[k]) for k in ("sector_start", "sector_stop", "sector_total"))
        data = {
            "alpha": t["alpha"],
            "reflectance": t["reflectance"],
            "density": t["density"],
            "geometry": np.stack([t[f"geometry/{c}"] for c in GEOM], axis=1),
            "params": {p: t[f"sector/{p}"] for p in PARAMS},
            "errors": {k: float(t.attrs[f"storage_max_abs_error_{k}"]) for k in ("alpha", "reflectance")},
        }
    except KeyError as exc:
        raise errors.MissingDatasetError(path, f"shard lacks {exc}") from None
    if len(data["alpha"]) != stop - start:
        raise errors.CorruptAssetError(path, "sector range does not match the tables")
    return data, start, total, t.recipe


def concat(parts: list[dict]) -> dict:
    """Join per-sector data of consecutive parts."""
    out = {k: np.concatenate([p[k] for p in parts]) for k in ("alpha", "reflectance", "density", "geometry")}
    out["params"] = {k: np.concatenate([p["params"][k] for p in parts]) for k in PARAMS}
    if all("errors" in p for p in parts):
        out["errors"] = {k: max(p["errors"][k] for p in parts) for k in ("alpha", "reflectance")}
    return out


def _row_areas(data: dict, n_s: int, n_r: int) -> np.ndarray:
    g = data["geometry"]
    col = {c: g[:, i] for i, c in enumerate(GEOM)}
    edges = col["v0"][:, None] + (col["v1"] - col["v0"])[:, None] * np.linspace(0, 1, n_r + 1)[None, :]
    return (col["aspect"] * col["du"])[:, None] / n_s * 0.5 * np.diff(edges**2, axis=1)


#: Sectors per feature chunk: the index's features are computed in chunks aligned at multiples of this (of fewer for a
#: smaller database), so a process computes its own parts' features bit for bit as the whole (``_parts.part_features``).
FEATURE_CHUNK = 256


def _index(recipe: dict, data: dict, n: int) -> tuple[list[Axis], list[Variable], dict]:
    """The whole-database part of an ``hrir_db``: axes, the feature index (satf §5.2) and root attributes."""
    n_s, n_r = recipe["sectors"]["grid"]
    names = feature_names(recipe["sectors"]["features"])
    extra, extra_attrs = [], {}
    if names == PROJECTION:
        from ._projection import fit_projection, projection_settings, sector_projections

        basis, feats, stats = fit_projection(
            sector_projections(data["density"], data["geometry"], n_steps=recipe["trace"]["steps"])
        )
        extra = [
            Variable("projection_mean", basis.mean, ("projection_bin",), "1", "mean projection profile"),
            Variable(
                "projection_components",
                basis.components,
                ("feature", "projection_bin"),
                "1",
                "principal components of the projection profiles (zero rows pad a small database)",
            ),
        ]
        extra_attrs = {"projection": json.dumps(projection_settings(recipe))}
    else:
        feats = (
            data["features"]
            if "features" in data
            else sector_features(data["density"], _row_areas(data, n_s, n_r), names, chunk=FEATURE_CHUNK)
        )
        if n >= 2:
            stats = FeatureStats.fit(feats, names)
        else:
            stats = FeatureStats(names, feats[0].copy(), np.ones(len(names)))
    dtype = np.dtype(recipe["storage"]["dtype"])
    err = data["errors"] if "errors" in data else storage_errors(recipe, data)
    axes = _axes(recipe, n) + [Axis("feature", np.arange(len(names), dtype=np.int32), "1", "feature: " + ",".join(names))]
    if extra:
        axes.append(
            Axis(
                "projection_bin",
                np.arange(len(extra[0].data), dtype=np.int32),
                "1",
                "projection profile bin: direction-major (direction, bin along the image line)",
            )
        )
    variables = [
        Variable(
            "features",
            feats,
            ("sector", "feature"),
            "1",
            "density features rho_feature (satf 5.2)",
            attrs={"names": json.dumps(list(names))},
        ),
        Variable("features_mean", stats.mean, ("feature",), "1", "feature mean (normalisation)"),
        Variable("features_std", stats.std, ("feature",), "1", "feature standard deviation (normalisation)"),
        *extra,
    ]
    attrs = {
        **extra_attrs,
        "n_sectors": np.int64(n),
        "feature_names": json.dumps(list(names)),
        "frame": FRAME,
        "storage_dtype": dtype.name,
        "storage_max_abs_error_alpha": err["alpha"],
        "storage_max_abs_error_reflectance": err["reflectance"],
    }
    return axes, variables, attrs


def assemble(path, recipe: dict, data: dict, epoch: int | None = None) -> Path:
    """Index, normalise, cast and write a complete bake as an ``hrir_db`` asset."""
    n = len(data["alpha"])
    axes, variables, attrs = _index(recipe, data, n)
    variables += _per_sector(data, np.dtype(recipe["storage"]["dtype"]))
    with _source_date(epoch):
        return write_table(path, KIND, recipe, axes, variables, attrs=attrs)


def _read(path, ds) -> np.ndarray:
    """A dataset's values, finite (a checksum or data fault names the file and dataset)."""
    try:
        values = ds[()]
    except OSError as exc:
        raise data_fault(path, ds, exc) from None
    bad = finite_fault(values)
    if bad:
        raise errors.CorruptAssetError(path, f"table {ds.name!r} holds non-finite values ({bad})")
    return values


@dataclass(frozen=True, eq=False)
class HRIRDB:
    """An HRIR database in memory: SATF(feature, θv, θl) records (eq 4)."""

    features: np.ndarray
    stats: FeatureStats
    theta_v: np.ndarray
    theta_l: np.ndarray
    alpha: np.ndarray
    reflectance: np.ndarray
    density: np.ndarray
    geometry: dict
    params: dict
    recipe: dict
    attrs: dict
    #: the projection profiles' basis (``hairlut.geometry.PCABasis``) of a ``projection``-indexed database, else None
    projection: PCABasis | None = None

    @classmethod
    def load(cls, path) -> HRIRDB:
        """Read and validate an ``hrir_db`` asset."""
        return load_hrir_db(path)

    @functools.cached_property
    def device_arrays(self):
        """(normalised features, α, reflectance) as float32 device arrays, made once per database."""
        from ._query import device_arrays

        return device_arrays(self)

    def query(self, features, theta_v, theta_l, k: int = 4):
        """SATF lookup (eq 4): (re, α, neighbour index, weights); see :func:`hairlut.hrir.satf_query`."""
        from ._query import satf_query

        return satf_query(self, features, theta_v, theta_l, k)


def _check_contents(path, t) -> tuple[str, ...]:
    """The feature names, after checking that every table has the shape the stored recipe implies.

    A file whose checksums pass but whose contents disagree with its recipe (a raised
    angle count, another grid, feature names that are not JSON) raises
    CorruptAssetError naming the table, before any query can index out of range."""
    from ._recipe import resolve_recipe

    try:
        r = resolve_recipe(t.recipe, budget=False)
    except errors.ValidationError as exc:
        raise errors.CorruptAssetError(path, f"stored recipe is not valid: {exc}") from None
    try:
        names = json.loads(t.attrs["feature_names"])
    except KeyError:
        raise errors.MissingDatasetError(path, "root attribute 'feature_names' is missing") from None
    except (TypeError, ValueError, UnicodeError) as exc:
        raise errors.CorruptAssetError(path, f"root attribute 'feature_names' is not JSON ({exc})") from None
    try:
        want_names = list(feature_names(r["sectors"]["features"]))
    except errors.ValidationError as exc:
        raise errors.CorruptAssetError(path, f"stored recipe: {exc}") from None
    if names != want_names:
        raise errors.CorruptAssetError(
            path, f"root attribute 'feature_names' is {str(names)[:80]}, the recipe's features give {want_names}"
        )
    V, L, P = r["angles"]["views"], r["angles"]["lights"], r["trace"]["pixels"]
    n_s, n_r = r["sectors"]["grid"]
    if "alpha" not in t.variables or t["alpha"].ndim < 1:
        raise errors.MissingDatasetError(path, "hrir_db lacks 'alpha'")
    n, F = t["alpha"].shape[0], len(names)
    want = {
        "features": (n, F),
        "features_mean": (F,),
        "features_std": (F,),
        "alpha": (n, V, P),
        "reflectance": (n, V, L, P),
        "density": (n, n_s, n_r),
        **{f"geometry/{c}": (n,) for c in GEOM},
        **{f"sector/{p}": (n,) for p in PARAMS},
    }
    for name, shape in want.items():
        if name not in t.variables:
            raise errors.MissingDatasetError(path, f"hrir_db lacks {name!r}")
        if t[name].shape != shape:
            raise errors.CorruptAssetError(
                path,
                f"table {name!r} has shape {t[name].shape}, the recipe "
                f"(views {V}, lights {L}, pixels {P}, grid {n_s}×{n_r}, {F} features) "
                f"needs {shape}",
            )
    if tuple(names) == PROJECTION:
        from ._projection import projection_settings

        m = projection_settings(r)["profile"]
        want = {"projection_mean": (m,), "projection_components": (F, m)}
        for name, shape in want.items():
            if name not in t.variables:
                raise errors.MissingDatasetError(path, f"a projection-indexed hrir_db lacks {name!r}")
            if t[name].shape != shape:
                raise errors.CorruptAssetError(path, f"table {name!r} has shape {t[name].shape}, need {shape}")
    for axis, size in (("theta_v", V), ("theta_l", L)):
        if axis not in t.axes or len(t.axes[axis].values) != size:
            raise errors.CorruptAssetError(path, f"axis {axis!r} does not have the recipe's {size} values")
    if not np.all(t["features_std"] > 0):
        raise errors.CorruptAssetError(path, "table 'features_std' holds values ≤ 0 (normalisation divides by it)")
    return tuple(names)


def load_hrir_db(path) -> HRIRDB:
    """Read and validate an ``hrir_db`` asset (a virtual one with its parts)."""
    check_file(path, HDF5_SIGNATURE, "an HDF5 file")
    check_virtual(path)
    t = read_table(path, kind=KIND)
    try:
        names = _check_contents(path, t)
        stats = FeatureStats(names, t["features_mean"], t["features_std"])
        basis = (
            PCABasis(
                (1, len(t["projection_mean"])),
                np.asarray(t["projection_mean"], np.float64),
                np.asarray(t["projection_components"], np.float64),
            )
            if names == PROJECTION
            else None
        )
        return HRIRDB(
            t["features"],
            stats,
            t.axes["theta_v"].values,
            t.axes["theta_l"].values,
            t["alpha"],
            t["reflectance"],
            t["density"],
            {c: t[f"geometry/{c}"] for c in GEOM},
            {p: t[f"sector/{p}"] for p in PARAMS},
            t.recipe,
            dict(t.attrs),
            basis,
        )
    except KeyError as exc:
        raise errors.MissingDatasetError(path, f"hrir_db lacks {exc}") from None


def reindex(db_path, out, features: str) -> Path:
    """The ``hrir_db`` at ``db_path`` with another feature index (``sectors.features``: "basic", "moments" or
    "projection"), written atomically to ``out``: the per-sector tables are copied, not traced again, so the
    file is the one a bake of the changed recipe writes (the index is computed from the same density and
    geometry rows)."""
    from ._recipe import resolve_recipe

    db = load_hrir_db(db_path)
    recipe = resolve_recipe({**db.recipe, "sectors": {**db.recipe["sectors"], "features": features}}, budget=False)
    data = {
        "alpha": db.alpha,
        "reflectance": db.reflectance,
        "density": db.density,
        "geometry": np.stack([db.geometry[c] for c in GEOM], axis=1),
        "params": db.params,
        "errors": {k: float(db.attrs[f"storage_max_abs_error_{k}"]) for k in ("alpha", "reflectance")},
    }
    return assemble(out, recipe, data)


def export_slice(db_path, out, sector: int, light: int) -> Path:
    """EXR of one sector under one light: rows = view angles, columns = pixels; Y = reflectance, A = alpha."""
    db = load_hrir_db(db_path)
    n, V, L, P = db.reflectance.shape
    if isinstance(sector, bool) or not 0 <= int(sector) < n:
        raise errors.ValidationError("sector", sector, f"need 0 ≤ sector < {n}")
    if isinstance(light, bool) or not 0 <= int(light) < L:
        raise errors.ValidationError("light", light, f"need 0 ≤ light < {L}")
    img = {"Y": db.reflectance[sector, :, light, :].astype(np.float32), "A": db.alpha[sector].astype(np.float32)}
    rec = {"source": db.recipe, "sector": int(sector), "light": int(light), "theta_l": float(db.theta_l[light])}
    return write_exr(out, img, recipe=rec, kind="hrir_slice")
