"""Hair geometry: strands and their file formats (.tfx, .hair, USD), generalized disk clusters
(satf §3: frames, positions, layer meshes, HSVs and sectors), strand generation and
assignment, sector density fields, features and the random sector sampler.

Strand I/O is imported eagerly; the cluster and density modules (which load JAX and
SciPy) on first use of one of their names, so ``hairlut strands info`` stays light.
"""

from .._lazy import lazy_exports

from .formats import SUFFIXES, format_of, read_strands, write_strands
from .strands import Strands

_LAZY = {
    "BSpline": "_bspline", "fit_bspline": "_bspline",
    "ClusterBatch": "cluster", "ClusterSpec": "cluster", "MacroCluster": "cluster", "STRUCTURE_DEFAULTS": "cluster_defaults",
    "ClusterGeometry": "sweep", "Section": "sweep",
    "LayerMeshes": "mesh", "layer_meshes": "mesh",
    "SectorTable": "sectors", "build_sectors": "sectors",
    "angle_grid": "inplane", "azimuths": "inplane", "grid_cell": "inplane", "sector_axes": "inplane",
    "SIGMA_PER_RADIUS": "splats", "SplatBatch": "splats",
    "PROFILES": "strandgen", "assign_strands": "strandgen", "generate_strands": "strandgen",
    "sector_density": "density", "sector_density_numpy": "density",
    "FEATURE_SETS": "features", "FeatureStats": "features", "PCABasis": "features",
    "feature_names": "features", "sector_features": "features",
    "fit_clusters": "fit", "resample_strands": "fit", "PLACES": "coverage", "length_inside": "coverage",
    "segment_places": "coverage",
    "SampledSectors": "sampler", "SectorSpace": "sector_space", "groom_sectors": "sampler", "sample_sectors": "sampler",
}

__all__ = ["SUFFIXES", "Strands", "format_of", "read_strands", "write_strands", *sorted(_LAZY)]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
