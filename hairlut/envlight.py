"""Environment light: an EXR environment map → SH coefficients a_i (xing §4).

a_i = ∫ L(ω) Y_i(ω) dω is computed as Σ_texels L(texel) Y_i(centre) ΔΩ(texel),
with ΔΩ the texel's exact solid angle.  ω points toward the light.

Layouts (all read from one EXR file):

``latlong``  H × W (2:1).  Row r, column c ↦ θ = π(r+½)/H from +up, φ = 2π(c+½)/W
             from +x toward +y (z-up); ΔΩ = (2π/W)(cos θ_top − cos θ_bottom).
``cube``     six square faces.  Either a multi-part file with parts named
             ``+x -x +y -y +z -z`` (or ``px nx py ny pz nz``), or one image 6n high
             and n wide with the faces stacked in that order (OpenEXR's ENVMAP_CUBE),
             a horizontal cross (4n × 3n) or a vertical cross (3n × 4n):

                     horizontal          vertical
                        +y                  +y
                     -x +z +x -z         -x +z +x
                        -y                  -y
                                            -z (rotated 180°)

             Face pixels follow the OpenGL cube-map convention: for face
             (major, sc, tc) = (+x: −z, −y), (−x: +z, −y), (+y: +x, +z),
             (−y: +x, −z), (+z: +x, −y), (−z: −x, −y), pixel (r, c) looks along
             major + sc·u + tc·v with u = 2(c+½)/n − 1, v = 2(r+½)/n − 1.
             ΔΩ is exact: the solid angle of the texel's square on the face.

``up="y"`` maps the layout's +z to world +y (x→z, y→x, z→y), for y-up maps.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import errors
from .assets import Axis, Variable, read_exr, read_table, write_table
from .sh import real_sh

FACES = ("+x", "-x", "+y", "-y", "+z", "-z")
_FACE_ALIASES = {"px": "+x", "nx": "-x", "py": "+y", "ny": "-y", "pz": "+z", "nz": "-z"}
# (major, sc, tc) per face, OpenGL convention
_FACE_AXES = {
    "+x": ((1, 0, 0), (0, 0, -1), (0, -1, 0)),
    "-x": ((-1, 0, 0), (0, 0, 1), (0, -1, 0)),
    "+y": ((0, 1, 0), (1, 0, 0), (0, 0, 1)),
    "-y": ((0, -1, 0), (1, 0, 0), (0, 0, -1)),
    "+z": ((0, 0, 1), (1, 0, 0), (0, -1, 0)),
    "-z": ((0, 0, -1), (-1, 0, 0), (0, -1, 0)),
}
LAYOUTS = ("auto", "latlong", "cube")


@dataclass(frozen=True)
class EnvSamples:
    """An environment map as directions (N, 3), exact solid angles (N,) and radiance (N, C)."""

    dirs: np.ndarray
    solid_angle: np.ndarray
    radiance: np.ndarray
    channels: tuple[str, ...]
    layout: str


@dataclass(frozen=True)
class EnvLight:
    """SH coefficients of an environment light and how well they represent it."""

    coeffs: np.ndarray  # ((lmax+1)², C)
    channels: tuple[str, ...]
    lmax: int
    band_error: np.ndarray  # (C,) relative L2 energy left out: ‖L − Σ a_i Y_i‖ / ‖L‖
    layout: str
    source_sha256: str | None = None


# ----------------------------------------------------------------------------- geometry


def latlong_samples(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Texel-centre directions (H, W, 3) and exact solid angles (H, W) of a z-up lat-long map."""
    edges = np.linspace(0.0, np.pi, height + 1)
    theta = 0.5 * (edges[:-1] + edges[1:])
    phi = 2 * np.pi * (np.arange(width) + 0.5) / width
    st = np.sin(theta)[:, None]
    dirs = np.stack(np.broadcast_arrays(st * np.cos(phi), st * np.sin(phi), np.cos(theta)[:, None]), axis=-1)
    omega = (2 * np.pi / width) * (np.cos(edges[:-1]) - np.cos(edges[1:]))
    return dirs, np.broadcast_to(omega[:, None], (height, width)).copy()


def _corner_area(u, v):
    return np.arctan2(u * v, np.sqrt(u * u + v * v + 1.0))


