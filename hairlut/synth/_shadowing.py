"""The shadow seam of the online module: one transmittance per (texel, light), by the scene's method.

``Scene.shadow_method`` (``[shadows] method``, hairlut.scene) selects it:

``smap``            eq 12 from the view's α-maps, inside the shading kernel (nothing here);
``light_oriented``  the light-oriented density map (bertails §2–3) of all the scene's strands,
``opacity_maps``    or its opacity shadow maps (kim ch. 6), one map per light, evaluated at
                    the points the texels' strands are seen at (:func:`seen_points`) → T
                    (C, K, n_t, n_u, L), which eq 13 applies per light;
``none``            no shadow work at all: τ = 1.

The light-space maps do not depend on the view: :func:`prepare_shadows` builds them once in
``prepare`` for the scene's lights, and :meth:`Shadows.for_lights` rebuilds them in ``render_view``
only when a view's lights differ from those it holds.

A texel's colour stands for the strands its α comes from, and those lie behind its layer surface, not on it: the
paper's layers (satf §3) sit at the shells v = 0.5, 0.75, 1, and the outer shell is where a cluster's strands end.
Looked up on the surface, the transmittance is that of the cluster's lit skin, and the side and back views of
a groom came out 1.19–1.27× brighter per unit α than its strands (Sintel, Ratboy and the curly groom, 128²,
benchmarks/records.md 2026-12-05).  So a texel's transmittance is the mean over :data:`SEEN_SAMPLES` points between
it and its cluster's centre line (:func:`seen_points`: its side of the chord, whose sectors a track read sums),
placed where that segment shows its strands (Beer–Lambert under the cluster's own in-plane extinction: spread over
the segment for a sparse cluster, within a few mean free paths of the surface for a dense one).  Measured on those
nine scenes, colour per unit α went from 1.02–1.27× to 0.90–1.20×.  Tried and dropped: one point at the mean depth
of the whole chord through the centre (0.81–0.93×: too dark, because T is convex in the depth), and the whole
chord's quartiles (0.86–1.21×).  This departs from the paper, which shades the layer where it lies.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np


@dataclass(eq=False)
class Shadows:
    """A scene's shadow ``method``; for a light-space method also its merged ``strands``, the texels' seen
    ``points`` (M, C, K, n_t, n_u, 3: :func:`seen_points`), the method's ``params``, and the ``lights`` (L, 3) its
    ``transmittance`` (C, K, n_t, n_u, L; float32 on the device) was built for."""

    method: str
    strands: object = None
    points: np.ndarray | None = None
    params: dict | None = None
    lights: np.ndarray | None = None
    transmittance: object = None
    cache: dict | None = None  # a groom scene's: the table cache folder and what keys its maps (prepare_shadows)

    @property
    def per_light(self) -> bool:
        return self.method in ("light_oriented", "opacity_maps")

    def for_lights(self, lights, timing: dict | None = None):
        """T (C, K, n_t, n_u, L) for ``lights``, rebuilt (and timed as "shadows") only when they
        differ from the ones held; None for ``smap`` and ``none``."""
        if not self.per_light:
            return None
        lights = np.atleast_2d(np.asarray(lights, np.float64))
        if self.lights is None or self.lights.shape != lights.shape or not np.array_equal(self.lights, lights):
            t0 = time.perf_counter()
            tr = self._transmittance(lights)
            self.transmittance, self.lights = jnp.asarray(tr, jnp.float32), lights.copy()
            if timing is not None:
                timing["shadows"] = timing.get("shadows", 0.0) + time.perf_counter() - t0
        return self.transmittance

    def _transmittance(self, lights: np.ndarray) -> np.ndarray:
        """The light-space method's T at the texels, through the groom cache when the scene is a groom's (the maps of
        100,000 strands take seconds, and depend on the strands, the lights, the texels and the method alone)."""

        def compute():
            from ..shadows import light_transmittance  # here: hairlut.shadows loads scipy.spatial (0.2 s), a hit needs neither

            t = light_transmittance(self.strands, lights, self.points, method=self.method, **self.params)
            return {"T": t.mean(axis=0)}  # each texel: the mean over its seen points

        if self.cache is None:
            return compute()["T"]
        from ..scene import cached_arrays

        want = self.points.shape[1:-1] + (len(lights),)

        def check(arrays):
            t = arrays["T"]
            if t.shape != want or t.dtype != np.float64 or not (np.isfinite(t).all() and (t >= 0).all() and (t <= 1).all()):
                raise ValueError(f"T of shape {t.shape}, dtype {t.dtype}, not transmittances of shape {want}")

        doc = {**self.cache["doc"], "lights": lights, "method": self.method, "params": self.params}
        return cached_arrays("shadows", doc, compute, check, self.cache["root"], ("geometry", "scene", "shadows"))["T"]


#: Points per texel along its chord (:func:`seen_points`): the quartiles' midpoints of where the chord shows its strands.
SEEN_SAMPLES = 4


def depth_quantiles(x, m: int = SEEN_SAMPLES) -> np.ndarray:
    """(m, *x.shape): the depths, as fractions of the chord, of the (i + ½)/m quantiles of where a chord of optical
    depth ``x`` = σ c shows what it holds (the truncated exponential σ e^{−σs} on [0, c], Beer–Lambert):
    −ln(1 − q (1 − e^{−x})) / x, → q for a sparse chord (every strand along it seen alike), → within a few mean free
    paths of the surface for a dense one."""
    x = np.asarray(x, np.float64)
    q = ((np.arange(m) + 0.5) / m).reshape((m,) + (1,) * x.ndim)
    sparse = x < 1e-9
    safe = np.where(sparse, 1.0, x)
    return np.where(sparse, q, -np.log1p(q * np.expm1(-safe)) / safe)


def section_extinction(table) -> tuple[np.ndarray, np.ndarray]:
    """(t, σ) per cross-section of one cluster's :class:`~hairlut.geometry.SectorTable`: the in-plane extinction
    σ = Σ 2 r · stretch / (π A B) of the strands crossing it (their cut widths over the ellipse's area; the planar
    trace's own σ_t = κ / r, summed), at its t."""
    n = table.shape[1]
    _, first = np.unique(np.asarray(table.t_index), return_index=True)  # any sector of a cross-section has its t, A, B
    t = np.asarray(table.t, np.float64)[first]
    a, b = np.asarray(table.half_axes, np.float64)[first].T
    width = 2.0 * np.asarray(table.crossing_radius, np.float64) * np.asarray(table.crossing_stretch, np.float64)
    summed = np.bincount(np.asarray(table.t_index)[table.crossing_sector], weights=width, minlength=n)
    area = np.pi * a * b
    return t, np.where(area > 0, summed / np.where(area > 0, area, 1.0), 0.0)


def seen_points(points, tables, t, m: int = SEEN_SAMPLES) -> np.ndarray:
    """(m, C, K, n_t, n_u, 3): for each texel of ``points`` (C, K, n_t, n_u, 3), on the layer surfaces at rows ``t``
    (n_t,), ``m`` points on the segment from it to its cluster's centre line at its row (the ring's mean over u), at
    the :func:`depth_quantiles` of that segment under the cluster's :func:`section_extinction` at the row
    (``tables``: one SectorTable per cluster).  The segment is the texel's side of the chord, whose sectors its
    track reads (``hairlut.synth._view``).  A texel's transmittance is the mean over its points (module
    docstring)."""
    p = np.asarray(points, np.float64)
    centre = p.mean(axis=3, keepdims=True)  # an ellipse's points at uniform phase average to its centre
    radius = np.linalg.norm(p - centre, axis=-1, keepdims=True)
    out = np.empty((m,) + p.shape)
    for c, table in enumerate(tables):
        ts, sigma = section_extinction(table)
        s = np.interp(t, ts, sigma)[None, :, None, None]
        depth = depth_quantiles(s * radius[c], m)  # of the radius: 0 on the surface, 1 at the centre line
        out[:, c] = centre[c] + (1.0 - depth) * (p[c] - centre[c])
    return out


def prepare_shadows(scene, strands: list, points: np.ndarray, timing: dict | None = None) -> Shadows:
    """The scene's :class:`Shadows`, its light-space maps built for the scene's own lights (module docstring);
    ``strands``: every cluster's Strands; ``points`` (M, C, K, n_t, n_u, 3): where the texels' strands are seen
    (:func:`seen_points`), whose transmittances each texel averages, or (C, K, n_t, n_u, 3): one point a texel."""
    method = scene.shadow_method
    if method not in ("light_oriented", "opacity_maps"):
        return Shadows(method)
    from ..geometry import Strands

    cfg = scene.config["shadows"]
    merged = Strands(
        np.concatenate([s.points for s in strands]),
        np.concatenate([s.counts for s in strands]),
        thickness=None if any(s.thickness is None for s in strands) else np.concatenate([s.thickness for s in strands]),
    )
    params = {"resolution": cfg["resolution"], "kappa": None if cfg["kappa"] == "auto" else float(cfg["kappa"])}
    params |= {"padding": cfg["padding"]} if method == "light_oriented" else {"slices": cfg["slices"]}
    points = np.asarray(points, np.float64)
    out = Shadows(method, merged, points[None] if points.ndim == 5 else points, params)
    if scene.groom_path is not None:  # a groom's maps are kept with its fit (hairlut.scene's groom cache)
        from ..scene import cache_root_of, strands_digest

        texels = hashlib.sha256(f"{out.points.shape}".encode() + out.points.tobytes()).hexdigest()
        out.cache = {"root": cache_root_of(scene), "doc": {"strands": strands_digest(merged), "points": texels}}
    out.for_lights(scene.lights, timing)
    return out
