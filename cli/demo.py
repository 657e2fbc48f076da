"""``hairlut demo``: the README's main job."""

from __future__ import annotations

import json
import time

import click

from hairlut import demo

from .format import render


@click.command("demo")
@click.option("--out", "out_dir", default="out/demo", show_default=True, type=click.Path(file_okay=False),
              help="Folder for the assets and previews.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def demo_cmd(out_dir, as_json):
    """Bake the built-in example assets and inspect them.

    Today: the Kajiya–Kay kernels sampled into an HDF5 table and an EXR image.
    """
    start = time.perf_counter()
    report = demo.run(out_dir)
    report["seconds"] = time.perf_counter() - start
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    for summary in report["assets"]:
        click.echo(render(summary))
        click.echo()
    for png in report["previews"]:
        click.echo(f"preview: {png}")
    click.echo(f"demo finished in {report['seconds']:.2f} s; assets in {out_dir}/")
