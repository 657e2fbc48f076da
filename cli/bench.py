"""``hairlut bench``: run time against error for every part of hairlut, as report.md, results.json and plots."""

from __future__ import annotations

import time

import click


def _parts_help() -> str:
    from hairlut.bench import PARTS

    return "\n".join(f"  {p.name:<8} {p.title}" for p in PARTS.values())


class _PartsEpilog(click.Command):
    """``hairlut bench --help`` ends with the parts, listed from :data:`hairlut.bench.PARTS` only when the help is
    shown: importing hairlut.bench loads HDF5 and NumPy, which ``hairlut --help`` need not."""

    def format_epilog(self, ctx, formatter):
        self.epilog = "\b\nParts:\n" + _parts_help()
        super().format_epilog(ctx, formatter)


@click.command("bench", cls=_PartsEpilog)
@click.option("--quick", is_flag=True, help="Small sweeps (a few minutes): the same parts and tables, fewer settings.")
@click.option("--only", "only", metavar="PART,...", help="Run only these parts (comma-separated; see the list below).")
@click.option(
    "--out",
    "out",
    type=click.Path(file_okay=False),
    default="bench-out",
    show_default=True,
    help="Folder for report.md, results.json and plots/.",
)
@click.option("--json", "as_json", is_flag=True, help="Print results.json's content on stdout instead of the summary.")
@click.option("--no-progress", is_flag=True, help="No per-part progress lines on stderr.")
def bench_cmd(quick: bool, only: str | None, out: str, as_json: bool, no_progress: bool) -> None:
    """Benchmark run time against error, part by part, each against a baseline timed in the same run.

    \b
    Each part sweeps its quality knobs (grid sizes, quadrature orders, database
    sizes, views, map counts, sample fractions, storage precision) and records,
    per setting, its warm run time and its error against the part's reference.
    Writes OUT/report.md (one table per part: each figure beside the same-run
    baseline as a ratio; the Pareto front and the papers' settings marked),
    OUT/results.json (every figure and the machine: CPU, cores, device and
    memory, library versions) and OUT/plots/*.png (time against error, log-log).
    A part that cannot run here (scale needs two cores) is listed as skipped.
    The report references its plots relatively and names no local path, so
    `--out docs/bench` writes the documentation's bench page.
    """
    from hairlut.bench import PARTS, BenchInterrupted, run_bench, select

    names = None if only is None else [p.name for p in select(PARTS, only, "--only")]  # "" and "," name no part
    start = time.perf_counter()

    def progress(message: str) -> None:
        if not no_progress:
            click.echo(f"[{time.perf_counter() - start:6.1f} s] {message}", err=True)

    try:
        results = run_bench(out, registry=PARTS, only=names, quick=quick, progress=progress)
    except BenchInterrupted as stop:
        pr = stop.results["partial"]
        done = [n for n, i in stop.results["parts"].items() if i["status"] not in ("interrupted", "not run")]
        click.echo(
            f"hairlut: interrupted while {pr['interrupted']} ran; wrote a partial {out}/report.md and "
            f"{out}/results.json for {', '.join(done) or 'no part'}; not run: {', '.join(pr['not_run']) or 'none'}",
            err=True,
        )
        raise SystemExit(130) from None
    if as_json:
        from .format import dumps

        click.echo(dumps(results))
        return
    for name, info in results["parts"].items():
        took = f" in {info['seconds']:.1f} s" if info.get("seconds") is not None else ""
        click.echo(f"{name:<8} {info['status']}{took}" + (f": {info['reason']}" if info["reason"] else ""))
    click.echo(f"wrote {out}/report.md, {out}/results.json and {len(results['plots'])} plots in {results['seconds']:.0f} s")
