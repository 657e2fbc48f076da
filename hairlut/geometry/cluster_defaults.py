"""The structure defaults of a generalized disk cluster (satf §3.1–3.2, eq 3), set once (no JAX).

Shell radii and core (fractions of the ellipse, v ∈ [0, 1] as in eq 1) and the sampling
counts s_t, s_v, s_u of eq 3.  :class:`~hairlut.geometry.ClusterSpec`,
:func:`~hairlut.geometry.fit_clusters`, :func:`~hairlut.geometry.groom_sectors` and the scene
schema's ``[[clusters]]`` and ``[groom]`` tables all take their defaults from here.
"""

STRUCTURE_DEFAULTS = {
    "layer_radii": (0.5, 0.75, 1.0),  # shell surfaces v, strictly increasing, in (0, 1]
    "core_radius": 0.25,  # the core surface, inside the first shell
    "s_t": 8,  # steps along the trajectory
    "s_v": 1,  # tracks per shell (the online module maps one per layer)
    "s_u": 8,  # phase steps, Δu = 2π / s_u
}
