"""``hairlut demo``: the README's main job."""

from __future__ import annotations

import json
import time
from pathlib import Path

import click

from hairlut import demo

from .format import render


@click.command("demo")
@click.option("--out", "out_dir", default="out/demo", show_default=True, type=click.Path(file_okay=False),
              help="Folder for the assets and previews.")
@click.option("--shared", type=click.Path(file_okay=False), default=None,
              help="The shared/ folder with data/hair/*.tfx (default: ../shared beside the checkout, if present).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def demo_cmd(out_dir, shared, as_json):
    """Bake the built-in example assets, use them, and inspect them.

    
    1. Kajiya–Kay kernels as a table and an image.
    2. A procedural sky, projected to SH light coefficients.
    3. Exact SH convolution tables (paper settings) with the light folded in,
       and their Cd/Cs shader textures.
    4. The Sintel groom (or a procedural tuft) shaded with them: hair.png.
    """
    if shared is None:
        guess = Path(__file__).resolve().parents[1].parent / "shared"
        shared = guess if guess.is_dir() else None
    start = time.perf_counter()
    report = demo.run(out_dir, shared)
    report["total_seconds"] = time.perf_counter() - start
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    for summary in report["assets"]:
        click.echo(render(summary))
        click.echo()
    sh = report["sh"]
    click.echo(f"SH tables: θ′ series of {sh['chebyshev_nodes']} Chebyshev nodes per half (tail {sh['chebyshev_tail']:.1e}); "
               f"specular energy beyond 8 light bands {sh['specular_truncation_error']:.2f}")
    click.echo("light band-limiting error (relative L2): "
               + ", ".join(f"{c} {e:.3f}" for c, e in sh["light_band_error"].items()))
    hair = report["hair"]
    click.echo(f"hair: {hair['source']}, {hair['vertices']:,} vertices shaded, radiance {hair['radiance_min']:.3g} … "
               f"{hair['radiance_max']:.3g}, mean self-shadow visibility {hair['mean_visibility']:.2f}, "
               f"{100 * hair['clamped_fraction']:.1f} % of vertices clamped at 0 (SH ringing)")
    click.echo(f"HRIR-DB: {report['hrir']['sectors']} sectors; SATF query at a stored record reproduces it to "
               f"{report['hrir']['query_self_check_max_error']:.1e}")
    click.echo("times: " + ", ".join(f"{k} {v:.2f} s" for k, v in report["seconds"].items()))
    for png in report["previews"]:
        click.echo(f"preview: {png}")
    click.echo(f"demo finished in {report['total_seconds']:.2f} s; assets in {out_dir}/")
