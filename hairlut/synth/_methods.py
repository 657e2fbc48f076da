"""Where a view's per-sector rows come from: the map methods ``direct`` and ``scene``.

``satf`` (the paper's lookup, ``_view.view_maps``) fetches database rows at Params(b).  The
other two give every sector its own row, then run the same eq 7 sweep (``_view.sweep_sectors``,
two sectors per HSV), so the shading kernel receives the same (re, α) map arrays:

* ``direct``: each view, every non-empty sector traced at its exact θv and θl from its own density
  grid (``_direct.direct_sector_maps``; the inputs, ``scene_sector_inputs``, built once here);
* ``scene``: each sector's row read from the groom's baked ``scene_maps`` table at its exact angles
  (``hairlut.scenemaps.fetch_kernel``).

:func:`prepare_map_source` builds the method's inputs once; :meth:`MapSource.view` makes a view's maps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..march import direct_sector_maps, scene_sector_inputs
from ._view import MapIndex, _fenced, _split, _texels, params_kernel, sweep_sectors


@dataclass(frozen=True, eq=False)
class MapSource:
    """A prepared map method: ``method`` and the planner's ``reason``; for ``direct`` the HRIR
    ``recipe`` (trace and Phong settings) and the sectors' ``density`` (S, n_s, n_r) and ``geometry``
    (S, 11); for ``scene`` the loaded table ``maps`` and its device arrays ``device``."""

    method: str
    reason: str
    pixels: int
    recipe: dict | None = None
    density: np.ndarray | None = None
    geometry: np.ndarray | None = None
    maps: object = None
    device: tuple = ()
    texel_sectors: dict = field(default_factory=dict, repr=False)  # id(ix) → (ix, top, bot): see sectors_of

    def sectors_of(self, ix):
        """Each texel's top and bottom sector, (C, K, n_t, n_u) int32 twice, for the index ``ix``: static per
        scene, so built once here and passed to :func:`scene_view_kernel` (computed in the kernel, XLA:CPU
        redoes the (C, s_t + 1, G, s_u) → texel index arithmetic for every read: the paper-scale sweep
        measured 16.6 → 5.0 CPU-ms with them given)."""
        hit = self.texel_sectors.get(id(ix))
        if hit is None or hit[0] is not ix:
            ids = _split(ix, jnp.arange(ix.axes.shape[1], dtype=jnp.int32))
            hit = self.texel_sectors[id(ix)] = (ix, *(jnp.asarray(np.asarray(_texels(ix, x))) for x in ids))
        return hit[1:]

    def view(self, ix, view, lights, path=None, light_path=None):
        """re (C, K, Lt, n_t, n_u) and α (C, K, n_t, n_u) (device arrays) of one view, and the uniform
        mask (H,) (all False: every HSV sweeps its two sectors' own rows).  ``path`` (S,) and ``light_path`` (S, Lt):
        the ``direct`` method's per-sector optical-path factors of the camera's and the lights' rays
        (``_direct.direct_sector_maps``; :func:`sector_tangents` gives each sector's axis); other methods refuse them."""
        f32 = partial(np.asarray, dtype=np.float32)
        if self.method != "direct" and (path is not None or light_path is not None):
            raise errors.ValidationError("path", self.method, "per-ray optical paths need the direct map method")
        tv, tl, cs, _, _ = params_kernel(ix, f32(view), f32(lights), f32(0.0), n_v=1, n_l=1)
        if self.method == "direct":
            alpha, re = direct_sector_maps(
                self.density,
                self.geometry,
                np.asarray(tv, np.float64),
                np.asarray(tl, np.float64),
                self.recipe,
                path=path,
                light_path=light_path,
            )
            alpha, re = jnp.asarray(alpha), jnp.asarray(re)
        else:
            from ..scenemaps import index_kernel, terms_kernel

            alpha_t, ratio_t, row = self.device
            index = index_kernel(row, tv, half=alpha_t.shape[1], views=ratio_t.shape[1])
            re_map, a_map = scene_view_kernel(ix, *terms_kernel(alpha_t, ratio_t, index, tv, tl), cs, *self.sectors_of(ix))
            return re_map, a_map, np.zeros(int(np.prod(ix.grid)), bool)
        re_map, a_map = sweep_sectors(ix, alpha, re, cs)
        return re_map, a_map, np.zeros(int(np.prod(ix.grid)), bool)


def sector_tangents(clusters) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangent ∂P/∂t/|∂P/∂t| and point P (S, 3) at every sector's parametric centre (its section's t, mid
    radius, mid phase), for ``prepare``'s clusters (``Prepared.clusters``), in the order of the maps' sectors:
    the axis the strands of the sector follow, against which a ray's angle ψ sets its optical path 1/sin ψ
    (``_direct.direct_sector_maps``'s ``path``; the same tangent as the texels' ``PreparedCluster.tangent``)."""
    from ..geometry import ClusterGeometry

    tangents, points = [], []
    for pc in clusters:
        tb = pc.table
        t, v, u = np.asarray(tb.t, np.float64), tb.v_range.mean(axis=1), tb.u_range.mean(axis=1)
        p, pt, _ = ClusterGeometry(pc.spec).derivatives_of(np.zeros(len(t), np.int64), t, v, u)
        tangents.append(pt / np.maximum(np.linalg.norm(pt, axis=-1, keepdims=True), 1e-300))
        points.append(p)
    return np.concatenate(tangents), np.concatenate(points)


@jax.jit
def scene_view_kernel(ix: MapIndex, alpha, ratio, cs, top, bot):
    """The ``scene`` method's eq 7 from every sector's α (S, P) and re/α ratio ρ (S, Lt, Q), read from its
    table row at its exact angles (``hairlut.scenemaps.index_kernel`` then ``terms_kernel``: separate
    kernels, because fused into this one XLA:CPU recomputes the rows' gathers and index arithmetic per
    texel; with :meth:`MapSource.sectors_of`, the paper-scale maps (53,040 sectors, default layout) went
    from 48.5 to 18.3 CPU-ms, best of 20 in one run, on the shared 2-core CPU, bitwise equal).  Per texel as
    :func:`~hairlut.synth.sweep_sectors` (the HSV's top sector at x⊤, with weight γ its bottom sector at
    x⊥, linear in the pixel), sampling re = α ρ at the two pixels it interpolates instead of a
    materialised (S, Lt, P) re row: the same numbers as ``sweep_sectors(fetch_kernel(...))`` (each
    sampled re is the same float32 product α(p) ρ(⌊pQ/P⌋)), without writing and re-reading the rows or
    concatenating the HSVs' two sectors.  ``cs`` (S, 2) from :func:`params_kernel`; ``top``, ``bot``
    (C, K, n_t, n_u) each texel's two sectors (:meth:`MapSource.sectors_of`); re (C, K, Lt, n_t, n_u),
    α (C, K, n_t, n_u)."""
    P, (Lt, Q) = alpha.shape[1], ratio.shape[1:]
    if ix.reads == "track":  # [render] layer_reads: every sector's re row, re(p) = α(p) ρ(⌊pQ/P⌋), for sweep_track
        re = _fenced(lambda a, r: a[:, None] * jnp.repeat(r, P // Q, axis=-1), alpha, ratio)  # not per gather
        return sweep_sectors(ix, alpha, re, cs)
    c1, c2 = cs[top], cs[bot]
    pix = [((-c[..., 1] * o[0] + c[..., 0] * o[1]) + 1.0) * P / 2.0 - 0.5 for c, o in zip((c1, c2), ix.offset)]
    fa, fr = alpha.reshape(-1), ratio.reshape(-1)
    g = ix.gamma[:, None]

    def sample(s, p, j):  # α (j None) or α·ρ_j at float pixel p of sector s: linear in the pixel, clamped
        f = jnp.clip(p, 0.0, P - 1.0)
        i0 = jnp.clip(jnp.floor(f).astype(jnp.int32), 0, max(P - 2, 0))
        i1 = jnp.minimum(i0 + 1, P - 1)
        g0, g1 = fa[s * P + i0], fa[s * P + i1]
        if j is not None:
            g0, g1 = g0 * fr[(s * Lt + j) * Q + i0 // (P // Q)], g1 * fr[(s * Lt + j) * Q + i1 // (P // Q)]
        return g0 + (f - i0) * (g1 - g0)

    def eq7(j):
        return (1 - g) * sample(top, pix[0], j) + g * sample(bot, pix[1], j)

    return jnp.stack([eq7(j) for j in range(Lt)], axis=2), jnp.clip(eq7(None), 0.0, 1.0)


def _scene_maps(maps):
    if maps is None:
        return None
    if hasattr(maps, "ratio") and hasattr(maps, "row"):
        return maps
    from ..scenemaps import load_scene_maps

    return load_scene_maps(maps)


def prepare_map_source(scene, method: str, reason: str, tables, frames, maps=None) -> MapSource:
    """The inputs of ``method`` (``direct`` or ``scene``) for a scene's clusters: ``tables`` their
    :class:`~hairlut.geometry.SectorTable` s and ``frames`` their ``SectorFrames`` (in prepare's order);
    ``maps`` the scene's ``scene_maps`` table (a path or a loaded one) for ``scene``."""
    from ..planner import direct_recipe, scene_maps_recipe

    n = sum(len(fr.extent) for fr in frames)
    if method == "direct":
        recipe = direct_recipe(scene)
        parts = [scene_sector_inputs(tb, recipe, extent=fr.extent) for tb, fr in zip(tables, frames)]
        return MapSource(
            "direct",
            reason,
            recipe["trace"]["pixels"],
            recipe,
            np.concatenate([p[0] for p in parts]),
            np.concatenate([p[1] for p in parts]),
        )
    if method != "scene":
        raise errors.ValidationError("render.method", method, "prepare_map_source makes direct or scene maps")
    table = _scene_maps(maps)
    if table is None:
        raise errors.AssetNotFoundError(
            scene.source,
            "render.method resolves to 'scene' and its scene_maps table was not "
            f"given: bake it with `hairlut bake --scene {scene.source}` (or `hairlut bake "
            f"scene_maps --scene {scene.source}`) and pass it as maps=",
        )
    from ..scenemaps import geometry_key

    want = scene_maps_recipe(scene)
    key = geometry_key(scene)
    got = table.recipe.get("geometry", {}).get("sha256")
    if got != key:
        raise errors.ValidationError(
            "maps",
            str(table.path),
            "this scene_maps table was baked for another groom "
            f"(geometry {str(got)[:12]}…, the scene's is {key[:12]}…); rebake with "
            f"`hairlut bake --scene {scene.source}`",
        )
    if len(table.row) != n:
        raise errors.ValidationError("maps", str(table.path), f"the table holds {len(table.row)} sectors, the scene {n}")
    if table.recipe.get("hrir") != want["hrir"] or table.recipe.get("table") != want["table"]:
        raise errors.ValidationError(
            "maps",
            str(table.path),
            "the table's trace or layout settings differ from the "
            f"scene's render settings; rebake with `hairlut bake --scene {scene.source}`",
        )
    device = (jnp.asarray(table.alpha), jnp.asarray(table.ratio), jnp.asarray(table.row, jnp.int32))
    return MapSource("scene", reason, table.pixels, None, None, None, table, device)
