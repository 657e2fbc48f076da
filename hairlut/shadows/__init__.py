"""Volumetric self-shadowing of hair: density volumes (:func:`voxelize`, a :class:`Volume`) and voxel
SH transmittance (:func:`transmittance`, a :class:`Transmittance`; xing §5), the light-oriented density map
(:func:`light_oriented_map`, a :class:`LightOrientedMap`; bertails) and opacity shadow maps
(:func:`opacity_shadow_maps`, an :class:`OpacityMaps`; kim ch. 6), and :func:`light_transmittance`: either of
the last two per light at arbitrary points (the online module's shadow seam); :func:`ray_march`, the NumPy
reference transmittance they are checked against."""

from ._light import light_frame
from ._light_oriented import LightOrientedMap, light_oriented_map
from ._methods import LIGHT_METHODS, fibre_width, light_transmittance
from ._opacity import OpacityMaps, opacity_shadow_maps
from ._reference import ray_march
from ._transmittance import Transmittance, transmittance
from ._volume import Volume, gradient, trilinear, voxelize

__all__ = [
    "LightOrientedMap",
    "OpacityMaps",
    "Transmittance",
    "Volume",
    "light_oriented_map",
    "light_transmittance",
    "opacity_shadow_maps",
    "ray_march",
    "transmittance",
    "voxelize",
]
