"""Procedural grooms for the tests and the picture benchmark (issue 26, deliverable 4): NumPy only, seeded, deterministic.
They live in the package, not in ``tests/``, because ``hairlut bench --only picture`` (``_picture``) renders them too.

Three kinds, each a :class:`hairlut.geometry.Strands` with float32 points, the same number of points in every strand
(so that ``.tfx`` can hold it) and a constant per-point ``thickness`` of ``2 · radius`` (so that the ``.hair`` copy,
which always carries a thickness, and the ``.tfx`` copy, which never does and takes ``[groom] radius``, default 0.1,
describe the same hair):

* :func:`curly`: helical curls of random phase, radius and pitch around centrelines that fall from the scalp;
* :func:`parted`: long straight hair whose roots leave a parting band free and which is combed away from it;
* :func:`crop`: many short strands standing nearly normal to the scalp.

The scalp is a cap of a sphere (:data:`SCALP_CENTRE`, :data:`SCALP_RADIUS`; y up, the face toward +z), in the units of
the vendored grooms (Sintel's head is about 20 units wide).  A strand's centreline leaves the scalp along the normal
and turns toward −y with arc length s as t(s) ∝ n·e^(−s/ℓ) + g·(1 − e^(−s/ℓ)) (ℓ: ``lift``), stepped in equal arcs and
kept outside the head (a point closer than the scalp radius plus a small clearance is pushed out radially).

:func:`write_groom` writes a groom as ``.hair`` and ``.tfx``; :func:`write_scene` writes a scene TOML holding only
``[groom] path``, ``[camera]`` (view, resolution) and ``[lights]`` (directions): every other key is hairlut's default.
:func:`groom_scenes` does both for every kind in :data:`KINDS`.  :func:`mean_curvature`, :func:`roots`,
:func:`root_normals` and :func:`in_parting` measure what the tests check.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from hairlut.geometry import Strands, write_strands

#: The centre and radius of the scalp sphere (y up, the face toward +z).
SCALP_CENTRE = np.array([0.0, 30.0, 0.0])
SCALP_RADIUS = 8.0
#: The axis of the scalp cap: up, tilted 20° toward the back of the head (−z), so the hairline sits high on the forehead.
SCALP_AXIS = np.array([0.0, math.cos(math.radians(20.0)), -math.sin(math.radians(20.0))])
#: How far outside the scalp sphere a falling strand is kept.
CLEARANCE = 0.15
#: Three views per groom (directions toward the viewer) for the picture benchmark: front, side, three-quarter back.
VIEWS = {"front": [0.5, 0.15, 1.0], "side": [1.0, 0.1, 0.0], "back": [-0.6, 0.3, -1.0]}
#: One directional light from the upper front right (the direction toward the light).
LIGHT = [0.5, 0.8, 1.0]
_DOWN = np.array([0.0, -1.0, 0.0])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def _basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``axis`` to a right-handed orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = _unit(np.cross(axis, helper))
    return e1, np.cross(axis, e1)


def scalp_roots(rng: np.random.Generator, n: int, cap_deg: float = 75.0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` roots uniform in area over the scalp cap of half-angle ``cap_deg`` about :data:`SCALP_AXIS`:
    (positions (n, 3), outward unit normals (n, 3)).  Uniform in area: cos of the polar angle uniform in [cos cap, 1]."""
    cos_t = rng.uniform(math.cos(math.radians(cap_deg)), 1.0, n)
    sin_t = np.sqrt(1.0 - cos_t**2)
    phi = rng.uniform(0.0, 2.0 * math.pi, n)
    e1, e2 = _basis(SCALP_AXIS)
    normals = cos_t[:, None] * SCALP_AXIS + sin_t[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    return SCALP_CENTRE + SCALP_RADIUS * normals, normals


def cap_area(cap_deg: float) -> float:
    """The area of the scalp cap of half-angle ``cap_deg``: 2πR²(1 − cos cap)."""
    return 2.0 * math.pi * SCALP_RADIUS**2 * (1.0 - math.cos(math.radians(cap_deg)))


def _keep_outside(p: np.ndarray, margin: float = CLEARANCE) -> np.ndarray:
    """``p`` (..., 3) with every point closer to :data:`SCALP_CENTRE` than the scalp radius plus ``margin`` pushed out
    radially onto that sphere."""
    d = p - SCALP_CENTRE
    r = np.linalg.norm(d, axis=-1, keepdims=True)
    floor = SCALP_RADIUS + margin
    return np.where(r < floor, SCALP_CENTRE + d / np.maximum(r, 1e-300) * floor, p)


def _fall(roots: np.ndarray, start: np.ndarray, lengths: np.ndarray, points: int, lift: np.ndarray) -> np.ndarray:
    """(S, points, 3) centrelines: from each root along ``start`` (S, 3), turning toward −y over the arc length ``lift``
    (module docstring), ``lengths`` (S,) long in ``points − 1`` equal steps, kept outside the head."""
    out = np.empty((len(roots), points, 3))
    out[:, 0] = roots
    ds = lengths / (points - 1)
    for k in range(1, points):
        s = (k - 0.5) * ds
        w = 1.0 - np.exp(-s / lift)
        tangent = _unit((1.0 - w)[:, None] * start + w[:, None] * _DOWN)
        nxt = out[:, k - 1] + tangent * ds[:, None]
        out[:, k] = _keep_outside(nxt) if k > 1 else nxt
    return out


def _frames(line: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation-minimising normal and binormal (S, P, 3) along polylines (S, P, 3), by double reflection
    (Wang, Jüttler, Zheng & Liu 2008, "Computation of rotation minimizing frames", §4)."""
    seg = np.diff(line, axis=1)
    t = _unit(np.concatenate([seg[:, :1], 0.5 * (seg[:, 1:] + seg[:, :-1]), seg[:, -1:]], axis=1))
    S, P, _ = line.shape
    normal = np.empty((S, P, 3))
    helper = np.where(np.abs(t[:, 0, :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    normal[:, 0] = _unit(np.cross(t[:, 0], helper))
    for k in range(P - 1):
        v1 = line[:, k + 1] - line[:, k]
        c1 = np.maximum(np.sum(v1 * v1, axis=1, keepdims=True), 1e-300)
        r_l = normal[:, k] - 2.0 / c1 * np.sum(v1 * normal[:, k], axis=1, keepdims=True) * v1
        t_l = t[:, k] - 2.0 / c1 * np.sum(v1 * t[:, k], axis=1, keepdims=True) * v1
        v2 = t[:, k + 1] - t_l
        c2 = np.maximum(np.sum(v2 * v2, axis=1, keepdims=True), 1e-300)
        normal[:, k + 1] = _unit(r_l - 2.0 / c2 * np.sum(v2 * r_l, axis=1, keepdims=True) * v2)
    return normal, np.cross(t, normal)


def _strands(lines: np.ndarray, radius: float) -> Strands:
    pts = lines.astype(np.float32)
    return Strands.from_padded(pts, thickness=np.full(pts.shape[0] * pts.shape[1], 2.0 * radius, np.float32))


def curly(
    n_strands: int = 400,
    points: int = 32,
    *,
    seed: int = 0,
    length: tuple[float, float] = (14.0, 18.0),
    curl_radius: tuple[float, float] = (0.6, 1.2),
    curl_pitch: tuple[float, float] = (3.5, 5.5),
    lift: float = 2.5,
    radius: float = 0.1,
) -> Strands:
    """Curly, about shoulder-length hair: each strand a helix of random phase, radius (``curl_radius``) and pitch
    (``curl_pitch``: the rise of one turn along the centreline) around a centreline ``length`` long that falls from the
    scalp.  The helix is x(s) = c(s) + ρ(s)·(cos(φ + 2πs/pitch)·n(s) + sin(φ + 2πs/pitch)·b(s)) in the centreline's
    rotation-minimising frame (n, b), its radius ρ growing from 0 at the root over the first 15 % of the length
    (smoothstep) so that the root stays on the scalp; its curvature is ρ/(ρ² + (pitch/2π)²).  About 10 points a turn
    at the defaults."""
    rng = np.random.default_rng(seed)
    roots, normals = scalp_roots(rng, n_strands)
    lengths = rng.uniform(*length, n_strands)
    centre = _fall(roots, normals, lengths, points, np.full(n_strands, lift))
    normal, binormal = _frames(centre)
    s = np.linspace(0.0, 1.0, points)[None, :] * lengths[:, None]
    ramp = np.clip(s / (0.15 * lengths[:, None]), 0.0, 1.0)
    rho = rng.uniform(*curl_radius, n_strands)[:, None] * ramp * ramp * (3.0 - 2.0 * ramp)
    angle = rng.uniform(0.0, 2.0 * math.pi, n_strands)[:, None] + 2.0 * math.pi * s / rng.uniform(*curl_pitch, n_strands)[:, None]
    lines = centre + rho[..., None] * (np.cos(angle)[..., None] * normal + np.sin(angle)[..., None] * binormal)
    lines[:, 1:] = _keep_outside(lines[:, 1:])
    return _strands(lines, radius)


def in_parting(points: np.ndarray, parting_x: float = 0.0, parting_width: float = 1.2) -> np.ndarray:
    """Which of ``points`` (N, 3) lie in the parting band: within ``parting_width``/2 of the plane x = ``parting_x``,
    on the top of the head (above the scalp centre) and from the crown forward (z > −0.3 · scalp radius)."""
    p = np.asarray(points, np.float64)
    return (
        (np.abs(p[:, 0] - parting_x) < 0.5 * parting_width)
        & (p[:, 1] > SCALP_CENTRE[1])
        & (p[:, 2] - SCALP_CENTRE[2] > -0.3 * SCALP_RADIUS)
    )


def parted(
    n_strands: int = 500,
    points: int = 32,
    *,
    seed: int = 0,
    length: tuple[float, float] = (22.0, 28.0),
    parting_x: float = 0.0,
    parting_width: float = 1.2,
    comb: float = 0.8,
    lift: float = 3.0,
    radius: float = 0.1,
) -> Strands:
    """Long straight hair with a parting: the roots cover the scalp cap but the parting band (:func:`in_parting`), and
    each strand leaves the scalp combed away from the parting (its start direction the normal plus ``comb`` times ±x,
    the side of its root) before it falls.  A few degrees of random start direction keep the strands apart."""
    rng = np.random.default_rng(seed)
    roots, normals = np.empty((0, 3)), np.empty((0, 3))
    while len(roots) < n_strands:  # rejection sampling: the band holds under a tenth of the cap
        r, n = scalp_roots(rng, 2 * n_strands)
        keep = ~in_parting(r, parting_x, parting_width)
        roots, normals = np.concatenate([roots, r[keep]]), np.concatenate([normals, n[keep]])
    roots, normals = roots[:n_strands], normals[:n_strands]
    side = np.where(roots[:, 0] >= parting_x, 1.0, -1.0)
    start = _unit(normals + comb * side[:, None] * np.array([1.0, 0.0, 0.0]) + 0.08 * rng.normal(size=(n_strands, 3)))
    lines = _fall(roots, start, rng.uniform(*length, n_strands), points, rng.uniform(0.8, 1.2, n_strands) * lift)
    return _strands(lines, radius)


def crop(
    n_strands: int = 600,
    points: int = 8,
    *,
    seed: int = 0,
    length: tuple[float, float] = (1.0, 1.6),
    tilt_deg: float = 12.0,
    cap_deg: float = 80.0,
    radius: float = 0.1,
) -> Strands:
    """A short dense crop: ``n_strands`` strands ``length`` long over a wide cap (``cap_deg``), each nearly straight
    and tilted at most ``tilt_deg`` from the scalp normal (a random direction), bending a little backward (−z) along
    its length."""
    rng = np.random.default_rng(seed)
    roots, normals = scalp_roots(rng, n_strands, cap_deg)
    e1 = _unit(np.cross(normals, np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]])))
    e2 = np.cross(normals, e1)
    tilt = np.radians(tilt_deg) * np.sqrt(rng.uniform(0.0, 1.0, n_strands))
    phi = rng.uniform(0.0, 2.0 * math.pi, n_strands)
    start = np.cos(tilt)[:, None] * normals + np.sin(tilt)[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    s = np.linspace(0.0, 1.0, points)[None, :, None] * rng.uniform(*length, n_strands)[:, None, None]
    lines = roots[:, None] + start[:, None] * s + 0.04 * s**2 * np.array([0.0, 0.0, -1.0])
    return _strands(lines, radius)


#: The generated kinds, by name: each a function (n_strands, points, *, seed, ...) → Strands.
KINDS = {"curly": curly, "parted": parted, "crop": crop}
#: The formats a groom is written in (:func:`write_groom`).
FORMATS = ("hair", "tfx")
#: The generators and the views as ``hairlut.bench`` lends them to the repository's benchmarks.
GROOM_KINDS, GROOM_VIEWS = KINDS, VIEWS


# ----------------------------------------------------------------------------- measures


def roots(strands: Strands) -> np.ndarray:
    """(S, 3) float64: the first point of every strand."""
    return strands.points[strands.offsets[:-1]].astype(np.float64)


def root_normals(strands: Strands) -> np.ndarray:
    """(S, 3): the scalp's outward normal under each root."""
    return _unit(roots(strands) - SCALP_CENTRE)


def mean_curvature(strands: Strands) -> float:
    """The groom's mean discrete curvature: the sum of the turning angles between consecutive segments over the sum
    of the strand lengths (radians per unit length)."""
    turned = 0.0
    pts = strands.points.astype(np.float64)
    for i in range(strands.n_strands):
        seg = np.diff(pts[strands.offsets[i] : strands.offsets[i + 1]], axis=0)
        u = _unit(seg)
        turned += float(np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0)).sum())
    return turned / float(strands.lengths().sum())


