"""The kind registry: every table kind hairlut bakes, one line each.

``BAKERS`` maps a kind to the module whose ``BAKER`` (a :class:`hairlut.bake.protocol.Baker`)
declares it; the module is imported on first use, so ``import hairlut`` stays light
and only the kinds in use are loaded.  Adding a table kind is one subpackage with a
``BAKER`` and one line here; the CLI (``hairlut bake KIND``, ``merge``, ``inspect``),
the cache and the planner find it through :func:`get`.

Importing a declaration also declares its asset kinds (the table, its shard kind and
any other kind the subpackage writes, such as ``sh_light``) to ``hairlut.assets``, which
asks :func:`declare` when a reader meets a kind not declared yet.
"""

from __future__ import annotations

import time
from importlib import import_module
from pathlib import Path

from .. import errors
from .protocol import Baker, prepare

#: kind → module holding its ``BAKER``.  One line per kind.
BAKERS: dict[str, str] = {
    "hrir_db": "hairlut.hrir",
    "sh_tables": "hairlut.shtables",
    "scene_maps": "hairlut.scenemaps",
    "hair_bsdf": "hairlut.hairbsdf",
}


def get(kind: str) -> Baker:
    """The baker of a kind, by kind name (``sh_tables``) or command name (``sh``)."""
    for name, module in BAKERS.items():
        if kind == name:
            return _load(name, module)
    for name, module in BAKERS.items():
        baker = _load(name, module)
        if kind == baker.command:
            return baker
    names = ", ".join(f"{get(k).command} ({k})" for k in BAKERS)
    raise errors.ValidationError("kind", kind, f"unknown table kind; known: {names}")


def _load(name: str, module: str) -> Baker:
    baker = getattr(import_module(module), "BAKER", None)
    if not isinstance(baker, Baker) or baker.kind != name:
        raise errors.ValidationError("kind", name, f"{module}.BAKER does not declare the {name} baker")
    return baker


def kinds() -> list[str]:
    """The registered table kinds, in registry order."""
    return list(BAKERS)


def bakers() -> list[Baker]:
    return [get(k) for k in BAKERS]


def declare(name: str) -> None:
    """Declare asset kind ``name`` to ``hairlut.assets`` (all kinds when it is no table kind)."""
    if name in BAKERS:
        get(name)
    else:
        declare_all()


def declare_all() -> None:
    for name in BAKERS:
        get(name)


def for_shard_kind(shard_kind: str) -> Baker:
    """The baker whose shards are of kind ``shard_kind``."""
    for baker in bakers():
        if baker.shard_kind == shard_kind:
            return baker
    raise errors.ValidationError("shards", shard_kind, "no registered kind merges shards of this kind")


def kind_of(path) -> str:
    """The ``kind`` attribute of a validated table file."""
    from ..assets import open_table

    with open_table(path) as f:
        k = f.attrs["kind"]
        return k.decode() if isinstance(k, bytes) else str(k)


def merge(shards, out) -> dict:
    """Join shard files into one asset with the merge of the kind that wrote them."""
    if not shards:
        raise errors.ValidationError("shards", list(shards), "give at least one shard")
    from . import sharding

    baker = for_shard_kind(kind_of(shards[0]))
    return baker.merge(list(shards), out) if baker.merge is not None else sharding.merge(baker, list(shards), out)


def describe(kind: str) -> str | None:
    """The description of an asset kind (a table, shard or other kind hairlut writes), or None."""
    from ..assets.kinds import KINDS

    return KINDS[kind].description if kind in KINDS else None


def ensure(kind: str, recipe: dict | None = None, root=None, progress=None, **inputs) -> tuple[Path, str]:
    """The cached asset of ``kind`` for ``recipe`` (plus keyed ``inputs``, e.g. ``light=``), baked if needed.

    Returns (path, status) with status ``"reused"`` or ``"baked"``; see :mod:`hairlut.bake.cache`."""
    return bake_cached(kind, recipe, root=root, progress=progress, **inputs)[:2]


def bake_cached(
    kind: str, recipe: dict | None = None, *, root=None, progress=None, options=None, **inputs
) -> tuple[Path, str, dict]:
    """:func:`ensure` with the bake report (or, when reused, a report of the cached file)."""
    from ..assets import recipe_hash
    from . import cache, sharding

    baker = get(kind)
    r, kwargs = prepare(baker, recipe, {**(options or {}), **inputs})
    for opt in baker.options:
        if not opt.cached and kwargs.get(opt.name) is not None:
            raise errors.ValidationError(opt.name, kwargs[opt.name], "give an output file too (it is not cached)")
    report = {}
    t0 = time.perf_counter()

    def produce(path):
        report.update(sharding.bake(baker, r, path, progress=progress, **kwargs))

    path, status = cache.ensure(baker.kind, r, produce, root)
    if status == "reused":
        report = {
            "out": str(path),
            "kind": baker.kind,
            "recipe": r,
            "recipe_hash": recipe_hash(r),
            "bytes": path.stat().st_size,
            "seconds": time.perf_counter() - t0,
        }
    return path, status, report


def bake(
    kind: str, recipe: dict | None, out, *, progress=None, shard=None, options=None, distributed=False, merge=None, **inputs
) -> dict:
    """Bake ``kind`` into ``out`` (no cache): :func:`prepare`, then the split path of a kind that declares units
    (``shard`` 'K/N'; ``distributed``: this process is one of JAX's distributed processes; ``merge`` 'virtual'
    or 'copy'; :mod:`hairlut.bake.sharding`) or the kind's own bake."""
    from . import sharding

    baker = get(kind)
    r, kwargs = prepare(baker, recipe, {**(options or {}), **inputs})
    return sharding.bake(baker, r, out, progress=progress, shard=shard, distributed=distributed, merge=merge, **kwargs)
