"""``hairlut cache``: list and prune the content-addressed table cache."""

from __future__ import annotations

import json

import click


@click.group("cache")
def cache_group():
    """The table cache ($HAIRLUT_CACHE, default ./tables): assets keyed by recipe hash."""


@cache_group.command("ls")
@click.option(
    "--cache", "--dir", "root", type=click.Path(file_okay=False), help="Cache folder (default: $HAIRLUT_CACHE or ./tables)."
)
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
def ls_cmd(root, as_json):
    """List cached assets, newest first, each with its status: ok; foreign (a valid asset under another asset's
    name, which the cache never reuses under that name); corrupt (fails validation: the fault is shown)."""
    from hairlut.bake.cache import cache_dir, entries

    rows = entries(root)
    if as_json:
        click.echo(
            json.dumps(
                [
                    {
                        "path": str(e.path),
                        "kind": e.kind,
                        "recipe_hash": e.recipe_hash,
                        "created": e.created,
                        "bytes": e.bytes,
                        "status": e.status,
                        "fault": e.fault,
                    }
                    for e in rows
                ],
                indent=2,
            )
        )
        return
    if not rows:
        click.echo(f"no cached assets in {cache_dir(root)}")
        return
    for e in rows:
        why = f"  ({e.fault})" if e.fault else ""
        click.echo(
            f"{e.status:<8} {e.kind or '-':<12} {e.recipe_hash[:16] or '-':<16}  {e.bytes / 1024:>9.1f} KiB  "
            f"{e.created or '-'}  {e.path}{why}"
        )
    counts = ", ".join(f"{n} {s}" for s in ("foreign", "corrupt") if (n := sum(e.status == s for e in rows)))
    click.echo(f"{len(rows)} assets{f' ({counts})' if counts else ''}, {sum(e.bytes for e in rows) / 2**20:.2f} MiB")


@cache_group.command("prune")
@click.option(
    "--cache", "--dir", "root", type=click.Path(file_okay=False), help="Cache folder (default: $HAIRLUT_CACHE or ./tables)."
)
@click.option("--kind", "kinds", multiple=True, help="Remove assets of this kind (repeatable).")
@click.option("--older-than", "days", type=float, help="Remove assets older than this many days.")
@click.option("--all", "everything", is_flag=True, help="Remove every cached asset.")
@click.option("--dry-run", is_flag=True, help="Only show what would be removed.")
def prune_cmd(root, kinds, days, everything, dry_run):
    """Remove cached assets; always removes what killed bakes left: temporaries and parts folders (OUT.parts/ of
    an asset that is gone) older than an hour, and lock files nobody holds."""
    from hairlut.bake.cache import prune

    gone = prune(root, kinds=kinds or None, older_than_days=days, everything=everything, dry_run=dry_run)
    for p in gone:
        click.echo(("would remove " if dry_run else "removed ") + str(p))
    click.echo(f"{len(gone)} file(s) {'to remove' if dry_run else 'removed'}")
