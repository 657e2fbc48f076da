"""The ``scene_maps`` recipe: the HRIR trace settings, the table layout and the groom's geometry key.

A recipe is ``{"hrir": {...}, "table": {...}, "geometry": {...}}``:

* ``hrir``: the trace, Phong and density-grid settings (an ``hrir_db`` recipe's ``sectors.grid``,
  ``sectors.density_scale``, ``trace`` and ``phong``; ``hairlut.hrir.resolve_recipe`` checks them);
* ``table``: ``views`` V (even: α is stored on V/2 of them, the mirror symmetry gives the rest),
  ``lights`` L (the light-angle grid of the bake; L ≥ 2·terms + 1 so the kept terms do not alias),
  ``terms`` K (Fourier terms of the re/α ratio in θl − θv: 2K + 1 coefficients), ``ratio_step`` (the
  terms are kept on every ratio_step-th view: V / ratio_step of them; on Sintel 32 of 64 views cost re
  0.139 → 0.144 for half the ratio's bytes, ``benchmarks/scene_layouts.py``), ``shading_pixels``
  Q (pixel bins of the ratio, a divisor of trace.pixels), ``dtype`` (float16 or float32), and how the
  bake computes them (``hairlut.march.bake_view_grid``): ``alpha_grid`` m (α projected through an m × m
  Cartesian resampling of each sector's density, one matrix product for every view; 0: the tracer's
  own march per view, ``hairlut.march.trace_view_grid``, the reference), ``shade_rays`` and
  ``shade_steps`` (the re/α march's rays per pixel and steps; 0: the trace's; with alpha_grid 0 the
  trace's always);
* ``geometry``: ``sha256``, the groom's identity (:func:`geometry_key`), folded in from the keyed
  input ``scene`` (so a different groom, fit or strand set is a different asset).

Light: no JAX.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from .. import errors
from ..files import regular_file
from ..recipes import Field, resolve

SCHEMA = {
    "hrir": Field({}, (dict,), None, "hrir_db recipe keys (sectors.grid, sectors.density_scale, trace, phong)"),
    "table": {
        "views": Field(
            64,
            (int,),
            lambda v: None if 8 <= v <= 1024 and v % 2 == 0 else "an even number in [8, 1024]",
            "view angles θv = 2πi/V",
        ),
        "lights": Field(
            9, (int,), lambda v: None if 1 <= v <= 1024 else "must lie in [1, 1024]", "light angles of the bake θl = 2πj/L"
        ),
        "terms": Field(
            2, (int,), lambda v: None if 0 <= v <= 16 else "must lie in [0, 16]", "Fourier terms K of the re/α ratio in θl − θv"
        ),
        "ratio_step": Field(
            2,
            (int,),
            lambda v: None if v >= 1 else "must be ≥ 1",
            "the re/α terms are stored on every ratio_step-th view (linear in θv between them)",
        ),
        "shading_pixels": Field(8, (int,), lambda v: None if v >= 1 else "must be ≥ 1", "pixel bins Q of the ratio"),
        "dtype": Field(
            "float16", (str,), lambda v: None if v in ("float16", "float32") else "use float16 or float32", "storage precision"
        ),
        "alpha_grid": Field(
            0,
            (int,),
            lambda v: None if v == 0 or 2 <= v <= 256 else "0 or in [2, 256]",
            "side m of the Cartesian node grid α is projected through (0: the tracer's march per view)",
        ),
        "shade_rays": Field(
            0,
            (int,),
            lambda v: None if 0 <= v <= 64 else "must lie in [0, 64]",
            "rays per pixel of the re/α march (0: trace.rays_per_pixel)",
        ),
        "shade_steps": Field(
            0,
            (int,),
            lambda v: None if v == 0 or 2 <= v <= 4096 else "0 or in [2, 4096]",
            "steps of the re/α march (0: trace.steps)",
        ),
    },
    "geometry": {"sha256": Field("", (str,), None, "the groom's geometry key (hairlut.scenemaps.geometry_key)")},
}

#: The parts of an hrir_db recipe a scene table uses.
HRIR_PARTS = ("trace", "phong")


def hrir_recipe(recipe: dict) -> dict:
    """The full ``hrir_db`` recipe (defaults made explicit) of a scene-maps recipe's ``hrir`` part."""
    from ..hrir import resolve_recipe as resolve_hrir

    try:
        return resolve_hrir(dict(recipe.get("hrir", {})))
    except errors.ValidationError as exc:
        raise errors.ValidationError(f"hrir.{exc.field}", exc.value, exc.reason) from None


#: The last few groom files' digests, by their identity (path, device, inode, size, modification and change times):
#: a plan and a render ask for a scene's geometry key several times, and a production groom is tens of MB to hash.
_SHA256: dict = {}


def _file_sha256(path) -> str:
    path = regular_file(path, "a groom file")
    st = os.stat(path)
    ident = (os.path.abspath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    if ident not in _SHA256:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        while len(_SHA256) >= 8:
            _SHA256.pop(next(iter(_SHA256)))
        _SHA256[ident] = h.hexdigest()
    return _SHA256[ident]


def geometry_key(scene) -> str:
    """SHA-256 of what fixes a scene's sectors and strands: the groom file's bytes and the ``[groom]``
    fit settings, or the ``[[clusters]]`` tables and ``[strands]`` settings, and the code that fits and cuts them
    (``hairlut.scene.code_digest``: a hairlut whose fit or sectors changed does not reuse an old table).  Camera,
    lights, material and render settings do not enter it (they do not move a strand)."""
    from ..scene import as_scene, code_digest

    sc = as_scene(scene)
    if sc.groom_path is not None:
        doc = {
            "groom": {k: v for k, v in sc.config["groom"].items() if k != "path"},
            "file_sha256": _file_sha256(Path(sc.groom_path)),
        }
    else:
        doc = {"clusters": sc.raw.get("clusters"), "strands": sc.config["strands"]}
    doc["code"] = code_digest(backend=False)  # a recipe is resolved before a distributed bake starts JAX
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()


def resolve_recipe(given: dict | None = None, *, scene=None) -> dict:
    """Every default made explicit (idempotent); ``scene`` (a Scene, mapping or path) folds its
    :func:`geometry_key` into ``geometry.sha256``.  Raises ValidationError naming the key."""
    r = resolve(SCHEMA, dict(given or {}))
    full = hrir_recipe(r)
    r["hrir"] = {
        "sectors": {"grid": list(full["sectors"]["grid"]), "density_scale": float(full["sectors"]["density_scale"])},
        **{k: dict(full[k]) for k in HRIR_PARTS},
    }
    t, P = r["table"], full["trace"]["pixels"]
    if t["lights"] < 2 * t["terms"] + 1:
        raise errors.ValidationError("table.lights", t["lights"], f"need ≥ 2·terms + 1 = {2 * t['terms'] + 1} light angles")
    if t["views"] % t["ratio_step"]:
        raise errors.ValidationError("table.ratio_step", t["ratio_step"], f"must divide table.views ({t['views']})")
    if P % t["shading_pixels"]:
        raise errors.ValidationError("table.shading_pixels", t["shading_pixels"], f"must divide trace.pixels ({P})")
    if scene is not None:
        r["geometry"] = {"sha256": geometry_key(scene)}
    return r
