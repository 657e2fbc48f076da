"""hairlut: precomputation and lookup tables for real-time hair rendering.

The public API, imported on first use (so ``import hairlut`` stays light):

``hairlut.SHTables``          exact SH convolution tables (xing §4): ``SHTables.load(path)``
``hairlut.HRIRDB``            the HRIR database (satf §4-5): ``HRIRDB.load(path).query(...)``
``hairlut.assets``            HDF5 tables and OpenEXR images, atomic and validated
``hairlut.sh``                real spherical harmonics, quadrature, Gaunt coefficients
``hairlut.shtables``          baking the SH tables
``hairlut.envlight``          environment maps → SH light coefficients
``hairlut.geometry``          strands, strand files, generalized disk clusters, sector densities
``hairlut.hrir``              baking the HRIR database by planar ray tracing
``hairlut.cache``             the content-addressed table cache
``hairlut.synthesize``        the online module (satf §6): re-, α-, s-maps, shading, blending
``hairlut.scene``             scene files, their clusters and strands, and the planner
``hairlut.plan``              the scene planner, ``hairlut.scene.plan``: what a scene needs, what the cache holds, what it skips
``hairlut.shadows``           density volumes and voxel SH transmittance (xing §5)
``hairlut.errors``            every exception hairlut raises on purpose
"""

from __future__ import annotations

import importlib

from . import errors
from ._version import __version__

_SUBMODULES = {"assets", "bench", "cache", "demo", "envlight", "geometry", "hrir", "kernels", "recipes", "scene", "sh",
               "render", "shadows", "shtables", "stress", "synth"}
_ATTRIBUTES = {"SHTables": "shtables", "HRIRDB": "hrir", "plan": "scene", "synthesize": "synth"}

__all__ = ["__version__", "errors", *sorted(_SUBMODULES), *sorted(_ATTRIBUTES)]


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    if name in _ATTRIBUTES:
        return getattr(importlib.import_module(f".{_ATTRIBUTES[name]}", __name__), name)
    raise AttributeError(f"module 'hairlut' has no attribute {name!r}")
