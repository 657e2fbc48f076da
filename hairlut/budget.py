"""The memory budget: estimate what a request allocates before allocating it.

Every boundary where a user's number turns into an allocation (a scene's strand
count and render sizes, a recipe's grids and angle counts, a file's declared
shapes) asks :func:`check` with its estimate in bytes and the key that drives it.
Above the limit the request is refused with a :class:`hairlut.errors.BudgetError`
that names the key, the value, the estimate and the limit, instead of a
``MemoryError`` (or an OOM kill) half-way through.

The limit, in order of precedence:

1. the ``limit=`` keyword of the call (bytes);
2. the environment variable ``HAIRLUT_MEMORY_LIMIT``: bytes, or a number with a
   binary suffix ``K``, ``M``, ``G`` or ``T`` (``HAIRLUT_MEMORY_LIMIT=8G``);
3. half of the machine's physical memory (``os.sysconf``), or 8 GiB where the
   platform does not say.

The estimates are lower bounds of the peak (the arrays that must exist at once);
a request under the limit can still fail for memory, one over it never starts.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping

from . import errors

ENV = "HAIRLUT_MEMORY_LIMIT"
FALLBACK = 8 << 30
_SUFFIX = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
_SPEC = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?(?:[eE][0-9]+)?)\s*([KMGT]?)(?:i?B)?\s*$", re.IGNORECASE)


def physical_memory() -> int | None:
    """Bytes of physical memory, or None where ``os.sysconf`` does not say."""
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
    return pages * size if pages > 0 and size > 0 else None


def parse_size(text: str, field: str = ENV) -> int:
    """``"8G"`` → 8·2³⁰; plain numbers are bytes.  ValidationError naming ``field`` otherwise."""
    m = _SPEC.match(str(text))
    value = float(m.group(1)) * _SUFFIX[m.group(2).upper()] if m else float("nan")
    if not (math.isfinite(value) and value >= 1):
        raise errors.ValidationError(field, text, "a size in bytes, optionally with K, M, G or T (binary), ≥ 1")
    return int(value)


def memory_limit(limit: int | None = None) -> int:
    """The budget in bytes: ``limit``, else ``$HAIRLUT_MEMORY_LIMIT``, else half the physical memory."""
    if limit is not None:
        if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not limit >= 1:
            raise errors.ValidationError("memory_limit", limit, "a positive number of bytes")
        return int(limit)
    env = os.environ.get(ENV)
    if env:
        return parse_size(env)
    phys = physical_memory()
    return phys // 2 if phys else FALLBACK


def describe(nbytes: float) -> str:
    """``1.5 GiB``-style text of a byte count (any size, even absurd ones)."""
    n = float(nbytes)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"  # pragma: no cover


def source() -> str:
    """Where the current limit comes from (for messages)."""
    return f"${ENV}" if os.environ.get(ENV) else f"half the physical memory; set ${ENV} to change"


def check(field: str, value: object, nbytes: float, what: str, limit: int | None = None) -> float:
    """Refuse (BudgetError naming ``field`` = ``value``) when ``nbytes`` exceeds the budget.

    ``what`` says what the estimate counts (``"the traced reflectance table"``).
    Returns ``nbytes`` so that callers can add estimates up.
    """
    cap = memory_limit(limit)
    if not nbytes <= cap:  # also refuses NaN and inf estimates
        raise errors.BudgetError(
            field,
            value,
            f"needs about {describe(nbytes)} for {what}, above the memory limit of {describe(cap)} "
            f"({'the limit= argument' if limit is not None else source()})",
            estimate=int(min(nbytes, 2**63 - 1)) if math.isfinite(nbytes) else 2**63 - 1,
            limit=cap,
        )
    return nbytes


def product(*factors) -> float:
    """The product of ``factors`` as a float (no integer overflow, no huge Python ints)."""
    out = 1.0
    for f in factors:
        out *= float(f)
    return out


def driver(*pairs) -> tuple[str, object]:
    """(key, value) of the factor furthest above its default, from ``(key, value, default)`` triples:
    the key the user set that drives an estimate."""
    key, value, _ = max(pairs, key=lambda p: float(p[1]) / float(p[2]) if p[2] else float(p[1]))
    return key, value


# ----------------------------------------------------------------------------- estimates at the boundaries
# Each is a lower bound of the peak: the arrays that must exist at once, with a
# small factor for the float64 intermediates the code is known to make.

STRAND_POINTS = 32  # points per procedural strand (hairlut.geometry.generate_strands)
STRAND_BYTES = STRAND_POINTS * 3 * 8 * 4  # float64 points, tangents and two work copies
TEXEL_BYTES = 256  # per texel, layer and cluster: frames, positions and maps (float64 / float32)
#: The most texels, all layers of all clusters together, that ``render.resolution = "auto"`` chooses
#: (``hairlut.scene.texel_resolution``): the frame's maps, shading and raster grow with them, and the curly groom's 48
#: clusters × 3 layers × 64 × 32 (295k) took 30 ms a warm frame on the 2-core CPU, so about twice that.
AUTO_TEXELS = 1 << 19
TEXEL_LIGHT_BYTES = 32  # per texel, layer, cluster and light: transmittance and shading terms
MAX_EXPONENT = 1e6  # material.p_I / p_II: the float32 shading's exponent range
MAX_LIGHTS = 256  # direct lights: each one's maps are computed and written separately (synth time grows with it)
PIXEL_BYTES = 64  # per preview pixel: RGBA float32 and its tone-mapped copies
SECTOR_BYTES = 1024  # per sector: its table row, frames, index and the float64 edge points of its extent


def check_scene(
    cfg: dict,
    n_clusters: int,
    n_layers: int,
    n_lights: int,
    limit: int | None = None,
    structure: tuple[str, int, int, Mapping] | None = None,
) -> None:
    """Refuse a scene whose strands, sectors, maps or preview would not fit (keys ``strands.count``,
    ``<where>.s_t``/``s_u``, ``render.resolution``, ``lights.directions``, ``render.preview_size``), or whose
    exponents ``material.p_I``/``p_II`` the float32 shading cannot raise to, or with more than
    :data:`MAX_LIGHTS` direct lights.  ``structure``: (where the cluster keys live, s_t, s_u, their defaults), e.g.
    ``("clusters[0]", 8, 16, {"s_t": 8, "s_u": 16})`` or ``("groom", 8, 16, ...)``: the key furthest above its default is
    the one named."""
    for key in ("p_I", "p_II"):  # float32 shading: cos^p of a huge p overflows on the way (p_I = 1e300)
        p = cfg["material"][key]
        if not p <= MAX_EXPONENT:
            raise errors.ValidationError(
                f"material.{key}",
                p,
                f"at most {MAX_EXPONENT:g} (the shading runs in float32; beyond that the lobe is a single texel anyway)",
            )
    if n_lights > MAX_LIGHTS:
        raise errors.ValidationError(
            "lights.directions",
            f"{n_lights} directions",
            f"at most {MAX_LIGHTS} direct lights (each is shaded and written as its own maps; "
            "light a scene with many directions through [environment] map)",
        )
    n = cfg["strands"]["count"]
    check(
        "strands.count", n, product(n, max(n_clusters, 1), STRAND_BYTES), f"{n} strands in each of {n_clusters} clusters", limit
    )
    if structure is not None:
        where, s_t, s_u, defaults = structure
        key, value = driver((f"{where}.s_t", s_t, defaults["s_t"]), (f"{where}.s_u", s_u, defaults["s_u"]))
        check(
            key,
            value,
            product(max(n_clusters, 1), s_t + 1, max(n_layers, 1), s_u, SECTOR_BYTES),
            f"the sectors of {n_clusters} clusters × {s_t + 1} rings × {n_layers} layers × {s_u} columns",
            limit,
        )
    if cfg["render"]["resolution"] == "auto":  # the planner's choice stays within AUTO_TEXELS
        texels = float(AUTO_TEXELS)
    else:
        n_u, n_t = cfg["render"]["resolution"]
        texels = product(n_u, n_t, max(n_layers, 1), max(n_clusters, 1))
    check(
        "render.resolution",
        cfg["render"]["resolution"],
        texels * TEXEL_BYTES,
        f"the texel frames of {n_layers} layers × {n_clusters} clusters",
        limit,
    )
    check(
        "lights.directions",
        f"{n_lights} directions",
        texels * (TEXEL_BYTES + TEXEL_LIGHT_BYTES * n_lights),
        f"the per-light maps at render.resolution {cfg['render']['resolution']}",
        limit,
    )
    size = cfg["render"]["preview_size"]
    check("render.preview_size", size, product(size, size, PIXEL_BYTES), "the preview image", limit)


HRIR_DEFAULTS = {
    "sectors.count": 512,
    "angles.views": 32,
    "angles.lights": 32,
    "trace.pixels": 64,
    "trace.steps": 64,
    "trace.rays_per_pixel": 1,
    "sectors.grid": 32 * 32,
    "sectors.space.strands": 48,
}
HRIR_BLOCK = 32  # sectors sampled and traced together (hairlut.hrir BLOCK)


def check_hrir(r: dict, limit: int | None = None, *, block: int | None = None, held: int | None = None, note: str = "") -> None:
    """Refuse an ``hrir_db`` recipe whose held tables, tracer working set, grids or splats would not fit.

    ``block``: the sectors sampled and traced together (``--block``; default :data:`HRIR_BLOCK`).
    ``held``: the sectors whose α and reflectance one process holds at once (default: one block, what
    every bake holds: ``resolve_recipe`` checks that).  A copied asset (a plain or cached bake, ``--merge
    copy``, ``hairlut merge``) holds the whole database, a ``--shard`` file its slice, a virtual asset
    (``--distributed``) one block per process: :func:`hairlut.bake.sharding.run` checks what its bake holds
    before it starts.  The leader reads every sector's density grid (the feature index), so those count
    whole.  ``note`` is added to a refusal (why that many are held)."""
    d = HRIR_DEFAULTS
    n, V, L = r["sectors"]["count"], r["angles"]["views"], r["angles"]["lights"]
    block = min(n, HRIR_BLOCK if block is None else int(block))
    held = block if held is None else min(n, int(held))
    P, K, rays = r["trace"]["pixels"], r["trace"]["steps"], r["trace"]["rays_per_pixel"]
    n_s, n_r = r["sectors"]["grid"]
    strands = max(r["sectors"]["space"]["strands"])

    def keyed(*keys):
        vals = {
            "sectors.count": n,
            "angles.views": V,
            "angles.lights": L,
            "trace.pixels": P,
            "trace.steps": K,
            "trace.rays_per_pixel": rays,
            "sectors.grid": n_s * n_r,
            "sectors.space.strands": strands,
        }
        key, _ = driver(*((k, vals[k], d[k]) for k in keys))
        shown = {"sectors.grid": r["sectors"]["grid"], "sectors.space.strands": r["sectors"]["space"]["strands"]}
        return key, shown.get(key, vals[key])

    what = "the database's" if held == n else f"{held} of its {n} sectors'"
    check(
        *keyed(*(("sectors.count",) if held == n else ()), "angles.views", "angles.lights", "trace.pixels"),
        product(held, V, P, L + 1, 4),
        f"{what} α and reflectance tables ({held} sectors × {V} views × {L} lights × {P} pixels, float32{note and '; ' + note})",
        limit,
    )
    check(
        *keyed("angles.views", "angles.lights", "trace.pixels", "trace.steps", "trace.rays_per_pixel"),
        product(V, P, rays, K, 6 + L, 4),
        f"tracing one sector ({V} views × {P}×{rays} rays × {K} steps × {L} lights)",
        limit,
    )
    check(*keyed("sectors.grid", "sectors.count"), product(n, n_s, n_r, 4 * 2), f"{n} density grids of {n_s}×{n_r}", limit)
    check(
        *keyed("sectors.space.strands"),
        product(block, strands, 64, n_s * n_r / (32 * 32) + 1),
        f"the splats of a block of {block} sectors with up to {strands} strands each",
        limit,
    )


def check_sh(r: dict, limit: int | None = None) -> None:
    """Refuse an ``sh_tables`` recipe whose Gaunt tensor or dense grids would not fit."""
    k, b, dense = r["kernel"], r["bands"], r["dense"]
    T = b["transmittance"]
    li = max(b["light_specular"] if k["specular"] else 0, b["light_diffuse"] if k["diffuse"] else 0)
    key = "bands.light_specular" if k["specular"] and b["light_specular"] >= b["light_diffuse"] else "bands.light_diffuse"
    check(
        key,
        b[key.split(".")[1]],
        product((li + T - 1) ** 2, li**2, T**2, 8 * 2),
        f"the float64 Gaunt tensor ({li} light bands, {T} transmittance bands)",
        limit,
    )
    nodes = 6 * math.sqrt(k["p"]) + li + T  # the specular kernel's quadrature grows with √p (p = 1e12: 6e6 nodes)
    if k["specular"]:
        check("kernel.p", k["p"], product(nodes, nodes, 8), f"the specular kernel's quadrature (~{nodes:.3g}² nodes)", limit)
    n = dense["t_resolution"]
    if n:
        per_t = (b["light_diffuse"] ** 2 if k["diffuse"] else 0) + (
            b["light_specular"] ** 2 * dense["theta_v_steps"] if k["specular"] else 0
        )
        check(
            "dense.t_resolution",
            n,
            product(6, n, n, per_t, T**2, 8 * 2),
            f"the dense Rd/Rs grids ({6 * n * n} tangent directions, float64)",
            limit,
        )


__all__ = [
    "ENV",
    "check",
    "check_hrir",
    "check_scene",
    "check_sh",
    "describe",
    "driver",
    "memory_limit",
    "parse_size",
    "physical_memory",
    "product",
]
