"""``hairlut bake`` and ``hairlut merge``: bake any registered table kind, join shards.

Every ``hairlut bake KIND`` command is built from the kind's :class:`hairlut.bake.protocol.Baker`
(found in :mod:`hairlut.bake.registry` when the command is looked up): the common options
below plus the kind's own :class:`~hairlut.bake.protocol.Option` s.  Nothing here names a kind.
"""

from __future__ import annotations

import json
import os
import sys
import time

import click

from hairlut import errors
from hairlut.bake.coordination import TIMEOUT_S
from hairlut.recipes import apply_overrides, load_toml

from .main import Failure
from .progress import Bars, Progress


def _click_option(opt) -> click.Option:
    flag = "--" + opt.name.replace("_", "-")
    if opt.type is bool:
        return click.Option([flag, opt.name], is_flag=True, default=bool(opt.default), help=opt.help)
    if isinstance(opt.type, tuple):
        kind, show = click.Choice(opt.type), True
    elif opt.type == "path":
        kind, show = click.Path(dir_okay=False), False
    elif opt.type is int:
        kind, show = click.IntRange(opt.minimum) if opt.minimum is not None else click.INT, True
    else:
        kind, show = {float: click.FLOAT, str: click.STRING}[opt.type], opt.default is not None
    return click.Option(
        [flag, opt.name], type=kind, default=opt.default, show_default=show and opt.default is not None, help=opt.help
    )


def _first_key(schema, where="") -> str:
    """``a.b=default`` of a schema's first leaf (for help text)."""
    key, spec = next(iter(schema.items()))
    return _first_key(spec, f"{where}{key}.") if isinstance(spec, dict) else f"{where}{key}={spec.default!r}"


def _common_options(baker) -> list[click.Option]:
    example = _first_key(baker.schema) if baker.schema else "KEY=VALUE"
    return [
        click.Option(["--recipe"], type=click.Path(dir_okay=False), help="TOML recipe (default: the built-in defaults)."),
        click.Option(
            ["--out"],
            type=click.Path(dir_okay=False),
            help="Output HDF5 file; default: the table cache, reused when the recipe hash matches.",
        ),
        click.Option(
            ["--set", "sets"],
            multiple=True,
            metavar="KEY=VALUE",
            help=f"Override a recipe key (a TOML value), e.g. --set {example}; repeatable.",
        ),
        click.Option(
            ["--shard"],
            metavar="K/N",
            help="Bake only the K-th of N slices (K from 0) into a shard file for `hairlut merge` "
            "(kinds that shard; needs --out).",
        ),
        click.Option(
            ["--distributed"],
            is_flag=True,
            help="Join JAX's distributed runtime (jax.distributed.initialize): each process bakes its share "
            "into OUT.parts/, process 0 writes OUT.  Without the next three options JAX detects the "
            "cluster (SLURM, Open MPI, ...). Needs --out.",
        ),
        click.Option(["--coordinator"], metavar="HOST:PORT", help="With --distributed: process 0's address."),
        click.Option(["--num-processes", "num_processes"], type=click.IntRange(1), help="With --distributed: processes in all."),
        click.Option(["--process-id", "process_id"], type=click.IntRange(0), help="With --distributed: this process, from 0."),
        click.Option(
            ["--timeout"],
            type=click.IntRange(1),
            metavar="SECONDS",
            help="With --distributed: how long a process waits for a peer that has not joined, or that has "
            f"stopped answering, before it gives up with an error naming it [default: {TIMEOUT_S}].",
        ),
        click.Option(
            ["--merge", "merge"],
            type=click.Choice(["virtual", "copy"]),
            help="The final asset of a split bake: HDF5 virtual datasets over OUT.parts/ (default with "
            "--distributed; nothing copied) or one self-contained file (copy).",
        ),
        click.Option(["--no-progress", "no_progress"], is_flag=True, help="No progress bar on stderr."),
        click.Option(["--json", "as_json"], is_flag=True, help="Print the bake report as JSON."),
    ]


