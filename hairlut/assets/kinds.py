"""Asset kinds: what a file of each kind must hold, declared by whoever writes it.

``assets`` knows no kind of its own.  A kind is declared with :func:`register_kind`
by the module that writes it (a table kind's baker declaration, see
:mod:`hairlut.bake.protocol`).  A reader that meets a kind nobody in this process has
declared yet asks the kind catalogue (:data:`CATALOGUE`, the registry module that
lists every kind hairlut ships, one line each) once; the catalogue imports only
the light declaration module of that kind, never a baker, so ``assets`` stays
below the bakers.  A reader that is told the kind checks the file's ``kind``
attribute and the presence of every required variable before it trusts the file.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

#: The ``hairlut_schema`` this version writes, and the ones it can read.
#: 1: axes in /axes (netCDF readers miss them); 2: axes as root dimension scales.
SCHEMA = 2
SUPPORTED_SCHEMAS = frozenset({1, 2})

#: The module, named (not imported) here, whose ``declare(name)`` declares a kind hairlut ships.
CATALOGUE = "hairlut.bake.registry"


@dataclass(frozen=True)
class Kind:
    name: str
    required: tuple[str, ...]
    description: str
    bounds: tuple = ()  # hairlut.assets.bounds.Bound s, checked on every write of the kind


class KindTable(dict):
    """name → :class:`Kind`; a name not declared yet is looked up in the catalogue once."""

    def _discover(self, name) -> bool:
        if not dict.__contains__(self, name) and isinstance(name, str) and CATALOGUE:
            importlib.import_module(CATALOGUE).declare(name)
        return dict.__contains__(self, name)

    def __contains__(self, name) -> bool:
        return self._discover(name)

    def __missing__(self, name):
        if self._discover(name):
            return dict.__getitem__(self, name)
        raise KeyError(name)

    def get(self, name, default=None):
        return self[name] if name in self else default


KINDS: KindTable = KindTable()


def register_kind(name: str, required: tuple[str, ...], description: str, bounds: tuple = ()) -> Kind:
    """Declare a kind (idempotent for an identical declaration), with the physical bounds of its tables
    (:class:`hairlut.assets.bounds.Bound` s: :func:`hairlut.assets.write_table` refuses a table beyond them)."""
    kind = Kind(name, tuple(required), description, tuple(bounds))
    if dict.setdefault(KINDS, name, kind) != kind:
        raise RuntimeError(f"asset kind {name!r} declared twice with different contents")
    return kind


def known_kinds() -> list[str]:
    """Every kind declared so far, after asking the catalogue for all it lists."""
    if CATALOGUE:
        importlib.import_module(CATALOGUE).declare_all()
    return sorted(dict.keys(KINDS))
