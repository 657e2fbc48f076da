"""``hairlut bake hrir``, ``hairlut merge`` and ``hairlut hrir-slice``: the HRIR database (satf §4–5)."""

from __future__ import annotations

import json
import sys
import time

import click

from hairlut.recipes import apply_overrides, load_toml


def _clock(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    if seconds >= 3600:
        return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"
    return f"{seconds // 60}:{seconds % 60:02d}"


class Progress:
    """A one-line progress bar on stderr: sectors done/total, rate, ETA (rate counts only sectors baked now)."""

    def __init__(self, enabled: bool, width: int = 28, label: str = "hrir"):
        self.enabled, self.width, self.label = enabled, width, label
        self.tty = sys.stderr.isatty()
        self.start = time.perf_counter()
        self.first = None  # sectors already done (resumed) when baking began

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.first is None:
            self.first = (done, now)
        base, t0 = self.first
        rate = (done - base) / (now - t0) if done > base and now > t0 else None
        eta = (total - done) / rate if rate else None
        fill = int(self.width * done / max(total, 1))
        bar = "#" * fill + "-" * (self.width - fill)
        line = (f"{self.label} [{bar}] {done}/{total} sectors  "
                f"{'%.1f sectors/s' % rate if rate else '-- sectors/s'}  "
                f"ETA {_clock(eta) if eta is not None else '--:--'}  elapsed {_clock(now - self.start)}")
        click.echo(("\r" + line) if self.tty else line, err=True, nl=not self.tty)

    def close(self) -> None:
        if self.enabled and self.tty:
            click.echo("", err=True)


class Bars:
    """One :class:`Progress` bar per named bake, as ``hairlut.plan.bake``'s ``progress(name, done, total)``."""

    def __init__(self, enabled: bool):
        self.enabled, self.bars = enabled, {}

    def __call__(self, name: str, done: int, total: int) -> None:
        self.bars.setdefault(name, Progress(self.enabled, label=name))(done, total)

    def close(self) -> None:
        for bar in self.bars.values():
            bar.close()


@click.command("hrir")
@click.option("--recipe", type=click.Path(dir_okay=False), help="TOML recipe (default: the built-in defaults).")
@click.option("--out", required=True, type=click.Path(dir_okay=False),
              help="Output HDF5 file (kind hrir_db, or hrir_shard with --shard).")
@click.option("--shard", metavar="K/N",
              help="Bake only the K-th of N slices (K from 0) into an hrir_shard file for `hairlut merge`.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override a recipe key, e.g. --set sectors.count=1024.")
@click.option("--block", type=click.IntRange(1), default=32, show_default=True,
              help="Sectors per resumable part (OUT.parts/); does not change the result.")
@click.option("--keep-parts", is_flag=True, help="Keep OUT.parts/ after the final file is written.")
@click.option("--no-progress", is_flag=True, help="No progress bar on stderr.")
@click.option("--json", "as_json", is_flag=True, help="Print the bake report as JSON.")
def hrir_cmd(recipe, out, shard, sets, block, keep_parts, no_progress, as_json):
    """HRIR database: planar ray tracing of random generalized sectors (satf §5).

    Resumable: finished blocks are kept in OUT.parts/; rerun the same command after an
    interruption and it continues, writing the same bytes as an uninterrupted bake.

    \b
    Examples:
      hairlut bake hrir --recipe tables/hrir-default.toml --out tables/hrir-default.h5
      hairlut bake hrir --recipe tables/hrir-default.toml --out s0.h5 --shard 0/2
      hairlut merge s0.h5 s1.h5 --out tables/hrir-default.h5
    """
    from hairlut.hrir import bake

    given = apply_overrides(load_toml(recipe) if recipe else {}, sets)
    bar = Progress(not no_progress)
    try:
        report = bake(given, out, shard=shard, block=block, progress=bar, keep_parts=keep_parts)
    finally:
        bar.close()
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    rate = report["computed"] / report["seconds"] if report["seconds"] > 0 else 0.0
    click.echo(f"wrote {report['out']} ({report['kind']}, sectors {report['sector_range'][0]}..{report['sector_range'][1] - 1} "
               f"of {report['total_sectors']}, {report['bytes'] / 2**20:.1f} MiB) in {report['seconds']:.1f} s")
    click.echo(f"  baked {report['computed']} sectors ({rate:.1f}/s), resumed {report['resumed']}")


@click.command("merge")
@click.argument("shards", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Output HDF5 file (kind hrir_db).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def merge_cmd(shards, out, as_json):
    """Join hrir_shard files (from `hairlut bake hrir --shard K/N`) into one HRIR database.

    The result is byte-identical to a one-shot bake of the same recipe.
    """
    from hairlut.hrir import merge

    report = merge(list(shards), out)
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    click.echo(f"wrote {report['out']} ({report['sectors']} sectors from {report['shards']} shards, "
               f"{report['bytes'] / 2**20:.1f} MiB)")


@click.command("hrir-slice")
@click.argument("db", type=click.Path(dir_okay=False))
@click.option("--sector", type=click.IntRange(0), required=True, help="Sector index.")
@click.option("--light", type=click.IntRange(0), required=True, help="Light angle index.")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Output EXR (Y = reflectance, A = alpha).")
def hrir_slice_cmd(db, sector, light, out):
    """Export one sector under one light as an EXR image: rows = view angles, columns = pixels."""
    from hairlut.hrir import export_slice

    click.echo(f"wrote {export_slice(db, out, sector, light)}")
