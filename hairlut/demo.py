"""The built-in demo: bake real tables from the built-in defaults, use them, summarise them.

1. The Kajiya–Kay kernels sampled into a table and an image (``kk_lobes``).
2. A procedural sky (gradient plus sun) as a lat-long EXR, projected to SH.
3. The exact SH convolution tables at the paper's settings, with that light
   folded in (Cd/Cs), and their shader textures.
4. Hair shaded with those tables: the shared Sintel groom when it is present
   (else a procedural tuft), self-shadowed by its voxel SH transmittance
   (xing §5), drawn as an orthographic point splat so a person can look at it.
5. A small HRIR database (planar ray tracing of random sectors), one SATF query
   per held-in sector as a self-check, and a view × pixel slice as EXR and PNG.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from .assets import Axis, Variable, encode_png, preview, summarize, tonemap, write_exr, write_table
from .assets.atomic import atomic_write_bytes
from .envlight import SKY, load_env_light, sky_radiance, write_light
from .kernels import sample_lobes
from .shtables import bake_sh, write_sh_tables, write_textures

DEFAULT_RECIPE = {"n_theta": 181, "n_theta_v": 181, "exponents": [8.0, 49.0, 200.0], "storage": "float32"}
SH_RECIPE = {"kernel": {"p": 49.0}, "bands": {"light_specular": 8}, "dense": {"t_resolution": 16, "theta_v_steps": 9}}
HRIR_RECIPE = {"sectors": {"count": 64}, "angles": {"views": 16, "lights": 16}, "trace": {"pixels": 32, "steps": 48}}


def bake_lobes(out_dir: str | os.PathLike, recipe: dict | None = None) -> tuple[Path, Path]:
    """Write ``kk_lobes.h5`` and ``kk_lobes.exr`` into ``out_dir``; return their paths."""
    r = {**DEFAULT_RECIPE, **(recipe or {})}
    theta, theta_v, diff, spec = sample_lobes(r["n_theta"], r["n_theta_v"], r["exponents"])
    dtype = np.dtype(r["storage"])
    out_dir = Path(out_dir)
    axes = [
        Axis("theta", theta, "rad", "angle between light direction and tangent"),
        Axis("theta_v", theta_v, "rad", "angle between tangent and view direction"),
        Axis("exponent", np.asarray(r["exponents"], np.float64), "1", "specular exponent p"),
    ]
    variables = [
        Variable("diffuse", diff.astype(dtype), ("theta",), "1", "Kajiya-Kay diffuse kernel sin(theta)"),
        Variable("specular", spec.astype(dtype), ("exponent", "theta", "theta_v"), "1",
                 "Kajiya-Kay specular kernel max(0, cos(pi - theta - theta_v))^p"),
    ]
    h5 = write_table(out_dir / "kk_lobes.h5", "kk_lobes", r, axes, variables)
    layers = {f"p{p:g}.Y": spec[i] for i, p in enumerate(r["exponents"])}
    layers["diffuse.Y"] = np.broadcast_to(diff[:, None], spec.shape[1:])
    exr = write_exr(out_dir / "kk_lobes.exr", layers, recipe=r, kind="kk_lobes")
    return h5, exr


def sky(height: int = 128) -> dict[str, np.ndarray]:
    """The built-in procedural sky (:func:`hairlut.envlight.sky_radiance`) as EXR channels."""
    rgb = sky_radiance(height)
    return {c: rgb[..., k].astype(np.float32) for k, c in enumerate("RGB")}


def _hair(shared: Path | None):
    """Strand polylines: the shared Sintel groom if present, else a procedural tuft."""
    from .geometry import read_strands

    path = (shared or Path()) / "data" / "hair" / "sintel_lite.tfx"
    if shared is not None and path.is_file():
        s = read_strands(path)
        pts = s.as_padded().astype(np.float64)
        return pts[..., [0, 2, 1]] * np.array([1.0, -1.0, 1.0]), f"{path.name} ({s.n_strands} strands, y-up turned z-up)"
    rng = np.random.default_rng(0)
    roots = rng.normal(size=(200, 2)) * 4.0
    u = np.linspace(0, 1, 32)[:, None]
    pts = [np.column_stack([x + 3 * np.sin(2 * u[:, 0] + y) * u[:, 0], y + 0.5 * u[:, 0], 20 * u[:, 0]]) for x, y in roots]
    return np.stack(pts), "procedural tuft (200 strands)"


def hair_transmittance(strands: np.ndarray, kappa: float = 0.5, resolution: int = 32) -> np.ndarray:
    """Per-vertex SH transmittance b_j (n, 9) of the hair itself (xing §5)."""
    from .geometry import Strands
    from .shadows import transmittance, voxelize

    tr = transmittance(voxelize(Strands.from_padded(strands), resolution), kappa=kappa, stride=2)
    return tr.at(strands.reshape(-1, 3))


def shade_hair(contracted, strands: np.ndarray, b: np.ndarray, view=np.array([0.0, 1.0, 0.0]), size: int = 320,
               substeps: int = 6):
    """Shade every vertex with I = Σ_j b_j (Kd Cd + Ks Cs) and splat an orthographic image."""
    tangents = np.gradient(strands, axis=1)
    tangents /= np.maximum(np.linalg.norm(tangents, axis=-1, keepdims=True), 1e-12)
    t = tangents.reshape(-1, 3)
    theta_v = np.arccos(np.clip(t @ (-view), -1, 1))
    raw = np.asarray(contracted.radiance(b, t, theta_v, kd=0.25, ks=0.6)) * np.array([0.55, 0.38, 0.24])
    # 9 SH coefficients cannot hold a sharp occlusion: their ringing can make I < 0; clamp, and count it
    negative = float(np.mean(np.any(raw < 0, axis=-1)))
    rgb = np.maximum(raw, 0.0)
    # draw each segment as `substeps` interpolated points (position and colour)
    f = (np.arange(substeps) / substeps)[None, None, :, None]
    seg = lambda a: (a[:, :-1, None] * (1 - f) + a[:, 1:, None] * f).reshape(-1, a.shape[-1])  # noqa: E731
    pts = seg(strands)
    rgb_pts = seg(rgb.reshape(*strands.shape[:2], -1))
    right = np.cross(view, [0, 0, 1.0]) if abs(view[2]) < 0.9 else np.array([1.0, 0, 0])
    up = np.cross(right, view)
    x, y, depth = pts @ right, pts @ up, pts @ view
    lo, hi = np.array([x.min(), y.min()]), np.array([x.max(), y.max()])
    scale = (size - 9) / max(hi - lo)
    px = ((x - lo[0]) * scale + 4).astype(int)
    py = (size - 5 - (y - lo[1]) * scale).astype(int)
    image = np.zeros((size, size, 3))
    order = np.argsort(depth)[::-1]  # far to near: nearer points overwrite
    image[py[order], px[order]] = rgb_pts[order]
    return image, rgb, negative


def run(out_dir: str | os.PathLike, shared: str | os.PathLike | None = None) -> dict:
    """Bake and use the demo assets; return their summaries, previews and timings."""
    out = Path(out_dir)
    timings = {}
    start = time.perf_counter()
    h5, exr = bake_lobes(out)
    previews = [preview(exr, out / "kk_lobes_p49.png", channel="p49")]
    timings["kk_lobes"] = time.perf_counter() - start

    start = time.perf_counter()
    env = write_exr(out / "sky.exr", sky(), recipe=SKY, kind="envmap")
    light = load_env_light(env, lmax=SH_RECIPE["bands"]["light_specular"] - 1)
    light_h5 = write_light(out / "sky_light.h5", light, {"source_sha256": light.source_sha256, "lmax": light.lmax})
    previews.append(preview(env, out / "sky.png", exposure=-1))
    timings["light"] = time.perf_counter() - start

    start = time.perf_counter()
    res = bake_sh(SH_RECIPE, light)
    sh_h5 = write_sh_tables(out / "sh_tables.h5", res["tables"], res["info"], res["dense"], res["light"])
    lp = res["light"]
    tex = write_textures(out / "sh_textures.exr", lp["cd"], lp["cs"], res["dense"]["n"], lp["channels"], res["recipe"])
    previews.append(preview(tex, out / "sh_cd_j0.png", part="cd", channel="j0", normalize=True))
    timings["sh_tables"] = time.perf_counter() - start

    start = time.perf_counter()
    strands, source = _hair(Path(shared) if shared else None)
    b = hair_transmittance(strands)  # self-shadowing; b_0 = √(4π) would be no occlusion
    image, rgb, negative = shade_hair(lp["contracted"], strands, b)
    hair_png = atomic_write_bytes(out / "hair.png", encode_png(tonemap(image, exposure=-1.0)))
    previews.append(hair_png)
    timings["shade"] = time.perf_counter() - start

    start = time.perf_counter()
    from .hrir import HRIRDB, bake as bake_hrir, export_slice

    hrir_path = out / "hrir_small.h5"
    bake_hrir(HRIR_RECIPE, hrir_path)
    db = HRIRDB.load(hrir_path)
    re, _, _, _ = db.query(db.features, db.theta_v[3], db.theta_l[5], k=1)
    self_check = float(np.abs(re - db.reflectance[:, 3, 5]).max())
    slice_exr = export_slice(hrir_path, out / "hrir_slice.exr", sector=int(np.argmax(db.features[:, 0])), light=5)
    previews.append(preview(slice_exr, out / "hrir_slice.png", normalize=True))
    timings["hrir"] = time.perf_counter() - start
    return {
        "assets": [summarize(p) for p in (h5, exr, light_h5, sh_h5, tex, hrir_path)],
        "hrir": {"sectors": int(db.features.shape[0]), "query_self_check_max_error": self_check},
        "previews": [str(p) for p in previews],
        "seconds": timings,
        "hair": {"source": source, "vertices": int(rgb.shape[0]), "radiance_min": float(rgb.min()),
                 "radiance_max": float(rgb.max()),
                 "mean_visibility": float(np.mean(b[:, 0]) / np.sqrt(4 * np.pi)), "clamped_fraction": negative},
        "sh": {"chebyshev_nodes": res["info"]["chebyshev_nodes"], "chebyshev_tail": res["info"]["chebyshev_tail"],
               "specular_truncation_error": res["info"]["truncation_error"],
               "light_band_error": dict(zip(light.channels, light.band_error.tolist()))},
    }
