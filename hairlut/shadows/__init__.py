"""Volumetric self-shadowing of hair: density volumes and voxel SH transmittance (xing §5), the
light-oriented density map (bertails) and opacity shadow maps (kim ch. 6)."""

from ._light import light_frame
from ._light_oriented import LightOrientedMap, light_oriented_map
from ._opacity import OpacityMaps, opacity_shadow_maps
from ._transmittance import Transmittance, transmittance
from ._volume import Volume, gradient, trilinear, voxelize

__all__ = ["LightOrientedMap", "OpacityMaps", "Transmittance", "Volume", "gradient", "light_frame", "light_oriented_map",
           "opacity_shadow_maps", "transmittance", "trilinear", "voxelize"]
