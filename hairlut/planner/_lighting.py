"""A scene's environment light as the planner and the online module need it: the light at the
reference's bands, the light bands chosen against the scene's own radiance error
(``environment.bands = "auto"``, ``environment.tolerance``; ``_envbands``), the windowed light at
those bands, and the SH table recipe they imply (xing §4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def reference_light(scene):
    """The scene's environment light (intensity applied) at the reference's bands (``_envbands``)."""
    from ..envlight import EnvLight, load_env_light, sky_light
    from ._envbands import REFERENCE_BANDS

    env = scene.environment
    lmax = REFERENCE_BANDS - 1
    light = sky_light(lmax) if env["map"] == "sky" else load_env_light(env["map"], lmax, env["layout"], env["up"])
    if env["intensity"] != 1.0:
        light = EnvLight(
            light.coeffs * env["intensity"],
            light.channels,
            light.lmax,
            light.band_error,
            light.layout,
            f"{light.source_sha256}×{env['intensity']!r}",
        )
    return light


_BANDS: dict = {}


def environment_bands(scene) -> dict:
    """How many light bands the scene's environment term gets and what they cost in radiance
    (``hairlut.planner._envbands``): ``bands``, ``error`` (relative RMS against 30 bands, after
    ``environment.window``), ``clamped`` (share of (tangent, θ′) samples below 0), ``rule`` (the
    paper's ⌈√p⌉ + 1) and ``rule_error``.  ``environment.bands = auto``: the fewest within
    ``environment.tolerance``; an integer is kept and measured.  None without an environment light."""
    from ..shtables import specular_band_rule
    from ._envbands import band_radiance, choose_bands, radiance_error

    env, m, fx = scene.environment, scene.material, scene.effects
    if env is None:
        return None
    kd = m["kd"] * float(np.mean(m["hair_color"])) if fx["diffuse"] else 0.0
    ks = m["ks_I"] * fx["primary"] + m["ks_II"] * fx["secondary"]
    stat = Path(env["map"]).stat() if env["map"] != "sky" and Path(env["map"]).is_file() else None
    key = (
        env["map"],
        stat and (stat.st_size, stat.st_mtime_ns),
        env["layout"],
        env["up"],
        env["intensity"],
        env["bands"],
        env["tolerance"],
        env["window"],
        kd,
        ks,
        m["p_I"],
    )
    if key not in _BANDS:
        light = reference_light(scene)
        terms = band_radiance(light.coeffs, kd, ks, m["p_I"], tangents=1024, theta_v=17)
        rule = specular_band_rule(m["p_I"])
        if env["bands"] == "auto":
            b, err, clamped = choose_bands(terms, env["tolerance"], env["window"])
        else:
            b = int(env["bands"])
            err, clamped = radiance_error(terms, min(b, terms.shape[0]), env["window"])
        _BANDS[key] = (
            {
                "bands": b,
                "error": err,
                "clamped": clamped,
                "rule": rule,
                "rule_error": radiance_error(terms, min(rule, terms.shape[0]), "none")[0],
            },
            light,
        )
    return dict(_BANDS[key][0])


def environment_light(scene):
    """The scene's environment light projected to the bands its SH tables need (windowed by
    ``environment.window``), or None."""
    from ..envlight import EnvLight
    from ._envbands import window_coeffs

    env = scene.environment
    if env is None:
        return None
    info = environment_bands(scene)
    ref = next(light for stored, light in _BANDS.values() if stored == info)
    n = max(3, info["bands"])
    a = ref.coeffs[: n * n]
    total = (ref.coeffs**2).sum(0) / np.maximum(1.0 - np.asarray(ref.band_error) ** 2, 1e-300)
    err = np.sqrt(np.clip(1.0 - (a**2).sum(0) / np.maximum(total, 1e-300), 0.0, None))
    if env["window"] != "none":
        a = window_coeffs(a, env["window"])
    return EnvLight(
        a,
        ref.channels,
        n - 1,
        err,
        ref.layout,
        ref.source_sha256 if env["window"] == "none" else f"{ref.source_sha256}|{env['window']}",
    )


def sh_bands(scene) -> int:
    """The light bands the scene's SH tables need (``environment.bands``, or the fewest within
    ``environment.tolerance`` when "auto"); 0 without an environment light."""
    b = environment_bands(scene)
    return b["bands"] if b is not None else 0


def sh_recipe(scene) -> dict | None:
    """The SH-table recipe of a scene's environment light (None when nothing is needed).  Rd gets the
    light's chosen bands too (at least 3): the band choice measures the diffuse lobe at all of them, and
    at the recipe's old 3 the sky demo's radiance was 1.69 % RMS from 30 bands, not the 1.21 % chosen."""
    fx, m = scene.effects, scene.material
    diffuse, specular = fx["diffuse"], fx["primary"] or fx["secondary"]
    if scene.environment is None or not (diffuse or specular):
        return None
    return {
        "kernel": {"p": float(m["p_I"]), "diffuse": bool(diffuse), "specular": bool(specular)},
        "bands": {"light_specular": sh_bands(scene), "light_diffuse": max(3, sh_bands(scene))},
    }
