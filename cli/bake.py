"""``hairlut bake``: bake tables from a recipe."""

from __future__ import annotations

import json
import time
from pathlib import Path

import click

from hairlut import errors
from hairlut.envlight import LAYOUTS, load_light
from hairlut.recipes import apply_overrides, load_toml
from hairlut.shtables import bake_sh, full_recipe, resolve_recipe, write_sh_tables, write_textures

from .format import num


@click.group("bake", invoke_without_command=True)
@click.option("--scene", type=click.Path(dir_okay=False),
              help="Bake exactly what this scene needs (see `hairlut plan`), into the table cache.")
@click.option("--cache", "cache_root", type=click.Path(file_okay=False),
              help="Table cache folder (default: $HAIRLUT_CACHE, else tables/).")
@click.option("--no-progress", is_flag=True, help="No progress bars on stderr.")
@click.option("--json", "as_json", is_flag=True, help="With --scene: print the plan and the bake report as JSON.")
@click.pass_context
def bake_group(ctx, scene, cache_root, no_progress, as_json):
    """Bake lookup tables: for a scene (--scene), or from a recipe (sh, hrir).

    \b
    Examples:
      hairlut bake --scene tables/scenes/two-clusters.toml
      hairlut bake sh --recipe tables/sh-default.toml --out tables/sh.h5
      hairlut bake hrir --recipe tables/hrir-default.toml --out tables/hrir-default.h5
    """
    if ctx.invoked_subcommand is not None:
        if scene or as_json:
            raise click.UsageError("--scene and --json go without a sub-command")
        return
    if scene is None:
        click.echo(ctx.get_help())
        return
    from hairlut.plan import bake, plan

    from .hrir import Bars
    from .plan import echo_plan

    p = plan(scene, cache_root)
    if not as_json:
        echo_plan(p)
    bars = Bars(not no_progress)
    start = time.perf_counter()
    done = bake(p, bars)
    bars.close()
    if as_json:
        click.echo(json.dumps({"plan": p.to_json(), "assets": done, "seconds": time.perf_counter() - start},
                              indent=2, default=str))
        return
    for name, d in done.items():
        click.echo(f"{d['status']} {name}: {d['path']} ({d['seconds']:.1f} s)")
    click.echo(f"scene tables ready in {time.perf_counter() - start:.1f} s")


@bake_group.command("sh")
@click.option("--recipe", type=click.Path(dir_okay=False), help="TOML recipe (default: the built-in defaults).")
@click.option("--out", type=click.Path(dir_okay=False),
              help="Output HDF5 file (kind sh_tables); default: the table cache, reused when the recipe hash matches.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE",
              help="Override a recipe key, e.g. --set kernel.p=100 --set dense.t_resolution=16.")
@click.option("--p", "p", type=float, help="Shortcut for --set kernel.p=P.")
@click.option("--light", type=click.Path(dir_okay=False), help="Environment map (.exr) or sh_light table: also bake Cd/Cs.")
@click.option("--layout", type=click.Choice(LAYOUTS), default="auto", show_default=True, help="Layout of an EXR --light.")
@click.option("--up", type=click.Choice(["z", "y"]), default="z", show_default=True, help="Up axis of an EXR --light.")
@click.option("--textures", type=click.Path(dir_okay=False),
              help="Also write Cd/Cs shader textures (EXR); needs --light and dense.t_resolution > 0.")
@click.option("--json", "as_json", is_flag=True, help="Print the bake report as JSON.")
def bake_sh_cmd(recipe, out, sets, p, light, layout, up, textures, as_json):
    """Exact SH convolution tables Rd, Rs for Kajiya–Kay hair (xing §4).

    Stores the compact exact form (kernel Legendre coefficients over θ′ and the
    Gaunt tensor), optional dense Rd/Rs on cube-map tangents, and with --light
    the contracted Cd/Cs.

    \b
    Examples:
      hairlut bake sh --recipe tables/sh-default.toml --out tables/sh.h5
      hairlut bake sh --recipe tables/sh-paper.toml --out paper.h5 --light env.exr --textures paper_tex.exr
      hairlut bake sh --out p200.h5 --p 200 --set bands.light_specular=auto
    """
    given = load_toml(recipe) if recipe else {}
    if p is not None:
        sets = (*sets, f"kernel.p={p!r}")
    given = apply_overrides(given, sets)
    start = time.perf_counter()
    r = resolve_recipe(given)  # validate everything before any work or output
    if textures and (not light or r["dense"]["t_resolution"] == 0):
        raise errors.ValidationError("textures", textures, "needs --light and dense.t_resolution > 0")
    env = None
    if light:
        env = load_light(light, max(r["bands"]["light_diffuse"], r["bands"]["light_specular"]) - 1, layout, up)
    status = "baked"
    if out is None:
        if textures:
            raise errors.ValidationError("textures", textures, "give --out too (textures are not cached)")
        from hairlut.cache import ensure

        result = {}

        def produce(target):
            result.update(bake_sh(given, env))
            write_sh_tables(target, result["tables"], result["info"], result["dense"], result["light"])

        r = full_recipe(given, env)
        path, status = ensure("sh_tables", r, produce)
        if status == "reused":
            click.echo(f"reused {path} (recipe hash matches)", err=True)
            if as_json:
                click.echo(json.dumps({"out": str(path), "status": status, "recipe": r}, indent=2))
            return
    else:
        result = bake_sh(given, env)
        path = write_sh_tables(out, result["tables"], result["info"], result["dense"], result["light"])
    tex = None
    if textures:
        lp = result["light"]
        tex = write_textures(textures, lp.get("cd"), lp.get("cs"), result["dense"]["n"], lp["channels"], result["recipe"])
    info = result["info"]
    report = {
        "out": str(path),
        "status": status,
        "textures": None if tex is None else str(tex),
        "seconds": time.perf_counter() - start,
        "bytes": Path(path).stat().st_size,
        "recipe": result["recipe"],
        "chebyshev_nodes": info["chebyshev_nodes"],
        "chebyshev_tail": info["chebyshev_tail"],
        "specular_truncation_error": info.get("truncation_error"),
    }
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    r = result["recipe"]
    b = r["bands"]
    click.echo(f"wrote {path} ({report['bytes'] / 1024:.1f} KiB) in {report['seconds']:.2f} s")
    click.echo(f"  p = {num(r['kernel']['p'])}; light bands diffuse {b['light_diffuse']} ({b['light_diffuse']**2} coeffs), "
               f"specular {b['light_specular']} ({b['light_specular']**2}); transmittance {b['transmittance']} ({b['transmittance']**2})")
    if r["kernel"]["specular"]:
        click.echo(f"  θ′ dependence: {info['chebyshev_nodes']} Chebyshev nodes per half, series tail {info['chebyshev_tail']:.1e}")
        click.echo(f"  specular energy beyond the light bands (relative L2, worst θ′): {info['truncation_error']:.3e}")
    if tex:
        click.echo(f"wrote {tex}")
