"""The registry of asset kinds: what each kind must hold.

A reader that is told the kind checks the file's ``kind`` attribute and the
presence of every required variable before it trusts the file.
"""

from __future__ import annotations

from dataclasses import dataclass

#: The ``hairlut_schema`` this version writes, and the ones it can read.
#: 1: axes in /axes (netCDF readers miss them); 2: axes as root dimension scales.
SCHEMA = 2
SUPPORTED_SCHEMAS = frozenset({1, 2})


@dataclass(frozen=True)
class Kind:
    name: str
    required: tuple[str, ...]
    description: str


KINDS: dict[str, Kind] = {}


def register_kind(name: str, required: tuple[str, ...], description: str) -> Kind:
    """Declare a kind (idempotent for an identical declaration)."""
    kind = Kind(name, tuple(required), description)
    if KINDS.setdefault(name, kind) != kind:
        raise RuntimeError(f"asset kind {name!r} declared twice with different contents")
    return kind


# Every kind hairlut writes is declared here, so that any reader (inspect, the
# cache) knows it without importing the module that bakes it.
register_kind("kk_lobes", ("diffuse", "specular"), "Kajiya-Kay diffuse and specular kernels sampled on (theta, theta') grids")
register_kind("sh_tables", ("gaunt",), "exact SH convolution tables for Kajiya-Kay hair (xing §4)")
register_kind("sh_light", ("a",), "SH coefficients of an environment light (xing §4)")
register_kind("hrir_db", ("features", "alpha", "reflectance"), "HRIR database: planar ray-traced sectors (satf §4-5)")
register_kind("hrir_shard", ("alpha", "reflectance", "density"), "a slice of sectors of an HRIR-DB bake")
