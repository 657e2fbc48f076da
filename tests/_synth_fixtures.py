"""Shared helpers for the synth tests: a small synthetic HRIR database and a procedural scene."""

from types import SimpleNamespace

import numpy as np

from hairlut.geometry import FeatureStats

N, V, L, P = 24, 8, 8, 16


def synthetic_db(seed: int = 5):
    """An HRIRDB-like object: basic features, premultiplied reflectance (re ≤ α ≤ 1)."""
    rng = np.random.default_rng(seed)
    feats = np.stack([rng.uniform(0.0, 0.4, N), rng.uniform(0.2, 0.8, N), rng.uniform(0.2, 0.8, N)], axis=1)
    alpha = rng.uniform(0.0, 1.0, (N, V, P))
    refl = alpha[:, :, None, :] * rng.uniform(0.0, 1.0, (N, V, L, P))
    return SimpleNamespace(
        features=feats,
        stats=FeatureStats.fit(feats, ("rho_st", "rho_s", "rho_t")),
        theta_v=2 * np.pi * np.arange(V) / V,
        theta_l=2 * np.pi * np.arange(L) / L,
        alpha=alpha,
        reflectance=refl,
        recipe={"sectors": {"grid": [8, 8], "density_scale": 1.0}},
    )


CLUSTER_A = {
    "trajectory": [[0.0, 1.0, 0.0], [0.05, 0.5, 0.1], [0.1, 0.0, 0.1]],
    "half_axis_a": 0.08,
    "half_axis_b": 0.06,
    "twist": [0.0, 1.0],
    "layer_radii": [0.6, 1.0],
    "core_radius": 0.2,
    "s_t": 4,
    "s_u": 4,
}
CLUSTER_B = {
    "trajectory": [[0.3, 1.0, 0.0], [0.3, 0.5, 0.05], [0.28, 0.0, 0.0]],
    "half_axis_a": [0.07, 0.09],
    "half_axis_b": 0.05,
    "layer_radii": [0.6, 1.0],
    "core_radius": 0.2,
    "s_t": 4,
    "s_u": 4,
}


def scene(**material):
    """A small two-cluster scene that checks the paper's equations as written: eq 7's pair reads and eq 12's s-map
    are set, not left to the planner (which would choose track reads and light-oriented shadows)."""
    return {
        "render": {"resolution": [16, 8], "preview_size": 32, "layer_reads": "pair"},
        "shadows": {"method": "smap"},
        "camera": {"view": [0.0, 0.2, 1.0]},
        "lights": {"directions": [[0.5, 0.7, 1.0], [-0.3, 0.1, 0.4]]},
        "material": {"kd": 0.5, "ks_I": 0.3, "ks_II": 0.2, **material},
        "effects": {"noise": True},
        "strands": {"count": 60, "radius": 0.006, "seed": 3},
        "clusters": [dict(CLUSTER_A), dict(CLUSTER_B)],
    }
