"""``hairlut demo``: the README's main job."""

from __future__ import annotations

import json
from pathlib import Path

import click


def default_scenes() -> list[Path]:
    """The procedural sky scene and the Sintel and curly groom scenes (their grooms beside them in grooms/): the
    installed wheel's copies (``hairlut.examples``), else the clone's ``tables/``."""
    from hairlut.bench import example

    return [example(f"scenes/{name}.toml") for name in ("sky-clusters", "sintel-groom", "curly-groom")]


def _cached(status: str | None) -> str:
    """What a strand-render figure's time means when the frame came from the cache (hairlut.render.cached_frame)."""
    return " when first rendered; this run reused the cached frame" if status == "reused" else ""


@click.command("demo")
@click.option(
    "--out",
    "out_dir",
    default="out/demo",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Folder for the synthesised maps and previews.",
)
@click.option(
    "--scene",
    "scenes",
    multiple=True,
    type=click.Path(dir_okay=False),
    help="Scene file(s) to run instead of the built-in examples.",
)
@click.option(
    "--cache", "cache_root", type=click.Path(file_okay=False), help="Table cache folder (default: $HAIRLUT_CACHE, else tables/)."
)
@click.option("--no-progress", is_flag=True, help="No progress bars on stderr.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def demo_cmd(out_dir, scenes, cache_root, no_progress, as_json):
    """Plan, bake (cached) and synthesise the example scenes; report what was done.

    \b
    1. tables/scenes/sky-clusters.toml: three procedural clusters under the
       built-in sky (SH tables, voxel SH self-shadowing) and a key light.
    2. tables/scenes/sintel-groom.toml: the strands of the Sintel groom
       (tables/grooms/sintel_lite.tfx, CC-BY 3.0 Blender Foundation) under
       two directional lights.
    3. tables/scenes/curly-groom.toml: a procedural curly groom
       (tables/grooms/curly.hair).
    Both groom scenes give only the groom, the camera, the lights and a hair
    colour: the planner chooses every other knob (hairlut plan says why), and
    each is rendered beside its strand render (camera/side_by_side.png).
    The first run bakes each scene's tables into the cache and renders the
    strand-render frames (minutes); later runs reuse both (the camera's
    layered frame and the comparison figures are computed every run).
    """
    from hairlut import demo

    from .progress import Bars

    bars = Bars(not no_progress)
    try:
        report = demo.run(out_dir, list(scenes) or default_scenes(), cache_root, bars)
    finally:
        bars.close()
    if as_json:
        click.echo(json.dumps(report, indent=2, default=str))
        return
    for r in report["scenes"]:
        st = r["stats"]
        click.echo(f"scene {r['scene']}: {st['clusters']} clusters, {st['layers']} layers, {st['hsvs']} HSVs")
        for s in r["plan"]:
            if s["kind"] is not None or s["action"] == "skip" or s["name"] == "transmittance":
                click.echo(f"  {s['action']:<5} {s['name']:<13} {s['reason']}")
        for name, a in r["assets"].items():
            click.echo(f"  {a['status']} {name} in {a['seconds']:.1f} s: {a['path']}")
        if r["accuracy"]:
            click.echo("  accuracy: " + ", ".join(f"{k} {v:.2g}" for k, v in r["accuracy"].items()))
        click.echo("  times: " + ", ".join(f"{k} {v:.1f} s" for k, v in r["seconds"].items()))
        click.echo(f"  preview: {r['files']['preview']}")
        cam = r.get("camera")
        if cam:
            f, lay, strand = cam["figures"], cam["layered"], cam["strands"]
            w, h = cam["resolution"]
            click.echo(
                f"  camera {w} x {h}: layered ({lay['map_method']} maps) frame {1e3 * lay['seconds']['raster']:.0f} ms "
                f"+ maps {1e3 * lay['seconds']['maps']:.0f} ms; strand render level {strand['level']} "
                f"({strand['samples_per_pixel']} spp, {strand['steps_per_crossing']} steps per crossing; a fixed level, "
                f"not converged, environment {strand['environment']}) {strand['seconds']['frame']:.1f} s"
                + _cached((strand.get("cache") or {}).get("status"))
            )
            pr = strand.get("convergence_probe")
            if pr:
                ch = pr["change_to_next"]
                click.echo(
                    f"  strand render level {pr['level']} -> {pr['next_level']} at {pr['resolution'][0]} x "
                    f"{pr['resolution'][1]} (same camera): RGB RMSE {ch['rgb_rmse']:.4f}, alpha RMSE "
                    f"{ch['alpha_rmse']:.4f} ({pr['cpu_seconds']:.1f} CPU-s{_cached(pr.get('cache'))})"
                )
            click.echo(
                f"  layered vs strands: FLIP {f['flip_mean']:.3f}, mean-alpha bias {f['alpha_bias']:+.4f} "
                f"({_relative(f['alpha_bias_relative'])}), RGB RMSE {f['rgb_rmse']:.4f}, 8x8 RGB RMSE {f['rgb_rmse_8x8']:.4f}"
            )
            click.echo(f"  side by side (layered | strands | FLIP): {cam['files']['side_by_side']}")
    click.echo(f"demo finished in {report['total_seconds']:.1f} s; outputs in {out_dir}/ (sky map {report['sky']})")


def _relative(x) -> str:
    """A relative bias as a percentage; n/a where the strand render's α is zero everywhere (compare gives None)."""
    return "n/a" if x is None else f"{x:+.1%}"