# ----------------------------------------------------------------------------- files


def write_groom(folder, name: str, strands: Strands, formats=FORMATS) -> dict[str, Path]:
    """Write ``strands`` as ``folder/name.<format>`` for each of ``formats``; {format: path}."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for fmt in formats:
        out[fmt] = folder / f"{name}.{fmt}"
        write_strands(out[fmt], strands)
    return out


def scene_text(groom: str, *, view=VIEWS["front"], light=LIGHT, resolution=(128, 128)) -> str:
    """A scene TOML of only ``[groom] path`` (``groom``, relative to the scene file), ``[camera] view`` and
    ``resolution``, and ``[lights] directions`` (one light): every other key is hairlut's default."""

    def vec(v):
        return "[" + ", ".join(f"{float(x):g}" for x in v) + "]"

    return (
        f"[groom]\npath = {json.dumps(groom)}\n\n"
        f"[camera]\nview = {vec(view)}\nresolution = [{int(resolution[0])}, {int(resolution[1])}]\n\n"
        f"[lights]\ndirections = [{vec(light)}]\n"
    )


def write_scene(path, groom_file, **camera) -> Path:
    """Write :func:`scene_text` for ``groom_file`` to ``path`` (the groom named relative to the scene's folder when it
    lies in it or below); ``camera``: ``view``, ``light``, ``resolution``."""
    path, groom_file = Path(path), Path(groom_file)
    try:
        rel = groom_file.resolve().relative_to(path.parent.resolve()).as_posix()
    except ValueError:
        rel = groom_file.resolve().as_posix()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(scene_text(rel, **camera))
    return path


def groom_scenes(folder, kinds=tuple(KINDS), fmt: str = "hair", *, seed: int = 0, sizes=None, **camera) -> dict[str, Path]:
    """Generate each of ``kinds`` (``sizes``: {kind: {n_strands, points, ...}} over the defaults), write it in both
    formats under ``folder`` and a default scene ``folder/<kind>-<fmt>.toml`` naming its ``fmt`` file; {kind: scene}."""
    out = {}
    for kind in kinds:
        strands = KINDS[kind](seed=seed, **(sizes or {}).get(kind, {}))
        files = write_groom(folder, kind, strands)
        out[kind] = write_scene(Path(folder) / f"{kind}-{fmt}.toml", files[fmt], **camera)
    return out
