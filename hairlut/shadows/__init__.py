"""Volumetric self-shadowing of hair: density volumes and voxel SH transmittance (xing §5)."""

from ._transmittance import Transmittance, transmittance
from ._volume import Volume, gradient, trilinear, voxelize

__all__ = ["Transmittance", "Volume", "gradient", "transmittance", "trilinear", "voxelize"]
