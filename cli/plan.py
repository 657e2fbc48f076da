"""``hairlut plan``: what a scene needs baked, reused from the cache, or skipped — and why."""

from __future__ import annotations

import json

import click

SYMBOL = {"bake": "bake ", "reuse": "reuse", "skip": "skip ", "run": "run  ", "choose": "chose", "set": "set  "}


def _size(n: int) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return ""


def echo_plan(p) -> None:
    """The plan as text, one decision per line (asset steps with size and estimated time)."""
    click.echo(f"plan for {p.scene.source} (cache {p.cache_dir})")
    for s in p.steps:
        cost = ""
        if s.action == "bake":
            cost = f" [~{_size(s.bytes)} uncompressed, ~{s.seconds:.0f} s]"
        elif s.action == "reuse":
            cost = f" [{_size(s.bytes)}: {s.path}]"
        elif s.action == "run" and s.seconds:
            cost = f" [~{s.seconds:.1f} s]"
        name = "" if s.action in ("choose", "set") else f"{s.name:<13} "  # a choice's reason starts with its key
        click.echo(f"  {SYMBOL[s.action]} {name}{s.reason}{cost}")
    t = p.to_json()["totals"]
    click.echo(f"to bake: ~{_size(t['bake_bytes'])}, ~{t['bake_seconds']:.0f} s; reused: {_size(t['reused_bytes'])}")


@click.command("plan")
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option(
    "--cache", "cache_root", type=click.Path(file_okay=False), help="Table cache folder (default: $HAIRLUT_CACHE, else tables/)."
)
@click.option("--json", "as_json", is_flag=True, help="Print the plan as JSON.")
def plan_cmd(scene: str, cache_root: str | None, as_json: bool) -> None:
    """Plan the tables SCENE needs: what will be baked, reused or skipped, and why.

    Rules: no environment light → no SH tables; ks = 0 → no Rs; p_I sets the
    light bands ((√p + 1)²) and the energy left beyond them is reported; the
    HRIR database's sector space is fitted to the scene's sectors; voxel SH
    transmittance only with an environment light and self_shadow; the hair BSDF
    tables only with [tables] hair_bsdf = true (nothing in hairlut reads them); switched-off
    or zero-weight shading terms do no work online.  Sizes and times of bakes
    are estimates.

    \b
    Examples:
      hairlut plan tables/scenes/two-clusters.toml
      hairlut plan tables/scenes/sky-clusters.toml --json
    """
    from hairlut.planner import plan

    p = plan(scene, cache_root)
    if as_json:
        click.echo(json.dumps(p.to_json(), indent=2, default=str))
    else:
        echo_plan(p)
