"""``hairlut inspect``: what is in a table or image, and a PNG preview of it."""

from __future__ import annotations

import click

from .format import dumps, render


@click.command("inspect")
@click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout instead of text.")
@click.option("--png", "png", type=click.Path(dir_okay=False), help="Also write a tone-mapped PNG preview (one input only).")
@click.option("--channel", help="EXR channel or layer to preview (default: R,G,B, else Y, else the only channel).")
@click.option("--part", help="EXR part to preview in a multi-part file (default: the first).")
@click.option("--dataset", help="HDF5 dataset to preview.")
@click.option("--slice", "index", default="", help='Index that makes the dataset 2-D, NumPy style: "0,:,:" or "2,10:20,:".')
@click.option("--exposure", type=float, default=0.0, show_default=True, help="Preview scale 2**E before the sRGB curve.")
@click.option("--normalize", is_flag=True, help="Preview maps the finite min..max to black..white (for signed tables).")
def inspect_cmd(paths, as_json, png, channel, part, dataset, index, exposure, normalize):
    """Summarise hairlut tables (.h5) and images (.exr).

    Shows kind (and what the kind is, from the kind registry), schema, the recipe,
    and for each dataset or channel its shape, dtype, axes and units, min/max/mean
    and NaN/Inf counts.  Every checksum is verified on the way, and a virtual table
    (a split bake's, over OUT.parts/) is read only when each of its parts is there and
    of its recipe.  EXR files from other tools are read too.

    \b
    Examples (after `hairlut bake sh --out tables/sh.h5 --set dense.t_resolution=8` and `hairlut demo`):
      hairlut inspect tables/sh.h5
      hairlut inspect tables/sh.h5 --dataset dense/rd --slice ":,0,:" --normalize --png rd.png
      hairlut inspect --json out/demo/sky-clusters/*.exr
      hairlut inspect out/demo/sky-clusters/cluster000.exr --channel layer2.A --png alpha.png
    """
    from hairlut.assets import preview, summarize
    from hairlut.assets.virtual_write import check_virtual
    from hairlut.bake import registry
    from hairlut.files import not_an_input

    if png and len(paths) != 1:
        raise click.UsageError("--png takes exactly one input file")
    not_an_input(png, paths, "png")
    for p in paths:
        check_virtual(p)  # a virtual table (a sharded bake's) only with every part, of its recipe: else one line naming it
    summaries = [summarize(p) for p in paths]
    for s in summaries:
        if s.get("kind"):
            s["description"] = registry.describe(s["kind"])
    if png:
        preview(paths[0], png, channel=channel, part=part, dataset=dataset, index=index, exposure=exposure, normalize=normalize)
    if as_json:
        click.echo(dumps(summaries[0] if len(summaries) == 1 else summaries))
    else:
        click.echo("\n\n".join(render(s) for s in summaries))
        if png:
            click.echo(f"preview written to {png}")
