"""hairlut: precomputation and lookup tables for real-time hair rendering.

The public API, imported on first use (so ``import hairlut`` stays light), floor by floor:

``hairlut.errors``            every exception hairlut raises on purpose
``hairlut.geometry``          strands, strand files, generalized disk clusters, sector densities
``hairlut.sh``                real spherical harmonics, quadrature, Gaunt coefficients
``hairlut.assets``            HDF5 tables and OpenEXR images, atomic and validated
``hairlut.scene``             scene files, their camera, clusters and sectors
``hairlut.march``             the planar march shared by the bakers and the direct map method (satf §5)
``hairlut.envlight``          environment maps → SH light coefficients
``hairlut.bake``              the bake machinery: the baker protocol, kind registry, split bakes, devices, cache
``hairlut.hrir``              the ``hrir_db`` kind: the HRIR database by planar ray tracing (satf §4-5)
``hairlut.shtables``          the ``sh_tables`` kind: exact SH convolution tables (xing §4)
``hairlut.scenemaps``         the ``scene_maps`` kind: a groom's own sector projections
``hairlut.hairbsdf``          the ``hair_bsdf`` kind: converged hair BSDF tables (Chiang 2016; dual scattering, lobe energy)
``hairlut.planner``           the scene planner: what a scene needs, what the cache holds, what it skips
``hairlut.shadows``           density volumes and voxel SH transmittance (xing §5), light-space shadow maps
``hairlut.synth``             the online module (satf §6): re-, α-, s-maps, shading, blending
``hairlut.render``            camera frames: the layered render, the strand render, and the two compared
``hairlut.bench``, ``hairlut.stress``, ``hairlut.demo``   the instruments: run time against error, edge cases, the demo
``hairlut.SHTables``, ``hairlut.HRIRDB``   the two tables' readers; ``hairlut.plan``, ``hairlut.synthesize``: the planner
and the online module's one-call entry points
"""

from __future__ import annotations

import importlib

from . import errors
from ._version import __version__

_SUBMODULES = {
    "assets",
    "bake",
    "bench",
    "demo",
    "envlight",
    "geometry",
    "hairbsdf",
    "hrir",
    "march",
    "planner",
    "render",
    "scene",
    "scenemaps",
    "sh",
    "shadows",
    "shtables",
    "stress",
    "synth",
}
_ATTRIBUTES = {"SHTables": "shtables", "HRIRDB": "hrir", "plan": "planner", "synthesize": "synth"}

__all__ = ["__version__", "errors", *sorted(_SUBMODULES), *sorted(_ATTRIBUTES)]


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    if name in _ATTRIBUTES:
        return getattr(importlib.import_module(f".{_ATTRIBUTES[name]}", __name__), name)
    raise AttributeError(f"module 'hairlut' has no attribute {name!r}")
