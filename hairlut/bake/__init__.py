"""The bake machinery: how any table kind is declared, found, split, run on devices and cached.

A kind declares a :class:`Baker` (with its :class:`Option` s and, for a kind that splits, its :class:`Units`);
:func:`kinds` lists the registered kinds, :func:`get` finds one's baker, :func:`ensure` returns the cached asset
of a recipe (baking it if needed) and :func:`merge` joins shard files.  Its modules: ``protocol`` (the
baker protocol), ``registry`` (every kind in one line each; ``registry.bake`` bakes without the cache),
``sharding`` (the one split path: resumable blocks, ``--shard K/N``, distributed processes, virtual or copied
assets), ``devices`` (units over local devices and JAX's processes; ``coordination`` keeps those processes
agreed and alive) and ``cache`` (the content-addressed table cache).  None of it imports JAX until a bake runs."""

from .._lazy import lazy_exports

_LAZY = {
    "Baker": "protocol",
    "Option": "protocol",
    "Units": "protocol",
    "get": "registry",
    "kinds": "registry",
    "ensure": "registry",
    "merge": "registry",
}

__all__ = ["Baker", "Option", "Units", "ensure", "get", "kinds", "merge"]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
