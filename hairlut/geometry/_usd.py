"""USD files (``.usda``, ``.usdc``, ``.usd``) holding ``UsdGeom.BasisCurves``; needs the optional ``usd-core``.

Mapping between ``Strands`` and a linear, non-periodic BasisCurves prim:

- ``points`` ↔ ``points`` (point3f, so float32), ``counts`` ↔ ``curveVertexCounts``;
- ``thickness`` ↔ ``widths`` (per vertex when written; constant and per-curve widths are spread on read);
- ``color`` ↔ ``primvars:displayColor``, ``transparency`` ↔ 1 − ``primvars:displayOpacity``;
- ``uv`` ↔ ``primvars:st`` (per curve), ``movable`` ↔ ``primvars:hairlut:movable`` (per vertex).

Reading gathers every BasisCurves prim in the stage, in world space, one after
another; an attribute survives only when every prim has it.  Cubic curves are
refused: their points are control points, not a polyline.  Writing makes one
prim, ``/hair/strands``, under a Y-up stage whose default prim is ``/hair``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import AssetError, CorruptAssetError, FormatError, MissingDependencyError, ValidationError
from ..files import regular_file
from ._binio import as_f32, build
from .strands import Strands

SUFFIXES = (".usda", ".usdc", ".usd")


def _pxr(path):
    """The pxr modules, or a hairlut error that says how to get them."""
    try:
        from pxr import Gf, Sdf, Tf, Usd, UsdGeom, Vt
    except ImportError as exc:
        raise MissingDependencyError(
            path, f"USD files need the optional package usd-core (pip install usd-core); importing pxr failed: {exc}"
        ) from None
    return Gf, Sdf, Tf, Usd, UsdGeom, Vt


def _tf_message(exc: Exception) -> str:
    """The first readable line of a pxr error."""
    for line in str(exc).splitlines():
        line = line.strip()
        if line:
            return line.rsplit(" : ", 1)[-1].strip("'")
    return type(exc).__name__


def _spread(values: np.ndarray, interpolation: str, counts: np.ndarray, n_points: int, what: str, path) -> np.ndarray:
    """Per-point values from constant, per-curve (uniform) or per-vertex data."""
    if interpolation == "constant" and len(values) == 1:
        return np.repeat(values, n_points, axis=0)
    if interpolation == "uniform" and len(values) == len(counts):
        return np.repeat(values, counts, axis=0)
    if interpolation in ("vertex", "varying") and len(values) == n_points:
        return values
    raise CorruptAssetError(
        path,
        f"{what}: {len(values)} values with interpolation {interpolation!r} do not fit {len(counts)} curves of {n_points} points",
    )


def _curves_fields(prim, path, usd) -> dict:
    Gf, Sdf, Tf, Usd, UsdGeom, Vt = usd
    curves = UsdGeom.BasisCurves(prim)
    where = f"{prim.GetPath()}"
    time = Usd.TimeCode.EarliestTime()
    kind = curves.GetTypeAttr().Get()
    if kind != UsdGeom.Tokens.linear:
        raise FormatError(path, f"{where} holds {kind} ({curves.GetBasisAttr().Get()}) curves; only linear curves are read")
    pts, counts = curves.GetPointsAttr().Get(time), curves.GetCurveVertexCountsAttr().Get(time)
    if pts is None or counts is None:
        raise CorruptAssetError(path, f"{where} has no points or no curveVertexCounts")
    points = np.asarray(pts, dtype=np.float32).reshape(-1, 3)
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    if counts.min(initial=2) < 0 or counts.sum() != len(points):
        raise CorruptAssetError(path, f"{where}: curveVertexCounts add up to {int(counts.sum())}, points has {len(points)}")
    matrix = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time)
    if matrix != Gf.Matrix4d(1):
        m = np.array(matrix)
        points = points @ m[:3, :3] + m[3, :3]
    fields = {"points": points, "counts": counts}
    widths = curves.GetWidthsAttr().Get(time)
    if widths is not None and (len(widths) or not len(points)):  # an empty widths array on curves means none
        fields["thickness"] = _spread(
            np.asarray(widths, dtype=np.float32), curves.GetWidthsInterpolation(), counts, len(points), f"{where} widths", path
        )
    primvars = UsdGeom.PrimvarsAPI(prim)
    for name, key in (
        ("displayColor", "color"),
        ("displayOpacity", "transparency"),
        ("hairlut:movable", "movable"),
        ("st", "uv"),
    ):
        pv = primvars.GetPrimvar(name)
        if not (pv and pv.HasValue()):
            continue
        values = np.asarray(pv.ComputeFlattened(time))
        if key == "uv":
            if pv.GetInterpolation() != "uniform" or len(values) != len(counts):
                continue  # texture coordinates per vertex are not a per-strand UV
            fields[key] = values.astype(np.float32).reshape(-1, 2)
            continue
        values = _spread(values, pv.GetInterpolation(), counts, len(points), f"{where} {name}", path)
        fields[key] = 1.0 - values.astype(np.float32) if key == "transparency" else values
    return fields


def read_usd(path: str | os.PathLike) -> Strands:
    """Read every linear BasisCurves prim of a USD stage as one set of strands."""
    usd = _pxr(path)
    Gf, Sdf, Tf, Usd, UsdGeom, Vt = usd
    regular_file(path, "a USD stage")  # a missing file, a folder, a FIFO or a device: before USD opens it
    try:
        stage = Usd.Stage.Open(os.fspath(path))
    except Tf.ErrorException as exc:
        raise FormatError(path, f"USD cannot open it: {_tf_message(exc)}") from None
    prims = [p for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)]
    if not prims:
        raise FormatError(path, "the stage holds no UsdGeom.BasisCurves prim")
    parts = [_curves_fields(p, path, usd) for p in prims]
    fields = {"points": np.concatenate([f["points"] for f in parts]), "counts": np.concatenate([f["counts"] for f in parts])}
    for key in ("thickness", "transparency", "color", "uv", "movable"):
        if all(key in f for f in parts):
            fields[key] = np.concatenate([f[key] for f in parts])
    return build(path, **fields)


def _stage(strands: Strands, usd):
    Gf, Sdf, Tf, Usd, UsdGeom, Vt = usd
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    root = UsdGeom.Xform.Define(stage, "/hair")
    stage.SetDefaultPrim(root.GetPrim())
    curves = UsdGeom.BasisCurves.Define(stage, "/hair/strands")
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
    points = Vt.Vec3fArray.FromNumpy(as_f32("points", strands.points))
    curves.CreatePointsAttr(points)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(strands.counts.astype(np.int32)))
    widths = Vt.FloatArray()
    if strands.thickness is not None:
        widths = Vt.FloatArray.FromNumpy(as_f32("thickness", strands.thickness))
        curves.CreateWidthsAttr(widths)
        curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    if strands.n_points:
        curves.CreateExtentAttr(UsdGeom.Curves.ComputeExtent(points, widths))
    vertex, uniform = UsdGeom.Tokens.vertex, UsdGeom.Tokens.uniform
    if strands.color is not None:
        curves.CreateDisplayColorPrimvar(vertex).Set(Vt.Vec3fArray.FromNumpy(as_f32("color", strands.color)))
    if strands.transparency is not None:
        opacity = 1.0 - strands.transparency.astype(np.float32)
        curves.CreateDisplayOpacityPrimvar(vertex).Set(Vt.FloatArray.FromNumpy(opacity))
    primvars = UsdGeom.PrimvarsAPI(curves.GetPrim())
    if strands.uv is not None:
        st = primvars.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, uniform)
        st.Set(Vt.Vec2fArray.FromNumpy(as_f32("uv", strands.uv)))
    if strands.movable is not None:
        mov = primvars.CreatePrimvar("hairlut:movable", Sdf.ValueTypeNames.BoolArray, vertex)
        mov.Set(Vt.BoolArray.FromNumpy(strands.movable))
    return stage


def write_usd(path: str | os.PathLike, strands: Strands) -> None:
    """Write ``strands`` as one linear BasisCurves prim; ``.usd`` files are binary (crate), like ``.usdc``."""
    usd = _pxr(path)
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIXES:
        raise ValidationError("path", os.fspath(path), f"not a USD file name; use one of {', '.join(SUFFIXES)}")
    stage = _stage(strands, usd)
    with atomic_path(path) as tmp:
        # USD picks the file format from the name, so export beside the temporary file under a USD suffix.
        staging = tmp.with_name(tmp.name + (".usda" if suffix == ".usda" else ".usdc"))
        try:
            if not stage.GetRootLayer().Export(os.fspath(staging)):
                raise AssetError(path, "USD could not export the layer")
            os.replace(staging, tmp)
        finally:
            staging.unlink(missing_ok=True)