def kind_command(kind: str, name: str | None = None) -> click.Command:
    """The ``hairlut bake KIND`` command of a registered kind."""
    from hairlut.bake import registry  # the bakers: JAX and the kinds' modules, only once a kind is named

    baker = registry.get(kind)

    def callback(
        recipe,
        out,
        sets,
        shard,
        distributed,
        coordinator,
        num_processes,
        process_id,
        timeout,
        merge,
        no_progress,
        as_json,
        **values,
    ):
        given = load_toml(recipe) if recipe else {}
        split = {}
        if distributed or coordinator or num_processes is not None or process_id is not None or timeout or merge:
            if out is None:
                raise errors.ValidationError("out", None, "give --out with --distributed or --merge (not cached)")
            if baker.units is None:
                raise errors.ValidationError(
                    "distributed" if distributed else "merge",
                    distributed or merge,
                    f"{baker.kind} bakes cannot be split across processes",
                )
            if not distributed and (coordinator or num_processes is not None or process_id is not None or timeout):
                raise errors.ValidationError(
                    "distributed", False, "--coordinator, --num-processes, --process-id and --timeout go with --distributed"
                )
            split = {"merge": merge}
            if distributed:
                from hairlut.bake.devices import initialize

                split["distributed"] = initialize(coordinator, num_processes, process_id, timeout or TIMEOUT_S, on_fatal=_fatal)
        if not split.get("distributed"):
            _bake(baker, given, out, sets, shard, split, no_progress, as_json, values)
            return
        from hairlut.bake.devices import leave

        try:
            _bake(baker, given, out, sets, shard, split, no_progress, as_json, values)
        except BaseException as exc:
            leave(exc)  # tell the other processes, and shut JAX's client down, before the error line
            raise
        leave()

    params = _common_options(baker) + [_click_option(o) for o in baker.options]
    return click.Command(
        name or baker.command,
        callback=callback,
        params=params,
        help=baker.help or baker.description,
        short_help=baker.description,
    )


def _bake(baker, given, out, sets, shard, split, no_progress, as_json, values) -> None:
    """Bake one kind (into ``out`` or the cache) and print its report."""
    from hairlut.bake import registry

    shortcuts = tuple(f"{o.sets}={values[o.name]!r}" for o in baker.options if o.sets and values[o.name] is not None)
    given = apply_overrides(given, (*sets, *shortcuts))
    options = {o.name: values[o.name] for o in baker.options if not o.sets}
    bar = Progress(not no_progress and baker.unit is not None, label=baker.command, unit=baker.unit or "")
    try:
        if out is not None:
            report = registry.bake(baker.kind, given, out, progress=bar, shard=shard, options=options, **split)
            report.setdefault("status", "baked")
        else:
            if shard is not None:
                raise errors.ValidationError("shard", shard, "give --out: shard files are not cached")
            root = click.get_current_context().meta.get("hairlut.bake.cache")
            path, status, report = registry.bake_cached(baker.kind, given, root=root, progress=bar, options=options)
            report["status"] = status
    finally:
        bar.close()
    if report["status"] == "reused":
        click.echo(f"reused {report['out']} (recipe hash matches)", err=True)
    if as_json:
        click.echo(json.dumps(report, indent=2, default=str))
    elif report["status"] == "baked" and report.get("process", 0) > 0:
        click.echo(_share_line(report, baker.unit or "units"))
    elif report["status"] == "baked":
        for line in baker.describe(report) or [f"wrote {report['out']} ({report['bytes'] / 1024:.1f} KiB)"]:
            click.echo(line)


def _share_line(report: dict, unit: str) -> str:
    """What a distributed process other than 0 did: its share of the parts (process 0 writes the asset)."""
    lo, hi = report["unit_range"]
    share = f"{unit} {lo}..{hi - 1}" if hi > lo else f"no {unit} (every block went to other processes)"
    return (
        f"process {report['process']} of {report['processes']}: baked {share} into {report['out']}.parts/ "
        f"({report['computed']} computed, {report['resumed']} resumed); process 0 wrote {report['out']}"
    )


def _fatal(message: str | None) -> None:
    """JAX's client is about to abort this process (see hairlut.bake.coordination): end it as a hairlut failure with
    one line and status 2 instead, or with status 0 where the bake had finished (``message`` None)."""
    try:
        sys.stdout.flush()
        if message is not None:
            Failure(message).show()
        sys.stderr.flush()
    finally:
        os._exit(0 if message is None else 2)


