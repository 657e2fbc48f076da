"""``hairlut synth``: the online module (satf §6) — maps, lighting, shading and blending of a scene."""

from __future__ import annotations

import json

import click


@click.command("synth")
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option(
    "--db",
    "db_path",
    type=click.Path(dir_okay=False),
    help="The hrir_db file (default: the scene's database in the table cache; see `hairlut bake --scene`).",
)
@click.option(
    "--sh",
    "sh_path",
    type=click.Path(dir_okay=False),
    help="The sh_tables file with the environment light (default: from the cache, when the scene has one).",
)
@click.option(
    "--cache", "cache_root", type=click.Path(file_okay=False), help="Table cache folder (default: $HAIRLUT_CACHE, else tables/)."
)
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def synth_cmd(scene: str, db_path: str | None, sh_path: str | None, cache_root: str | None, out_dir: str, as_json: bool) -> None:
    """Synthesise re-, alpha- and s-maps, light, shade and blend every cluster of SCENE.

    Writes one EXR per cluster (channels layerK.re, layerK.A, layerK.s, layerK.R/G/B and
    the composite R,G,B,A), a PNG beside each and preview.png (orthographic view).
    Without --db (and --sh for a scene with an environment light) the tables are found
    in the cache by the scene's plan; bake them first with `hairlut bake --scene SCENE`.

    \b
    Examples:
      hairlut bake --scene tables/scenes/sky-clusters.toml
      hairlut synth tables/scenes/sky-clusters.toml --out out/synth-sky
      hairlut synth tables/scenes/two-clusters.toml --db tables/hrir-default.h5 --out out/synth
    """
    from hairlut.atomic import check_writable
    from hairlut.planner import scene_assets
    from hairlut.scene import load_scene
    from hairlut.synth import synthesize, write_outputs

    check_writable(out_dir, folder=True)  # before the maps are made
    sc = load_scene(scene)
    db_path, sh_path, maps_path = scene_assets(sc, cache_root, db=db_path, sh=sh_path)
    result = synthesize(sc, db_path, sh=sh_path, maps=maps_path)
    files = write_outputs(result, out_dir)
    report = {"scene": scene, "db": db_path, "sh": sh_path, **files, **result.stats}
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    sec = result.stats["seconds"]
    n_t, n_u = result.stats["texels_per_layer"]
    click.echo(
        f"synthesised {result.stats['clusters']} clusters, {result.stats['layers']} layers, {result.stats['hsvs']} HSVs "
        f"({n_u} u × {n_t} t texels per layer) in {sum(sec.values()):.2f} s"
    )
    for path in files["exr"]:
        click.echo(f"  wrote {path}")
    click.echo(f"  preview {files['preview']}")
