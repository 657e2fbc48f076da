"""Hair geometry: strands and their file formats (.tfx, .hair, USD), generalized disk clusters
(satf §3: frames, positions, layer meshes, HSVs and sectors), strand generation and
assignment, sector density fields, features and the random sector sampler.

:class:`Strands` are read and written by :func:`read_strands` / :func:`write_strands`.  A cluster is a
:class:`ClusterSpec`; :class:`ClusterGeometry` sweeps specs (eqs 1–3) for :func:`generate_strands`,
:func:`layer_meshes` (a :class:`LayerMeshes`) and :func:`build_sectors` (a :class:`SectorTable`), and
:func:`fit_clusters` fits clusters to a groom's strands.  :func:`sector_density` grids a sector table's
splats and :func:`sector_features` describes the grids; :func:`sample_sectors` draws random sectors
(:class:`SampledSectors`) from a :class:`SectorSpace`.

Strand I/O is imported eagerly; the cluster and density modules (which load JAX and
SciPy) on first use of one of their names, so ``hairlut strands info`` stays light."""

from .._lazy import lazy_exports
from .formats import SUFFIXES, format_of, read_strands, write_strands
from .strands import Strands

_LAZY = {
    "BSpline": "_bspline",
    "fit_bspline": "_bspline",
    "ClusterBatch": "cluster",
    "ClusterSpec": "cluster",
    "MacroCluster": "cluster",
    "STRUCTURE_DEFAULTS": "cluster_defaults",
    "ClusterGeometry": "sweep",
    "Section": "sweep",
    "LayerMeshes": "mesh",
    "layer_meshes": "mesh",
    "SectorTable": "sectors",
    "build_sectors": "sectors",
    "angle_grid": "inplane",
    "azimuths": "inplane",
    "grid_cell": "inplane",
    "sector_axes": "inplane",
    "SIGMA_PER_RADIUS": "splats",
    "SplatBatch": "splats",
    "PROFILES": "strandgen",
    "assign_strands": "strandgen",
    "generate_strands": "strandgen",
    "sector_density": "density",
    "sector_density_numpy": "density",
    "sector_mean_density": "density",
    "FEATURE_SETS": "features",
    "FeatureStats": "features",
    "PCABasis": "features",
    "feature_names": "features",
    "sector_features": "features",
    "fit_clusters": "fit",
    "resample_strands": "fit",
    "PLACES": "coverage",
    "length_inside": "coverage",
    "segment_places": "coverage",
    "SampledSectors": "sampler",
    "SectorSpace": "sector_space",
    "groom_sectors": "sampler",
    "sample_sectors": "sampler",
}

__all__ = [
    "ClusterGeometry",
    "ClusterSpec",
    "LayerMeshes",
    "SampledSectors",
    "SectorSpace",
    "SectorTable",
    "Strands",
    "build_sectors",
    "fit_clusters",
    "generate_strands",
    "layer_meshes",
    "read_strands",
    "sample_sectors",
    "sector_density",
    "sector_features",
    "write_strands",
]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
