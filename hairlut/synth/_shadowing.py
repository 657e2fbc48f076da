"""The shadow seam of the online module: one transmittance per (texel, light), by the scene's method.

``Scene.shadow_method`` (``[shadows] method``, hairlut.scene) selects it:

``smap``            eq 12 from the view's α-maps, inside the shading kernel (nothing here);
``light_oriented``  the light-oriented density map (bertails §2–3) of all the scene's strands,
``opacity_maps``    or its opacity shadow maps (kim ch. 6), one map per light, evaluated at
                    the texels' 3-D positions on the layer surfaces → T (C, K, n_t, n_u, L),
                    which eq 13 applies per light;
``none``            no shadow work at all: τ = 1.

The light-space maps do not depend on the view: :func:`prepare_shadows` builds them once in
``prepare`` for the scene's lights, and :meth:`Shadows.for_lights` rebuilds them in ``render_view``
only when a view's lights differ from those it holds.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np


@dataclass(eq=False)
class Shadows:
    """A scene's shadow ``method``; for a light-space method also its merged ``strands``, the texel
    ``points`` (C, K, n_t, n_u, 3), the method's ``params``, and the ``lights`` (L, 3) its
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

            return {"T": light_transmittance(self.strands, lights, self.points, method=self.method, **self.params)}

        if self.cache is None:
            return compute()["T"]
        from ..scene import cached_arrays

        want = self.points.shape[:-1] + (len(lights),)

        def check(arrays):
            t = arrays["T"]
            if t.shape != want or t.dtype != np.float64 or not (np.isfinite(t).all() and (t >= 0).all() and (t <= 1).all()):
                raise ValueError(f"T of shape {t.shape}, dtype {t.dtype}, not transmittances of shape {want}")

        doc = {**self.cache["doc"], "lights": lights, "method": self.method, "params": self.params}
        return cached_arrays("shadows", doc, compute, check, self.cache["root"], ("geometry", "scene", "shadows"))["T"]


def prepare_shadows(scene, strands: list, points: np.ndarray, timing: dict | None = None) -> Shadows:
    """The scene's :class:`Shadows`, its light-space maps built for the scene's own lights (module docstring);
    ``strands``: every cluster's Strands; ``points`` (C, K, n_t, n_u, 3): the texels on the layer surfaces."""
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
    out = Shadows(method, merged, np.asarray(points, np.float64), params)
    if scene.groom_path is not None:  # a groom's maps are kept with its fit (hairlut.scene's groom cache)
        from ..scene import cache_root_of, strands_digest

        texels = hashlib.sha256(f"{out.points.shape}".encode() + out.points.tobytes()).hexdigest()
        out.cache = {"root": cache_root_of(scene), "doc": {"strands": strands_digest(merged), "points": texels}}
    out.for_lights(scene.lights, timing)
    return out