def cube_face_samples(face: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Texel-centre directions (n, n, 3) and exact solid angles (n, n) of one cube face."""
    major, sc, tc = (np.asarray(a, np.float64) for a in _FACE_AXES[face])
    edges = np.linspace(-1.0, 1.0, n + 1)
    centre = 0.5 * (edges[:-1] + edges[1:])
    v, u = np.meshgrid(centre, centre, indexing="ij")
    d = major + u[..., None] * sc + v[..., None] * tc
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    u0, u1 = edges[None, :-1], edges[None, 1:]
    v0, v1 = edges[:-1, None], edges[1:, None]
    omega = _corner_area(u1, v1) - _corner_area(u0, v1) - _corner_area(u1, v0) + _corner_area(u0, v0)
    return d, np.abs(omega)


def cube_dirs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Texel-centre directions (6n², 3) and exact solid angles (6n²,) of an n×n×6 cube map, faces in FACES order."""
    parts = [cube_face_samples(f, n) for f in FACES]
    return np.concatenate([d.reshape(-1, 3) for d, _ in parts]), np.concatenate([w.ravel() for _, w in parts])


# ----------------------------------------------------------------------------- reading maps


def _stack_channels(path, chans: dict) -> tuple[np.ndarray, tuple[str, ...]]:
    names = [c for c in ("R", "G", "B") if c in chans]
    if len(names) != 3:
        names = ["Y"] if "Y" in chans else []
    if not names:
        raise errors.MissingDatasetError(path, f"an environment map needs R,G,B or Y channels (has {sorted(chans)})")
    return np.stack([np.asarray(chans[c], np.float64) for c in names], axis=-1), tuple(names)


def _cross_faces(img: np.ndarray, n: int, vertical: bool) -> dict[str, np.ndarray]:
    def cell(row, col):
        return img[row * n : (row + 1) * n, col * n : (col + 1) * n]

    faces = {"+y": cell(0, 1), "-x": cell(1, 0), "+z": cell(1, 1), "+x": cell(1, 2), "-y": cell(2, 1)}
    faces["-z"] = cell(3, 1)[::-1, ::-1] if vertical else cell(1, 3)
    return faces


def read_envmap(path: str | os.PathLike, layout: str = "auto", up: str = "z") -> EnvSamples:
    """Read an EXR environment map as samples with exact solid angles."""
    if layout not in LAYOUTS:
        raise errors.ValidationError("layout", layout, f"use one of {LAYOUTS}")
    if up not in ("z", "y"):
        raise errors.ValidationError("up", up, "use 'z' or 'y'")
    image = read_exr(path)
    path = Path(path)
    names = [_FACE_ALIASES.get(p.name, p.name) for p in image.parts]
    if len(image.parts) == 6 and sorted(names) == sorted(FACES):
        faces, channels = {}, None
        for name, part in zip(names, image.parts):
            faces[name], ch = _stack_channels(path, part.channels)
            if channels not in (None, ch):
                raise errors.FormatError(path, "cube faces have different channels")
            channels = ch
        kind = "cube"
    else:
        img, channels = _stack_channels(path, image.parts[0].channels)
        h, w = img.shape[:2]
        envmap = str(image.parts[0].header.get("envmap", "")).lower()
        if "latlong" in envmap or (w == 2 * h and "cube" not in envmap):
            kind = "latlong"
        elif "cube" in envmap or h == 6 * w:
            if h != 6 * w:
                raise errors.ValidationError("envmap.shape", (h, w), f"{path}: a stacked cube map is 6n high and n wide")
            faces, kind = {f: img[i * w : (i + 1) * w] for i, f in enumerate(FACES)}, "cube"
        elif 3 * w == 4 * h or 4 * w == 3 * h:
            n = w // 4 if 3 * w == 4 * h else w // 3
            faces, kind = _cross_faces(img, n, vertical=4 * w == 3 * h), "cube"
        else:
            raise errors.ValidationError(
                "envmap.shape",
                (h, w),
                f"{path}: not a 2:1 lat-long map, a cube strip 6n high and n wide, a 4:3 or 3:4 cross, nor six cube parts",
            )
        if kind == "latlong" and w != 2 * h:
            raise errors.ValidationError("envmap.shape", (h, w), f"{path}: a lat-long map is twice as wide as high")
    if layout not in ("auto", kind):
        raise errors.ValidationError("layout", layout, f"{path} is a {kind} map")
    if kind == "latlong":
        dirs, omega = latlong_samples(*img.shape[:2])
        radiance = img
    else:
        sizes = {f.shape[:2] for f in faces.values()}
        if len(sizes) != 1 or next(iter(sizes))[0] != next(iter(sizes))[1]:
            raise errors.ValidationError("envmap.faces", sorted(sizes), f"{path}: cube faces must be equal squares")
        n = next(iter(sizes))[0]
        dirs, omega = cube_dirs(n)
        radiance = np.concatenate([faces[f].reshape(-1, len(channels)) for f in FACES])
    radiance = radiance.reshape(-1, len(channels))
    bad = ~np.isfinite(radiance)
    if bad.any():
        raise errors.ValidationError("envmap", str(path), f"{int(bad.any(axis=-1).sum())} texels are NaN or infinite")
    peak = float(np.abs(radiance).max()) if radiance.size else 0.0
    if peak > MAX_RADIANCE:
        raise errors.ValidationError(
            "envmap",
            str(path),
            f"radiance up to {peak:.3g} exceeds {MAX_RADIANCE:g}: the light's "
            "Cd/Cs tables are float32 (max 3.4e38) and would hold infinities; scale the map down",
        )
    dirs = dirs.reshape(-1, 3)
    if up == "y":
        dirs = dirs[:, [1, 2, 0]]
    return EnvSamples(dirs, omega.reshape(-1), radiance, channels, kind)


# ----------------------------------------------------------------------------- projection

_BLOCK = 1 << 16
#: Largest |radiance| a map may hold: Cd/Cs (float32) multiply it by up to ~4π·(bands) and must stay finite.
MAX_RADIANCE = 1e30


def project_samples(dirs: np.ndarray, weights: np.ndarray, values: np.ndarray, lmax: int) -> np.ndarray:
    """Σ_n w_n f_n Y_i(d_n) in float64, in blocks of texels: ((lmax+1)², C)."""
    out = np.zeros(((lmax + 1) ** 2, values.shape[-1]))
    for start in range(0, len(dirs), _BLOCK):
        sl = slice(start, start + _BLOCK)
        y = np.asarray(real_sh(lmax, np.asarray(dirs[sl], np.float64)))
        out += y.T @ (weights[sl, None] * values[sl])
    return out


def project_env(samples: EnvSamples, lmax: int) -> EnvLight:
    """SH coefficients a_i (per channel) and the relative L2 energy the band limit leaves out."""
    coeffs = project_samples(samples.dirs, samples.solid_angle, samples.radiance, lmax)
    energy = np.einsum("n,nc->c", samples.solid_angle, samples.radiance**2)
    kept = np.sum(coeffs**2, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.where(energy > 0, np.sqrt(np.clip(1.0 - kept / energy, 0.0, None)), 0.0)
    return EnvLight(coeffs, samples.channels, lmax, err, samples.layout)


#: The built-in procedural sky (``map = "sky"`` in a scene): its recipe is its identity.
SKY = {"procedural": "sky", "sun": [0.5, 0.3, 0.81], "height": 128}


def sky_radiance(height: int = SKY["height"]) -> np.ndarray:
    """A z-up lat-long sky (H, 2H, 3): a blue gradient, a warm ground bounce and a small bright sun."""
    d, _ = latlong_samples(height, 2 * height)
    up = d[..., 2]
    sun_dir = np.asarray(SKY["sun"]) / np.linalg.norm(SKY["sun"])
    sun = 40.0 * np.exp(60.0 * (d @ sun_dir - 1.0))
    top = np.clip(up, 0, 1)[..., None] * np.array([0.25, 0.45, 0.9])
    ground = np.clip(-up, 0, 1)[..., None] * np.array([0.3, 0.22, 0.15])
    return 0.15 + top + ground + sun[..., None] * np.array([1.0, 0.9, 0.75])


def sky_light(lmax: int) -> EnvLight:
    """The built-in sky projected to SH up to band ``lmax`` (its source hash is that of :data:`SKY`)."""
    dirs, omega = latlong_samples(SKY["height"], 2 * SKY["height"])
    light = project_env(
        EnvSamples(dirs.reshape(-1, 3), omega.reshape(-1), sky_radiance().reshape(-1, 3), ("R", "G", "B"), "latlong"), lmax
    )
    digest = hashlib.sha256(repr(sorted(SKY.items())).encode()).hexdigest()
    return EnvLight(light.coeffs, light.channels, light.lmax, light.band_error, light.layout, digest)


def load_env_light(path: str | os.PathLike, lmax: int, layout: str = "auto", up: str = "z") -> EnvLight:
    """Read an EXR environment map and project it to SH up to band ``lmax``."""
    light = project_env(read_envmap(path, layout, up), lmax)
    digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return EnvLight(light.coeffs, light.channels, light.lmax, light.band_error, light.layout, digest)


# ----------------------------------------------------------------------------- the sh_light asset

LIGHT_KIND = "sh_light"


def write_light(path: str | os.PathLike, light: EnvLight, recipe: dict) -> Path:
    """Store light coefficients as an ``sh_light`` table (a: coefficient × channel)."""
    n, c = light.coeffs.shape
    axes = [
        Axis("sh_i", np.arange(n, dtype=np.int32), "1", "SH index i = l*l + l + m"),
        Axis("channel", np.arange(c, dtype=np.int32), "1", "colour channel: " + ",".join(light.channels)),
    ]
    var = Variable("a", light.coeffs, ("sh_i", "channel"), "W/(m2 sr)", "SH coefficients a_i of the environment radiance")
    attrs = {"band_error": light.band_error.astype(np.float64), "channels": ",".join(light.channels)}
    return write_table(path, LIGHT_KIND, recipe, axes, [var], attrs=attrs)


def read_light(path: str | os.PathLike) -> EnvLight:
    """Read an ``sh_light`` table."""
    t = read_table(path, kind=LIGHT_KIND)
    a = t["a"]
    lmax = int(round(np.sqrt(a.shape[0]))) - 1
    if (lmax + 1) ** 2 != a.shape[0]:
        raise errors.CorruptAssetError(path, f"{a.shape[0]} coefficients is not a square number")
    channels = (
        tuple(str(t.attrs.get("channels", "")).split(",")) if "channels" in t.attrs else tuple(f"c{i}" for i in range(a.shape[1]))
    )
    err = np.asarray(t.attrs.get("band_error", np.zeros(a.shape[1])), np.float64)
    return EnvLight(a, channels, lmax, err, str(t.recipe.get("layout", "")), t.recipe.get("source_sha256"))


def load_light(path: str | os.PathLike, lmax: int, layout: str = "auto", up: str = "z") -> EnvLight:
    """A light from an EXR environment map (projected to ``lmax``) or an ``sh_light`` table."""
    from .assets import sniff

    if sniff(path) == "openexr":
        return load_env_light(path, lmax, layout, up)
    light = read_light(path)
    if light.lmax < lmax:
        raise errors.ValidationError("light", str(path), f"holds bands up to l={light.lmax}; l={lmax} needed")
    return light


# ----------------------------------------------------------------------------- the radiance reference


def hair_radiance(
    coeffs, b, tangent, theta_v, kd=1.0, ks=1.0, p: float = 49.0, *, height: int = 96, block: int = 256
) -> np.ndarray:
    """xing eq 2 by brute-force quadrature, the reference the SH tables are measured against:

        E_k = ∫ L_k(ω) V(ω) (kd_k sin θ + ks_k max(0, −cos(θ + θ′))^p) dω,   θ = ∠(ω, t),

    L_k = Σ_i coeffs[i, k] Y_i (any number of columns k), V = Σ_j b_j Y_j the texel's transmittance,
    on a z-up lat-long midpoint grid ``height`` × 2·``height`` with exact solid angles, float64.
    ``b`` (N, n), ``tangent`` (N, 3), ``theta_v`` (N,); ``kd``, ``ks`` scalars or (K,).  Returns (N, K)."""
    c = np.asarray(coeffs, np.float64)
    b = np.asarray(b, np.float64)
    t = np.asarray(tangent, np.float64)
    tv = np.asarray(theta_v, np.float64)
    n_trans, k = b.shape[-1], c.shape[-1]
    if len(t) != len(b) or len(tv) != len(b):
        raise errors.ValidationError("tangent", t.shape, f"b, tangent and theta_v need one row per texel ({len(b)})")
    dirs, omega = latlong_samples(height, 2 * height)
    dirs, omega = dirs.reshape(-1, 3), omega.reshape(-1)
    bands = int(round(np.sqrt(max(c.shape[0], n_trans))))
    y = np.asarray(real_sh(bands - 1, dirs), np.float64)
    light = y[:, : c.shape[0]] @ c  # (M, K)
    g = (omega[:, None, None] * y[:, :n_trans, None] * light[:, None, :]).reshape(len(dirs), n_trans * k)
    kd, ks = np.broadcast_to(np.asarray(kd, np.float64), (k,)), np.broadcast_to(np.asarray(ks, np.float64), (k,))
    out = np.empty((len(b), k))
    for s in range(0, len(b), block):
        cos = np.clip(t[s : s + block] @ dirs.T, -1.0, 1.0)  # (n, M)
        sin = np.sqrt(1.0 - cos * cos)
        ctv, stv = np.cos(tv[s : s + block, None]), np.sin(tv[s : s + block, None])
        spec = np.maximum(0.0, -(cos * ctv - sin * stv)) ** float(p)
        yd = (sin @ g).reshape(-1, n_trans, k)
        ys = (spec @ g).reshape(-1, n_trans, k)
        out[s : s + block] = np.einsum("nj,njk->nk", b[s : s + block], kd * yd + ks * ys)
    return out
