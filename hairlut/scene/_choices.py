"""What a scene leaves out, chosen from its groom and its settings (issue 26: right by default).

Each rule takes what it needs (the strands, the scene's given keys, the sector count) and returns a
:class:`Choice`: the value, whether the scene gave it, the reason in words, and the error it predicts, as
measured by the picture benchmark (``hairlut bench --only picture``: the layered render against the strand
render converged to 0.02, 128², defaults otherwise).  A value the scene gives is always kept.  The planner
prints every choice (``hairlut plan``); the online module and the cluster fit read the same rules, so what
the plan says is what runs.

* ``groom.clusters`` (:func:`cluster_count`): √S · (1 + turns), S strands of a mean of ``turns`` full turns of
  their tangent (curls), between :data:`CLUSTERS_MIN` and :data:`CLUSTERS_MAX`, and at least
  :data:`STRANDS_PER_CLUSTER` strands a cluster (a cluster's cross-section is measured from its strands' spread).
  A groom that bends more needs more clusters to keep its shape: a few clusters turn curls into a straight
  curtain.  Sintel (228 strands, 0.2 turns): 18; the test suite's curly groom (400, 2.9 turns): 48.
* ``shadows.method`` (:func:`shadow_method`): the light-oriented density map (bertails), whose transmittance
  follows each light through the strands' own width; eq 12's s-map when the scene sets its knobs
  (``material.k_shadow`` or ``shadow_form``); none when no strand can cast a shadow.
* ``groom.layer_radii`` (:func:`layer_shells`): the paper's three shells (``cluster_defaults``; a groom has no core).
  The shell count barely moves the picture: on the picture benchmark's scenes two and four shells changed FLIP by at
  most 0.01 and mean α by at most 4 points, two a little worse from the side (the crop 0.094 → 0.102) for 2/3 of the
  texels, so the rule is the measured default, not a function of the groom.
* ``render.resolution`` (:func:`texel_resolution`): the texels of every layer, from each cluster's projected size
  through the camera: a texel row every :data:`ROW_PIXELS` pixels along the cluster and a column every
  :data:`COLUMN_PIXELS` across it (its visible half-circumference holds half the columns), for the 90th percentile
  cluster, at least :data:`TEXELS_PER_SECTOR` a sector each way, kept within :data:`~hairlut.budget.AUTO_TEXELS`
  texels in all.  The picture's detail is finer across the
  strands than along them, and texels smaller than a pixel add cost, not picture.
* ``tables.hrir.sectors.grid`` (:func:`sector_grid`): the density grid each sector's strands are splatted on before
  the planar march (satf §5.1), fine enough that the median sector's strand Gaussian (σ = r/√2, eq 3's splat) spans
  :data:`SIGMA_CELLS` cells, with :data:`STEPS_PER_CELL` march steps a cell, within :data:`GRID` (the default 32²
  at least).  A coarse grid smears a thin strand over cells it does not cover, and a smeared optical depth
  covers more (Jensen): α and re come out high.  Thick strands keep the default grid; thin ones get a finer one.
* ``render.views`` and ``render.shading_pixels`` (:func:`table_layout`): the scene table's view angles and re/α pixel
  bins follow the sector grid n (a finer grid holds sharper projections, which change faster with the view and across
  the pixels): :data:`VIEWS_PER_CELL` · n views rounded up to :data:`VIEW_STEP`, at least :data:`VIEWS_MIN`, and the
  fewest bins dividing the trace's pixels that are at least :data:`BINS_PER_CELL` · n.  On the default 32² they are
  the defaults, 64 views and 8 bins.  ``render.terms`` stays 2: terms beyond 2 bought nothing (benchmarks/records.md).
* ``render.layer_reads`` (:func:`layer_reads`): ``track`` (every sector a texel's in-plane ray crosses) while its
  sweep fits the frame budget, ``pair`` (eq 7) beyond: at paper scale (53,040 sectors) track reads cost 41.6 ms a
  frame against 13.5 ms for pair on the 2-core CPU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The cluster count's bounds (``groom.clusters = "auto"``).
CLUSTERS_MIN, CLUSTERS_MAX = 4, 48
#: Fewest strands a fitted cluster holds when the count is chosen.
STRANDS_PER_CLUSTER = 8
#: Most sectors for which ``layer_reads = "auto"`` reads the whole track: track reads cost ~0.8 µs a sector on the
#: 2-core CPU (41.6 ms at 53,040 sectors), so 16,384 sectors keep them within ~13 ms of the frame.
TRACK_SECTORS = 16384

#: Pixels along a cluster per texel row, and across it per column (``render.resolution = "auto"``).
ROW_PIXELS, COLUMN_PIXELS = 2.5, 2.0
#: The bounds of the chosen rows and columns, and the step they are rounded up to.
ROWS, COLUMNS, TEXEL_STEP = (8, 256), (16, 512), 4
#: The fewest texels per sector along each axis: eq 7 interpolates a texel row between the two cross-sections around
#: it, and the short clusters of a crop at 128² (8 rows for 8 steps) gave mean α 6–13 % high and up to 2.2 % of it
#: outside the strands, against 2 % and 0.7 % at 4 rows a step.
TEXELS_PER_SECTOR = 4

#: The sector grid (``tables.hrir.sectors.grid``): its bounds, its step, the cells the median sector's strand σ spans
#: (0.88 cells missed the direct-map targets on Ratboy's thin strands, 1.33 met them: ``MEASURED["grid"]``), and the
#: march steps per cell.
GRID, GRID_STEP, SIGMA_CELLS, STEPS_PER_CELL = (32, 128), 16, 1.2, 2

#: The scene table's layout (``render.views``, ``render.shading_pixels``) per sector grid side n: views a cell, their
#: step and least count, and bins a cell (calibrated on Sintel at 32², Ratboy at 48² and 96²: ``MEASURED["layout"]``).
VIEWS_PER_CELL, VIEW_STEP, VIEWS_MIN, BINS_PER_CELL = 4 / 3, 32, 64, 1 / 4

#: Measured by the picture benchmark (Sintel's groom and, where said, the other untuned scenes; defaults, 128², strand
#: render converged to 0.02; 2026-12-04 and 2026-12-05, benchmarks/records.md), the figures each choice's ``predicted``
#: quotes.
MEASURED = {
    "clusters": "Sintel from the front: 9 clusters FLIP 0.154 (mean α +1.4 %), 18 clusters 0.134 (−1.9 %), 36 clusters "
    "0.117 (−5.6 %) (hairlut bench --only picture, docs/bench/picture)",
    "layers": "FLIP against the strand render with 2 / 3 / 4 shells: Sintel front 0.132 / 0.131 / 0.127, back "
    "0.108 / 0.106 / 0.103; the crop front 0.084 / 0.081 / 0.079, side 0.102 / 0.094 (2 / 3); mean α within 4 points",
    "light_oriented": "colour per unit α 0.82–1.20× the strand render's on 10 untuned scenes (Sintel front 0.99×; "
    "eq 12's s-map on Sintel: 1.62×)",
    "smap": "Sintel: colour per unit α 1.62× the strand render's (eq 12 darkens only inner layers, whatever the light)",
    "texels": "no resolution limits the picture: at 128², Sintel [72, 36] FLIP 0.131 against 0.132 at [64, 32], the "
    "curly groom [44, 32] 0.138 against 0.138; at 768², Sintel [96, 48] FLIP 0.198 against 0.207, α outside 1.8 % "
    "against 2.5 %, mean α 6.8 % low against 4.9 % (the trim's two texels are narrower)",
    "grid": "Ratboy at strand radius 0.05, direct maps against the 192² truth: 32² (0.88 cells a strand σ) re 0.132, "
    "α 0.064, coverage 0.051 (the direct targets: 0.12, 0.06, 0.035); 48² (1.33 cells) 0.079, 0.033, 0.028; 96² 0.028, "
    "0.011, 0.010",
    "layout": "against the direct trace at twice the grid (scene targets re 0.15, α 0.08): Sintel on 32² with 64 views "
    "and 8 bins re 0.113, α 0.043; Ratboy at radius 0.05 on 48² with 64 views and 16 bins re 0.118, α 0.042; the "
    "12-cluster Ratboy on 96² with 128 views and 32 bins re 0.130, α 0.040 (64 views: α 0.081; 16 bins: re 0.150)",
    "track": "Sintel: mean α −2.2 % against the strand render (pair: −24.9 %)",
    "pair": "Sintel: mean α −24.9 % against the strand render (track: −2.2 %)",
}


@dataclass(frozen=True)
class Choice:
    """One knob: ``key`` (dotted), ``value``, ``given`` (the scene set it), ``reason`` and ``predicted`` (the error
    the picture benchmark measured for it, in words, or None)."""

    key: str
    value: object
    given: bool
    reason: str
    predicted: str | None = None

    def to_json(self) -> dict:
        """The choice as a JSON object, as `hairlut plan --json` prints it."""
        return {"key": self.key, "value": self.value, "given": self.given, "reason": self.reason, "predicted": self.predicted}


def given_choice(key: str, value) -> Choice:
    return Choice(key, value, True, "the scene's own value")


def strand_turns(strands) -> float:
    """The mean over strands of the total turning of the tangent along the strand, in full turns (2π)."""
    p = np.asarray(strands.points, np.float64)
    d = np.diff(p, axis=0)
    ln = np.linalg.norm(d, axis=1)
    owner = np.repeat(np.arange(strands.n_strands), strands.counts)[1:]
    inside = np.ones(len(d), bool)
    inside[strands.offsets[1:-1] - 1] = False  # the step from one strand's last point to the next one's first
    ok = inside & (ln > 0)
    t = np.zeros_like(d)
    t[ok] = d[ok] / ln[ok, None]
    pair = ok[1:] & ok[:-1] & (owner[1:] == owner[:-1])
    angle = np.arccos(np.clip((t[1:] * t[:-1]).sum(axis=1), -1.0, 1.0)) * pair
    turns = np.bincount(owner[1:], weights=angle, minlength=strands.n_strands) / (2.0 * math.pi)
    return float(turns.mean()) if len(turns) else 0.0


def cluster_count(strands, given=None) -> Choice:
    """``groom.clusters``: ``given`` (an int) or √S · (1 + turns) within the bounds (module docstring)."""
    s = int(strands.n_strands)
    if given not in (None, "auto"):
        return given_choice("groom.clusters", min(int(given), s))
    turns = strand_turns(strands)
    raw = math.sqrt(s) * (1.0 + turns)
    cap = max(1, min(CLUSTERS_MAX, s // STRANDS_PER_CLUSTER))
    n = max(min(CLUSTERS_MIN, s), min(cap, round(raw)))
    return Choice(
        "groom.clusters",
        int(n),
        False,
        f"√{s} strands × (1 + {turns:.2f} turns a strand) = {raw:.0f}, kept in [{CLUSTERS_MIN}, {cap}] "
        f"(≤ {CLUSTERS_MAX}, ≥ {STRANDS_PER_CLUSTER} strands a cluster): a groom that bends more needs more clusters to keep its shape",
        MEASURED["clusters"],
    )


def layer_shells(given=None, core: float = 0.0) -> Choice:
    """``groom.layer_radii``: ``given`` (the scene's list) or the default shells (module docstring) around a core at
    ``core`` (``groom.core_radius``: none by default)."""
    from ..geometry.cluster_defaults import STRUCTURE_DEFAULTS

    if given is not None:
        return given_choice("groom.layer_radii", list(given))
    radii = list(STRUCTURE_DEFAULTS["layer_radii"])
    return Choice(
        "groom.layer_radii",
        radii,
        False,
        f"{len(radii)} shells at v = {', '.join(f'{r:g}' for r in radii)}"
        + (f" around a core at {core:g}" if core > 0 else ", no core")
        + ": the paper's count; two or four shells moved the picture benchmark's FLIP by at most 0.01",
        MEASURED["layers"],
    )


def shadow_method(config: dict, given: dict, has_strands: bool) -> Choice:
    """``shadows.method`` for a scene's resolved ``config`` and its ``given`` tables (module docstring)."""
    method = config["shadows"]["method"]
    if method != "auto":
        return given_choice("shadows.method", method)
    smap_keys = sorted(k for k in ("k_shadow", "shadow_form") if k in given.get("material", {}))
    if not has_strands:
        return Choice("shadows.method", "none", False, "the clusters hold no strands: nothing casts a shadow")
    if smap_keys:
        return Choice(
            "shadows.method",
            "smap",
            False,
            f"the scene sets eq 12's own knobs ({', '.join('material.' + k for k in smap_keys)}): eq 12's s-map",
            MEASURED["smap"],
        )
    return Choice(
        "shadows.method",
        "light_oriented",
        False,
        "the light-oriented density map (bertails): each light's transmittance through the strands' own width, as "
        "the strands shade each other",
        MEASURED["light_oriented"],
    )


def texel_resolution(value, lengths_px, widths_px, layers: int, sectors=(8, 8)) -> Choice:
    """``render.resolution`` for ``value`` (``auto`` or [u columns, t rows]) and clusters whose trajectories project
    to ``lengths_px`` pixels and whose widths (twice the larger half axis) to ``widths_px`` (module docstring);
    ``layers``: the layer surfaces of all clusters together; ``sectors``: (s_u, s_t), the sectors' columns and steps,
    of which each gets at least :data:`TEXELS_PER_SECTOR` texels each way."""
    if value != "auto":
        return given_choice("render.resolution", list(value))
    from ..budget import AUTO_TEXELS

    def up(x, lo_hi):
        return int(min(max(TEXEL_STEP * math.ceil(x / TEXEL_STEP), lo_hi[0]), lo_hi[1]))

    length = float(np.percentile(lengths_px, 90)) if len(lengths_px) else 0.0
    width = float(np.percentile(widths_px, 90)) if len(widths_px) else 0.0
    s_u, s_t = sectors
    rows = max(up(length / ROW_PIXELS, ROWS), up(TEXELS_PER_SECTOR * s_t, ROWS))
    cols = max(up(math.pi * width / COLUMN_PIXELS, COLUMNS), up(TEXELS_PER_SECTOR * s_u, COLUMNS))
    shrink = math.sqrt(AUTO_TEXELS / max(rows * cols * max(layers, 1), 1))
    capped = shrink < 1.0
    if capped:  # the same share off both, rounded down; then off the other where one is at its least
        rows = max(ROWS[0], TEXEL_STEP * int(rows * shrink / TEXEL_STEP))
        cols = max(COLUMNS[0], TEXEL_STEP * int(cols * shrink / TEXEL_STEP))
        room = AUTO_TEXELS // max(layers, 1)
        cols = max(COLUMNS[0], min(cols, TEXEL_STEP * (room // rows // TEXEL_STEP)))
        rows = max(ROWS[0], min(rows, TEXEL_STEP * (room // cols // TEXEL_STEP)))
    return Choice(
        "render.resolution",
        [cols, rows],
        False,
        f"clusters {length:.0f} px long and {width:.0f} px wide through the camera (90th percentile): a row every "
        f"{ROW_PIXELS:g} px along, a column every {COLUMN_PIXELS:g} px across"
        + (f", shrunk to {AUTO_TEXELS:,} texels over {layers} layers" if capped else f", {rows * cols * layers:,} texels in all"),
        MEASURED["texels"],
    )


def sector_grid(given: dict, radius_rel) -> Choice:
    """``tables.hrir.sectors.grid`` for a scene's ``[tables.hrir]`` table ``given`` and its sectors' strand radii
    relative to √area ``radius_rel`` (NaN for an empty sector): n × n cells, n = :data:`SIGMA_CELLS` / (σ/r ·
    median radius_rel) rounded up to :data:`GRID_STEP` within :data:`GRID` (module docstring)."""
    from ..geometry.splats import SIGMA_PER_RADIUS

    grid = given.get("sectors", {}).get("grid")
    if grid is not None:
        return given_choice("tables.hrir.sectors.grid", list(grid))
    r = np.asarray(radius_rel, np.float64)
    r = r[np.isfinite(r) & (r > 0)]
    if not len(r):
        return Choice("tables.hrir.sectors.grid", [GRID[0]] * 2, False, "no sector holds a strand: the default grid")
    median = float(np.median(r))
    raw = SIGMA_CELLS / (SIGMA_PER_RADIUS * median)
    n = int(min(max(GRID_STEP * math.ceil(raw / GRID_STEP), GRID[0]), GRID[1]))
    steps = "" if "steps" in given.get("trace", {}) else f", {STEPS_PER_CELL * n} march steps"
    return Choice(
        "tables.hrir.sectors.grid",
        [n, n],
        False,
        f"median strand radius {median:.3g} √area of a sector: its splat σ spans {SIGMA_CELLS:g} cells at {raw:.0f}², kept in "
        f"[{GRID[0]}, {GRID[1]}]²{steps}, {SIGMA_PER_RADIUS * median * n:.2f} cells a strand σ (a coarser grid smears thin "
        "strands and overstates α)",
        MEASURED["grid"],
    )


def hrir_with_grid(given: dict, choice: Choice) -> dict:
    """The scene's ``[tables.hrir]`` table ``given`` with a chosen sector grid (:func:`sector_grid`) folded in, and
    :data:`STEPS_PER_CELL` march steps a cell unless ``trace.steps`` is given; a given grid leaves it as it is."""
    if choice.given:
        return dict(given)
    n = choice.value[0]
    trace = {"steps": STEPS_PER_CELL * n, **given.get("trace", {})}
    return {**given, "sectors": {**given.get("sectors", {}), "grid": list(choice.value)}, "trace": trace}


def table_layout(render: dict, grid: int, pixels: int) -> tuple[Choice, Choice]:
    """``render.views`` and ``render.shading_pixels`` of the scene table for a scene's ``[render]`` table, its sector
    grid side ``grid`` (:func:`sector_grid`) and the trace's ``pixels`` per sector projection (module docstring)."""
    views, bins = render["views"], render["shading_pixels"]
    out = []
    if views != "auto":
        out.append(given_choice("render.views", views))
    else:
        n = max(VIEWS_MIN, VIEW_STEP * math.ceil(VIEWS_PER_CELL * grid / VIEW_STEP))
        out.append(
            Choice(
                "render.views",
                int(n),
                False,
                f"the scene table's view angles: {VIEWS_PER_CELL:.3g} a cell of the {grid}² sector grid, rounded up to "
                f"{VIEW_STEP}, at least {VIEWS_MIN} (a finer grid's projections change faster with the view)",
                MEASURED["layout"],
            )
        )
    if bins != "auto":
        out.append(given_choice("render.shading_pixels", bins))
    else:
        want = BINS_PER_CELL * grid
        b = min((d for d in range(1, pixels + 1) if pixels % d == 0 and d >= want), default=pixels)
        out.append(
            Choice(
                "render.shading_pixels",
                int(b),
                False,
                f"the scene table's re/α bins: the fewest dividing the trace's {pixels} pixels that are at least "
                f"{BINS_PER_CELL:g} a cell of the {grid}² sector grid",
                MEASURED["layout"],
            )
        )
    return out[0], out[1]


def layer_reads(value: str, sectors: int) -> Choice:
    """``render.layer_reads`` for ``value`` (``auto``, ``pair`` or ``track``) and a scene of ``sectors`` sectors."""
    if value != "auto":
        return given_choice("render.layer_reads", value)
    if sectors <= TRACK_SECTORS:
        return Choice(
            "render.layer_reads",
            "track",
            False,
            f"{sectors} sectors ≤ {TRACK_SECTORS}: every sector a texel's in-plane ray crosses, within ~"
            f"{sectors * 41.6 / 53040:.1f} ms a frame on the 2-core CPU",
            MEASURED["track"],
        )
    return Choice(
        "render.layer_reads",
        "pair",
        False,
        f"{sectors} sectors > {TRACK_SECTORS}: track reads would cost ~{sectors * 41.6 / 53040:.0f} ms a frame on the "
        "2-core CPU, so eq 7's pair of sectors",
        MEASURED["pair"],
    )
