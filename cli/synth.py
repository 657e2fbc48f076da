"""``hairlut synth``: the online module (satf §6) — maps, lighting, shading and blending of a scene."""

from __future__ import annotations

import json

import click


@click.command("synth")
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option("--db", "db_path", required=True, type=click.Path(dir_okay=False), help="The hrir_db file (hairlut bake hrir).")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def synth_cmd(scene: str, db_path: str, out_dir: str, as_json: bool) -> None:
    """Synthesise re-, alpha- and s-maps, light, shade and blend every cluster of SCENE.

    Writes one EXR per cluster (channels layerK.re, layerK.A, layerK.s, layerK.R/G/B and
    the composite R,G,B,A), a PNG beside each and preview.png (orthographic view).

    \b
    Example:
      hairlut synth tables/scenes/two-clusters.toml --db tables/hrir-default.h5 --out out/synth
    """
    from hairlut.hrir import load_hrir_db
    from hairlut.synth import load_scene, synthesize, write_outputs

    sc = load_scene(scene)
    result = synthesize(sc, load_hrir_db(db_path))
    files = write_outputs(result, out_dir)
    report = {"scene": scene, "db": db_path, **files, **result.stats}
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    sec = result.stats["seconds"]
    n_t, n_u = result.stats["texels_per_layer"]
    click.echo(f"synthesised {result.stats['clusters']} clusters, {result.stats['layers']} layers, {result.stats['hsvs']} HSVs "
               f"({n_u} u × {n_t} t texels per layer) in {sum(sec.values()):.2f} s")
    for path in files["exr"]:
        click.echo(f"  wrote {path}")
    click.echo(f"  preview {files['preview']}")
