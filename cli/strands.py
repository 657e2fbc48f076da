"""``hairlut strands``: look at hair strand files and convert between formats."""

from __future__ import annotations

import json

import click

from .format import num

_FORMAT_NAMES = {"tfx": "TressFX .tfx", "hair": "Cem Yuksel .hair", "usd": "USD BasisCurves"}


@click.group("strands")
def strands_group():
    """Hair strand files: .tfx (TressFX), .hair (Cem Yuksel), .usda/.usdc/.usd (USD, needs usd-core)."""


def _render(path: str, summary: dict) -> str:
    lines = [f"{path}  ({_FORMAT_NAMES.get(summary['format'], summary['format'])})", f"  strands   {summary['strands']}"]
    per = summary.get("points_per_strand")
    if per is None:
        lines.append(f"  vertices  {summary['points']}")
    elif per["min"] == per["max"]:
        lines.append(f"  vertices  {summary['points']}  ({per['min']} per strand)")
    else:
        lines.append(f"  vertices  {summary['points']}  ({per['min']}..{per['max']} per strand, mean {num(per['mean'])})")
    if "bbox" in summary:
        lo, hi = summary["bbox"]["min"], summary["bbox"]["max"]
        lines.append("  bbox      " + "   ".join(f"{a} {num(lo[i])} … {num(hi[i])}" for i, a in enumerate("xyz")))
        length = summary["length"]
        lines.append(f"  length    min {num(length['min'])}  mean {num(length['mean'])}  max {num(length['max'])}")
    arrays = summary["arrays"]
    have = ", ".join(["points"] + [k for k, v in arrays.items() if v])
    missing = ", ".join(k for k, v in arrays.items() if not v)
    lines.append(f"  arrays    {have}" + (f"   (absent: {missing})" if missing else ""))
    return "\n".join(lines)


@strands_group.command("info")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout instead of text.")
def info_cmd(path, as_json):
    """Strand and vertex counts, bounding box, strand lengths and optional arrays of a hair file.

    \b
    Examples:
      hairlut strands info tables/grooms/sintel_lite.tfx
      hairlut strands info --json tables/grooms/ratboy_mohawk.tfx
    """
    from hairlut.geometry import format_of, read_strands

    summary = {"path": path, "format": format_of(path), **read_strands(path).summary()}
    click.echo(json.dumps(summary, indent=2) if as_json else _render(path, summary))


@strands_group.command("convert")
@click.argument("src", type=click.Path(dir_okay=False))
@click.argument("dst", type=click.Path(dir_okay=False))
def convert_cmd(src, dst):
    """Convert a hair file to another format; both formats follow from the extensions.

    .tfx needs every strand to have the same power-of-two vertex count (4..64);
    .hair drops per-strand UVs and the TressFX movable flag.

    \b
    Examples:
      hairlut strands convert tables/grooms/ratboy_mohawk.tfx ratboy.hair
      hairlut strands convert tables/grooms/sintel_lite.tfx sintel.usda   # needs the usd extra
    """
    from hairlut.atomic import check_writable
    from hairlut.geometry import read_strands, write_strands

    check_writable(dst)
    strands = read_strands(src)
    write_strands(dst, strands)
    click.echo(f"wrote {dst}: {strands.n_strands} strands, {strands.n_points} vertices")
