"""The scene planner: the assets a scene needs, what the cache already holds, and the work it skips.

:func:`plan` reads a scene (:mod:`hairlut.scene` format) and decides, rule by rule, each in words:

* **Map method** (``[render] method``, :func:`map_method`): ``direct``, ``scene`` or ``satf``; ``auto``
  picks by device (a GPU: direct), motion (moving hair on a CPU: satf) and memory (static hair on a
  CPU: the per-groom ``scene_maps`` table when it fits in a quarter of the memory), and says why.
  The scene table is baked only for ``scene``, content-addressed by the groom's geometry and recipe.
* **HRIR database** (only for the ``satf`` map method, which reads it).  Its recipe is the
  defaults with ``[tables.hrir]`` over them; with ``tables.restrict`` (the default) the
  sampled sector space is fitted to the scene's own sectors (phase steps s_u exactly;
  aspect, inner radius, radial extent, strand count and relative strand radius over their ranges in
  the scene, widened by a margin): narrower where the scene uses less of the default
  space, so the same N records cover its features more densely, and wider where its
  sectors fall outside the defaults, which would not cover them.  A cached database is reused when its recipe hash matches, or
  when it differs only in a sector space that contains the scene's.  The in-plane view
  and light angles the scene's sectors produce are measured on the database's grid
  (with the neighbouring node bilinear interpolation reads); the grid is periodic, so the
  full circle is baked and the coverage is reported.
* **SH tables** only with an environment light: p = p_I sets the light bands,
  ceil(√p) + 1, i.e. (√p + 1)² coefficients (xing §4), and the specular energy left
  beyond them is reported; ks_I = ks_II = 0 (or both highlights off) bakes no Rs, kd = 0
  no Rd.  The light is projected (its hash is part of the recipe), so a new map re-bakes.
* **Voxel SH transmittance** only when an environment light and ``self_shadow`` are on.
* **Online work**: each shading term whose switch is off or whose coefficient is zero
  is skipped (no secondary highlight → none of its lighting or noise), and the uniformity
  test's fetch count follows k_threshold.
* **Hair BSDF tables** (``hair_bsdf``) only when the scene asks for them (``[tables] hair_bsdf = true``, or a
  table of recipe keys): an engine's Marschner-family hair shading reads them, hairlut's own online
  module (Kajiya–Kay) does not, so otherwise nothing reads them and the step is skipped, saying so.
* **Shadows** (``[shadows] method``): eq 12's s-map (``s_map``; off with k_shadow = 0 or
  ``effects.shadow`` off), or a light-oriented density map / opacity shadow maps per light
  (``shadow_maps``; built per scene in ``prepare``, rebuilt when the lights change), or none.

:func:`bake` carries a plan out through :mod:`hairlut.bake.registry` (and its cache) without
naming a kind; :func:`find_assets` gives the cached assets of a scene to ``synthesize``
without baking.  A bake's size and time are its kind's ``estimate`` (throughputs measured by
``benchmarks/hrir_bake.py`` and the plan part of ``hairlut bench`` on the 2-core development CPU;
that part reports them beside the real times).
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from .. import errors
from ..assets import recipe_hash
from ..bake import cache, registry
from ..scene import (
    as_scene,
    scene_sectors,
)
from ._steps import (
    Step,
    _choice_steps,
    _hair_bsdf_step,
    _hrir_step,
    _map_steps,
    _online_steps,
    _sh_step,
    _transmittance_step,
)


@dataclass(frozen=True)
class Plan:
    """What :func:`plan` decided for ``scene``: its :class:`Step` s in order (``step(name)`` finds one) and the
    table cache they refer to; ``to_json()`` is the plan as ``hairlut plan --json`` prints it, with the totals
    to bake and to reuse."""

    scene: object
    steps: tuple
    cache_dir: str

    def step(self, name: str) -> Step:
        """The step called ``name`` (``hrir_db``, ``sh_tables``, ``map_method``, …)."""
        return next(s for s in self.steps if s.name == name)

    def to_json(self) -> dict:
        """The plan as ``hairlut plan --json`` prints it: the steps (without their bake inputs) and the bake/reuse
        totals."""
        return {
            "scene": self.scene.source,
            "cache": self.cache_dir,
            "steps": [{k: v for k, v in asdict(s).items() if k != "inputs"} for s in self.steps],
            "totals": {
                "bake_seconds": sum(s.seconds for s in self.steps if s.action == "bake"),
                "bake_bytes": sum(s.bytes for s in self.steps if s.action == "bake"),
                "reused_bytes": sum(s.bytes for s in self.steps if s.action == "reuse"),
            },
        }


def plan(scene, cache_root=None) -> Plan:
    """Decide, rule by rule, what ``scene`` needs (module docstring)."""
    sc = as_scene(scene)
    root = cache.cache_dir(cache_root)
    ss = scene_sectors(sc, root)
    method, map_steps = _map_steps(sc, ss, root)
    hrir = (
        _hrir_step(sc, ss, root)
        if method == "satf"
        else Step("hrir_db", "skip", f"the maps come from {method!r}: no SATF database is read")
    )
    online = _online_steps(sc)
    if method != "satf":
        online = [
            s
            if s.name != "uniformity"
            else Step("uniformity", "skip", f"{method!r} maps: every HSV sweeps its two sectors' own rows (eq 7), no eq 6 test")
            for s in online
        ]
    steps = [
        *_choice_steps(sc, ss),
        *map_steps,
        hrir,
        _sh_step(sc, root),
        _transmittance_step(sc),
        _hair_bsdf_step(sc, root),
        *online,
    ]
    return Plan(sc, tuple(steps), str(root))


# ----------------------------------------------------------------------------- carrying it out


def bake(p: Plan, progress=None) -> dict[str, dict]:
    """Bake (or reuse) every asset step of a plan through the registry and the cache;
    ``progress(name, done, total)``.  No kind is named here: each step carries its kind,
    recipe and keyed inputs.

    Returns {name: {"path", "status", "seconds"}} for the asset steps that are not skipped."""
    out = {}
    for s in p.steps:
        if s.kind is None or s.action == "skip":
            continue
        t0 = time.perf_counter()
        if s.action == "reuse":
            path, status = Path(s.path), "reused"
        else:
            cb = (lambda d, n, name=s.name: progress(name, d, n)) if progress else None
            path, status = registry.ensure(s.kind, s.recipe, p.cache_dir, cb, **s.inputs)
        out[s.name] = {"path": str(path), "status": status, "seconds": time.perf_counter() - t0}
    return out


def find_assets(scene, cache_root=None) -> dict[str, Path]:
    """The cached assets a scene needs, without baking: {"hrir_db" or "scene_maps": path[, "sh_tables": path]}
    (none of the two for the ``direct`` map method).

    Raises :class:`~hairlut.errors.AssetNotFoundError` naming the missing asset and the command that bakes it."""
    p = plan(scene, cache_root)
    out = {}
    for s in p.steps:
        if s.kind is None or s.action == "skip" or not s.online:
            continue
        if s.action != "reuse":
            bake_it = f"run `hairlut bake --scene {p.scene.source}` (or give its path)"
            if os.path.lexists(s.path):  # there, but unusable: say why rather than "not in the cache"
                try:
                    cache.check(Path(s.path), s.kind, recipe_hash(s.recipe))
                except errors.AssetError as exc:
                    why = exc.fault if exc.path == s.path else str(exc)  # a part's fault names the part
                    raise errors.CorruptAssetError(
                        s.path, f"the scene's cached {s.kind} is unusable ({why}); {bake_it} to bake it again"
                    ) from None
            raise errors.AssetNotFoundError(s.path, f"the scene's {s.kind} is not in the cache; {bake_it}")
        out[s.name] = Path(s.path)
    return out


def scene_assets(scene, cache_root=None, *, db=None, sh=None) -> tuple[str | None, str | None, str | None]:
    """(hrir_db, sh_tables, scene_maps) paths for rendering ``scene``: the given ``db``/``sh`` paths,
    and from the cache (:func:`find_assets`) what is missing; a scene table only when no database is
    given.  Paths are strings, ``None`` where the scene needs no such table."""
    maps = None
    if db is None or (sh is None and scene.environment is not None):
        found = find_assets(scene, cache_root)
        db = db or (str(found["hrir_db"]) if "hrir_db" in found else None)
        maps = str(found["scene_maps"]) if "scene_maps" in found and db is None else None
        sh = sh or (str(found["sh_tables"]) if "sh_tables" in found else None)
    return db, sh, maps
