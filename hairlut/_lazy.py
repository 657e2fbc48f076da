"""Lazy re-exports for package ``__init__`` modules (PEP 562).

A package lists ``{public name: private module}``; a name's module (and so JAX)
is imported on first access only, which keeps ``import hairlut`` and the CLI's
start-up light.
"""

from __future__ import annotations

from importlib import import_module


def lazy_exports(package: str, namespace: dict, names: dict[str, str]):
    """Return ``(__getattr__, __dir__)`` serving ``names`` from ``package``'s submodules."""

    def __getattr__(name: str):
        if name in names:
            value = getattr(import_module(f".{names[name]}", package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return __getattr__, __dir__
