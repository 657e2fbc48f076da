"""``hairlut render`` (a scene through its camera) and ``hairlut compare`` (two frames)."""

from __future__ import annotations

import json
import logging

import click


@click.command("render")
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False), help="The frame's EXR (R, G, B, A, Z).")
@click.option("--png", is_flag=True, help="Also write a PNG beside the EXR.")
@click.option(
    "--strands", is_flag=True, help="The strand render (the strands ray-marched, converged) instead of the layered model."
)
@click.option(
    "--db",
    "db_path",
    type=click.Path(dir_okay=False),
    help="Layered: the hrir_db file of the satf map method (default: from the table cache).",
)
@click.option(
    "--sh",
    "sh_path",
    type=click.Path(dir_okay=False),
    help="Layered: the sh_tables file of the scene's environment light (default: from the cache).",
)
@click.option(
    "--cache", "cache_root", type=click.Path(file_okay=False), help="Table cache folder (default: $HAIRLUT_CACHE, else tables/)."
)
@click.option(
    "--bound",
    default=None,
    type=float,
    help="--strands: stop when one more level changes RGB and α RMSE by less than this "
    "(default: the scene's [render] strands_bound, 0.01 unless set).",
)
@click.option("--max-level", default=3, show_default=True, type=int, help="--strands: the finest level tried.")
@click.option(
    "--verify", is_flag=True, help="--strands: once converged, render one more level and store whether the bound still holds."
)
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def render_cmd(scene, out_path, png, strands, db_path, sh_path, cache_root, bound, max_level, verify, as_json):
    """Render SCENE through its [camera] into an EXR (R, G, B, A premultiplied, Z; the camera's
    4 x 4 world-to-clip matrix, resolution and projection in the hairlut:camera header, JSON).

    \b
    Default, the layered model: each cluster's layer meshes textured with the online
    module's maps ([render] method), lit with the scene's lights (and environment),
    rasterised in JAX with perspective-correct interpolation, eq 14 between a cluster's
    layers and front-to-back "over" between clusters.  The maps' time and the frame time
    (the rasteriser, maps excluded) are reported.
    --strands, the strand render: the strands as the Gaussian tubes of the sector
    densities, ray-marched with Beer-Lambert opacity, shaded with the scene's terms per
    strand tangent and shadowed through the same density; refined until converged (the
    bound and each level's change are stored).
    Examples:
      hairlut render tables/scenes/sintel-groom.toml --out out/sintel.exr --png
      hairlut render tables/scenes/sintel-groom.toml --strands --out out/sintel-strands.exr --png
    """
    from pathlib import Path

    from hairlut.atomic import check_writable
    from hairlut.planner import scene_assets
    from hairlut.render import render_layered, render_strands, write_frame
    from hairlut.scene import load_scene

    for path in [out_path] + ([Path(out_path).with_suffix(".png")] if png else []):
        check_writable(path)  # before the frame is computed
    sc = load_scene(scene)
    if strands:
        frame = render_strands(sc, bound=bound, max_level=max_level, verify=verify)
    else:
        db_path, sh_path, maps_path = scene_assets(sc, cache_root, db=db_path, sh=sh_path)
        frame = render_layered(sc, db=db_path, sh=sh_path, maps=maps_path)
    files = write_frame(frame, out_path, png=png)
    if not frame.rgba[..., 3].any() and logging.getLogger("hairlut").isEnabledFor(logging.WARNING):  # not under -q
        click.echo(
            "hairlut: warning: the frame catches no hair (alpha = 0 everywhere): the hair lies outside [camera]'s "
            "frame or shrinks below a pixel (extent, fov, position, look_at)",
            err=True,
        )
    report = {**files, **frame.info, "camera": frame.camera.to_json()}
    if as_json:
        click.echo(json.dumps(report, indent=2, default=str))
        return
    cam = frame.camera
    if strands:
        last = frame.info["levels"][-1]
        ch = last.get("change_from_previous", {})
        click.echo(
            f"strands {cam.width} x {cam.height} ({cam.projection}): frame "
            f"{frame.info['seconds']['frame']:.1f} s, level {last['level']} ({last['samples_per_pixel']} spp, "
            f"{last['steps_per_crossing']} steps), converged={frame.info['converged']} "
            + (f"(change RGB {ch['rgb_rmse']:.2g}, alpha {ch['alpha_rmse']:.2g}; bound {frame.info['bound']:g})" if ch else "")
        )
        ver = frame.info.get("verified")
        if ver:
            vc = ver["change_from_returned"]
            click.echo(
                f"  one more level ({ver['level']}): change RGB {vc['rgb_rmse']:.2g}, alpha {vc['alpha_rmse']:.2g}: "
                f"the bound {'holds' if ver['holds'] else 'does NOT hold'}"
            )
    else:
        sec = frame.info["seconds"]
        click.echo(
            f"layered {cam.width} x {cam.height} ({cam.projection}), map method {frame.info['map_method']}: "
            f"{frame.info['clusters']} clusters x {frame.info['layers']} layers, {frame.info['triangles']} triangles; "
            f"maps {1e3 * sec['maps']:.0f} ms, shade {1e3 * sec['shade']:.0f} ms, camera pass {sec['plan']:.1f} s, "
            f"frame (texturing and composite) {1e3 * sec['raster']:.0f} ms (first call with compile "
            f"{sec['raster_first']:.1f} s)"
        )
    for v in files.values():
        click.echo(f"  wrote {v}")


@click.command("compare")
@click.argument("a", type=click.Path(dir_okay=False))
@click.argument("b", type=click.Path(dir_okay=False))
@click.option("--png", "diff_png", type=click.Path(dir_okay=False), help="Write the FLIP heat map as a PNG.")
@click.option("--json", "as_json", is_flag=True, help="Print the figures as JSON.")
def compare_cmd(a, b, diff_png, as_json):
    """Measure frame A against frame B (e.g. a layered frame against the strand render): RGB and
    alpha RMSE, mean-alpha bias, the same after 8 x 8 block averaging, and NVIDIA FLIP (flip-evaluator) with its heat map."""
    import numpy as np

    from hairlut.assets import atomic_write_bytes, encode_png
    from hairlut.atomic import check_writable
    from hairlut.files import not_an_input
    from hairlut.render import compare, read_frame

    if diff_png:
        not_an_input(diff_png, [a, b], "png")
        check_writable(diff_png)
    figures, heat = compare(read_frame(a), read_frame(b))
    if diff_png:
        atomic_write_bytes(diff_png, encode_png(np.round(np.clip(heat, 0, 1) * 255).astype(np.uint8)))
        figures["png"] = diff_png
    if as_json:
        click.echo(json.dumps(figures, indent=2, allow_nan=False))
        return
    for k, v in figures.items():
        click.echo(f"{k:<20} {v:.6g}" if isinstance(v, float) else f"{k:<20} {'n/a' if v is None else v}")