class KindGroup(click.Group):
    """``hairlut bake``: its sub-commands are the registered kinds, by command name or kind name."""

    def list_commands(self, ctx):
        from hairlut.bake import registry

        return sorted({*super().list_commands(ctx), *(registry.get(k).command for k in registry.kinds())})

    def get_command(self, ctx, cmd_name):
        cmd = super().get_command(ctx, cmd_name)
        if cmd is not None:
            return cmd
        from hairlut.bake import registry

        try:
            baker = registry.get(cmd_name)
        except errors.ValidationError:
            return None
        return kind_command(baker.kind, cmd_name)


@click.group("bake", cls=KindGroup, invoke_without_command=True)
@click.option(
    "--scene",
    type=click.Path(dir_okay=False),
    help="Bake exactly what this scene needs (see `hairlut plan`), into the table cache.",
)
@click.option(
    "--cache", "cache_root", type=click.Path(file_okay=False), help="Table cache folder (default: $HAIRLUT_CACHE, else tables/)."
)
@click.option("--no-progress", is_flag=True, help="No progress bars on stderr.")
@click.option("--json", "as_json", is_flag=True, help="With --scene: print the plan and the bake report as JSON.")
@click.pass_context
def bake_group(ctx, scene, cache_root, no_progress, as_json):
    """Bake lookup tables: for a scene (--scene), or one table kind from a recipe (KIND).

    Each KIND command takes --recipe, --set KEY=VALUE, --out (without it the bake goes
    through the table cache and is reused when the recipe hash matches), --shard K/N
    (kinds that shard), --json and --no-progress, plus the kind's own options.

    \b
    Examples:
      hairlut bake --scene tables/scenes/two-clusters.toml
      hairlut bake sh --recipe tables/sh-default.toml --out tables/sh.h5
      hairlut bake hrir --recipe tables/hrir-default.toml --out tables/hrir-default.h5
      hairlut bake sh --p 16                      # into the cache; `hairlut cache ls` lists it
    """
    ctx.meta["hairlut.bake.cache"] = cache_root  # `hairlut bake --cache DIR KIND` bakes into DIR
    if ctx.invoked_subcommand is not None:
        if scene or as_json:
            raise click.UsageError("--scene and --json go without a sub-command")
        return
    if scene is None:
        click.echo(ctx.get_help())
        return
    from hairlut.planner import bake, plan

    from .plan import echo_plan

    p = plan(scene, cache_root)
    if not as_json:
        echo_plan(p)
    bars = Bars(not no_progress)
    start = time.perf_counter()
    try:
        done = bake(p, bars)
    finally:
        bars.close()  # a live display gives the terminal back (its cursor) whatever happened
    if as_json:
        click.echo(
            json.dumps({"plan": p.to_json(), "assets": done, "seconds": time.perf_counter() - start}, indent=2, default=str)
        )
        return
    for name, d in done.items():
        click.echo(f"{d['status']} {name}: {d['path']} ({d['seconds']:.1f} s)")
    click.echo(f"scene tables ready in {time.perf_counter() - start:.1f} s")


@click.command("merge")
@click.argument("shards", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Output HDF5 file (the shards' table kind).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def merge_cmd(shards, out, as_json):
    """Join shard files (from `hairlut bake KIND --shard K/N`) into one table.

    The kind that wrote the shards merges them; the result is byte-identical to a
    one-shot bake of the same recipe.

    \b
    Examples:
      hairlut bake hrir --recipe tables/hrir-default.toml --out s0.h5 --shard 0/2
      hairlut bake hrir --recipe tables/hrir-default.toml --out s1.h5 --shard 1/2
      hairlut merge s0.h5 s1.h5 --out tables/hrir-default.h5
    """
    from hairlut.bake import registry

    shards = list(shards)
    baker = registry.for_shard_kind(registry.kind_of(shards[0]))
    report = registry.merge(shards, out)
    if as_json:
        click.echo(json.dumps(report, indent=2, default=str))
        return
    n = report.get("units", report.get(baker.unit))
    count = f"{n} {baker.unit or baker.units.axis} " if n is not None else ""
    click.echo(f"wrote {report['out']} ({count}from {report['shards']} shards, {report['bytes'] / 2**20:.1f} MiB)")
