"""The ``hrir_db`` HDF5 asset (satf §4, §5.2), its shards, and EXR slices for inspection.

``hrir_db`` layout (axes in /axes; angles periodic with period 2π):

``features``      (sector, feature)   ρ_feature per sector (attr ``names``), the SATF index (eq 4)
``features_mean``, ``features_std`` (feature)   normalisation: z = (x − mean) / std
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
in float32, without features; :func:`assemble` turns the whole range into an ``hrir_db``.
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
from ..geometry.features import FeatureStats, feature_names, sector_features
from ._kind import KIND, SHARD_KIND
from ._tracer import GEOM

PARAMS = ("strands", "radius", "spread", "clumps", "aspect", "v_inner", "thickness", "s_u", "phase", "profile")

FRAME = ("local frame: origin at the sector's parametric centre, +x the outward ellipse normal (radial), "
         "+y the tangent (increasing phase); theta from +x toward the viewer / light; pixels span "
         "[-extent, extent] along the view direction rotated by +90 degrees")


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


def angles(n: int) -> np.ndarray:
    """The periodic angle grid 2πi/n, i = 0 … n − 1."""
    return 2 * np.pi * np.arange(n) / n


def _axes(recipe: dict, n: int, *, sector0: int = 0) -> list[Axis]:
    V, L = recipe["angles"]["views"], recipe["angles"]["lights"]
    P = recipe["trace"]["pixels"]
    n_s, n_r = recipe["sectors"]["grid"]
    return [
        Axis("sector", np.arange(sector0, sector0 + n, dtype=np.int64), "1",
             "sector index (its random draw depends on the seed and it alone)"),
        Axis("theta_v", angles(V), "rad", "in-plane view angle from the local +x axis", period=2 * np.pi),
        Axis("theta_l", angles(L), "rad", "in-plane light angle from the local +x axis", period=2 * np.pi),
        Axis("pixel", -1 + (np.arange(P) + 0.5) * 2 / P, "extent",
             "pixel centre along the image line, in units of the sector extent"),
        Axis("s", (np.arange(n_s) + 0.5) / n_s, "1", "density cell centre along the phase"),
        Axis("r", (np.arange(n_r) + 0.5) / n_r, "1", "density cell centre along the radius"),
    ]


def _per_sector(data: dict, dtype) -> list[Variable]:
    n, V, L, P = data["reflectance"].shape
    out = [
        Variable("alpha", data["alpha"].astype(dtype), ("sector", "theta_v", "pixel"), "1",
                 "accumulated opacity (eq 5), Gaussian-smoothed", chunks=(min(n, 16), V, P)),
        Variable("reflectance", data["reflectance"].astype(dtype), ("sector", "theta_v", "theta_l", "pixel"), "1",
                 "accumulated reflectance (eq 5, alpha-premultiplied), Gaussian-smoothed", chunks=(1, V, L, P)),
        Variable("density", data["density"].astype(np.float32), ("sector", "s", "r"), "1",
                 "sector density grid (area fraction times density_scale)", chunks=(min(n, 64), *data["density"].shape[1:])),
    ]
    out += [Variable(f"geometry/{c}", data["geometry"][:, i], ("sector",), "1", f"tracer frame column {c}")
            for i, c in enumerate(GEOM)]
    out += [Variable(f"sector/{p}", data["params"][p], ("sector",), "1", f"sampled sector parameter {p}") for p in PARAMS]
    return out


def write_shard(path, recipe: dict, data: dict, start: int, total: int, epoch: int | None = None) -> Path:
    """Write sectors [start, start + n) of a bake (float32) as an ``hrir_shard`` file."""
    n = len(data["alpha"])
    with _source_date(epoch):
        return write_table(path, SHARD_KIND, recipe, _axes(recipe, n, sector0=start), _per_sector(data, np.float32),
                           attrs={"sector_start": np.int64(start), "sector_stop": np.int64(start + n),
                                  "sector_total": np.int64(total)})


def read_shard(path, recipe_hash: str | None = None) -> tuple[dict, int, int, dict]:
    """(data, start, total, recipe) of a shard; checks the recipe hash when given."""
    t = read_table(path, kind=SHARD_KIND)
    if recipe_hash is not None and t.recipe_hash != recipe_hash:
        raise errors.CorruptAssetError(path, "baked from a different recipe")
    try:
        start, stop, total = (int(t.attrs[k]) for k in ("sector_start", "sector_stop", "sector_total"))
        data = {"alpha": t["alpha"], "reflectance": t["reflectance"], "density": t["density"],
                "geometry": np.stack([t[f"geometry/{c}"] for c in GEOM], axis=1),
                "params": {p: t[f"sector/{p}"] for p in PARAMS}}
    except KeyError as exc:
        raise errors.MissingDatasetError(path, f"shard lacks {exc}") from None
    if len(data["alpha"]) != stop - start:
        raise errors.CorruptAssetError(path, "sector range does not match the tables")
    return data, start, total, t.recipe


def concat(parts: list[dict]) -> dict:
    """Join per-sector data of consecutive parts."""
    out = {k: np.concatenate([p[k] for p in parts]) for k in ("alpha", "reflectance", "density", "geometry")}
    out["params"] = {k: np.concatenate([p["params"][k] for p in parts]) for k in PARAMS}
    return out


def _row_areas(data: dict, n_s: int, n_r: int) -> np.ndarray:
    g = data["geometry"]
    col = {c: g[:, i] for i, c in enumerate(GEOM)}
    edges = col["v0"][:, None] + (col["v1"] - col["v0"])[:, None] * np.linspace(0, 1, n_r + 1)[None, :]
    return (col["aspect"] * col["du"])[:, None] / n_s * 0.5 * np.diff(edges**2, axis=1)


def assemble(path, recipe: dict, data: dict, epoch: int | None = None) -> Path:
    """Index, normalise, cast and write a complete bake as an ``hrir_db`` asset."""
    n = len(data["alpha"])
    n_s, n_r = recipe["sectors"]["grid"]
    names = feature_names(recipe["sectors"]["features"])
    feats = sector_features(data["density"], _row_areas(data, n_s, n_r), names)
    if n >= 2:
        stats = FeatureStats.fit(feats, names)
    else:
        stats = FeatureStats(names, feats[0].copy(), np.ones(len(names)))
    dtype = np.dtype(recipe["storage"]["dtype"])
    err = {k: float(np.max(np.abs(data[k].astype(dtype).astype(np.float64) - data[k]))) for k in ("alpha", "reflectance")}
    axes = _axes(recipe, n) + [Axis("feature", np.arange(len(names), dtype=np.int32), "1", "feature: " + ",".join(names))]
    variables = [
        Variable("features", feats, ("sector", "feature"), "1", "density features rho_feature (satf 5.2)",
                 attrs={"names": json.dumps(list(names))}),
        Variable("features_mean", stats.mean, ("feature",), "1", "feature mean (normalisation)"),
        Variable("features_std", stats.std, ("feature",), "1", "feature standard deviation (normalisation)"),
        *_per_sector(data, dtype),
    ]
    attrs = {"n_sectors": np.int64(n), "feature_names": json.dumps(list(names)), "frame": FRAME,
             "storage_dtype": dtype.name, "storage_max_abs_error_alpha": err["alpha"],
             "storage_max_abs_error_reflectance": err["reflectance"]}
    with _source_date(epoch):
        return write_table(path, KIND, recipe, axes, variables, attrs=attrs)


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


def load_hrir_db(path) -> HRIRDB:
    """Read and validate an ``hrir_db`` asset."""
    t = read_table(path, kind=KIND)
    try:
        names = tuple(json.loads(t.attrs["feature_names"]))
        stats = FeatureStats(names, t["features_mean"], t["features_std"])
        return HRIRDB(t["features"], stats, t.axes["theta_v"].values, t.axes["theta_l"].values, t["alpha"],
                      t["reflectance"], t["density"], {c: t[f"geometry/{c}"] for c in GEOM},
                      {p: t[f"sector/{p}"] for p in PARAMS}, t.recipe, dict(t.attrs))
    except KeyError as exc:
        raise errors.MissingDatasetError(path, f"hrir_db lacks {exc}") from None


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
