"""The online module (satf §6): re-, α- and s-maps from the SATF, lighting, shading, blending.

``synthesize(scene, db, sh=None)`` runs it for a scene (``hairlut.scene.load_scene`` / ``resolve_scene``)
against an HRIR database (and the SH tables of its environment light, if it has one):
``render_view(prepare(scene, db, sh))``, where ``prepare`` does the view- and light-independent
work (strands, sectors, features, the SATF index, texel frames, transmittance) once, into a
:class:`Prepared`, and ``render_view`` the maps and shaded layers of any view and lights: a :class:`SynthResult` of one
:class:`ClusterResult` per cluster.  ``write_outputs`` writes one EXR and PNG per cluster.
JAX loads on first use of a name."""

from .._lazy import lazy_exports

_LAZY = {
    "Environment": "_environment",
    "prepare_environment": "_environment",
    "MapIndex": "_view",
    "view_maps": "_view",
    "map_index": "_view",
    "Maps": "_maps",
    "SectorFrames": "_maps",
    "SectorParams": "_maps",
    "Texels": "_maps",
    "build_maps": "_maps",
    "fetch": "_maps",
    "param_distance": "_maps",
    "wrap": "_maps",
    "sector_angles": "_maps",
    "sector_frames": "_maps",
    "sector_params": "_maps",
    "sweep_kernel": "_maps",
    "texel_grid": "_maps",
    "texels": "_maps",
    "blend": "_shading",
    "compose_clusters_kernel": "_shading",
    "compose_kernel": "_shading",
    "diffuse": "_shading",
    "lighting_kernel": "_shading",
    "shade": "_shading",
    "shade_lights": "_shading",
    "shadow_map": "_shading",
    "specular": "_shading",
    "value_noise": "_shading",
    "ClusterResult": "_synth",
    "KIND": "_synth",
    "Prepared": "_synth",
    "PreparedCluster": "_synth",
    "SynthResult": "_synth",
    "channels": "_synth",
    "material_arrays": "_synth",
    "ortho_preview": "_synth",
    "prepare": "_synth",
    "prepare_cluster": "_synth",
    "render_view": "_synth",
    "render_clusters": "_synth",
    "synthesize": "_synth",
    "write_outputs": "_synth",
    "Shadows": "_shadowing",
    "prepare_shadows": "_shadowing",
    "geometry_index": "_view",
    "params_kernel": "_view",
    "sweep_sectors": "_view",
    "MapSource": "_methods",
    "prepare_map_source": "_methods",
    "sector_tangents": "_methods",
}

__all__ = ["ClusterResult", "Prepared", "SynthResult", "prepare", "render_view", "synthesize", "write_outputs"]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
