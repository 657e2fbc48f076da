"""The bake machinery: how any table kind is declared, found, split, run on devices and cached.

``protocol`` is the baker protocol (:class:`~hairlut.bake.protocol.Baker`, ``Option``, ``Units``): what
every table kind declares, including how a bake splits into units.  ``registry`` names every kind in one
line each and bakes through the protocol (``registry.bake``, ``registry.ensure``, ``registry.merge``).
``sharding`` is the one split path (resumable blocks, ``--shard K/N``, distributed processes, virtual or
copied assets), ``devices`` spreads units over local devices and JAX's processes (``coordination`` keeps
those processes agreed and alive), and ``cache`` is the content-addressed table cache.  None of it
imports JAX until a bake runs.
"""

from .._lazy import lazy_exports

_LAZY = {
    "Baker": "protocol", "Option": "protocol", "Units": "protocol",
    "get": "registry", "kinds": "registry", "ensure": "registry", "merge": "registry",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
