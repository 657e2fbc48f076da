"""``hairlut bake hrir`` and ``hairlut hrir-slice``: the HRIR database (satf §4–5).

``hrir_cmd`` is the registry's generic bake command for ``hrir_db`` (see ``cli/bake.py``);
``merge_cmd`` is the kind-free ``hairlut merge``.  ``Progress`` and ``Bars`` live in
``cli/progress.py`` and are re-exported here for older imports.
"""

from __future__ import annotations

import click

from .bake import kind_command, merge_cmd
from .progress import Bars, Progress

__all__ = ["Bars", "Progress", "hrir_cmd", "hrir_slice_cmd", "merge_cmd"]  # noqa: F822 (hrir_cmd: module __getattr__)


def __getattr__(name: str):
    if name == "hrir_cmd":  # built on first use: it loads the hrir_db baker (JAX), which `hairlut --help` does not need
        return kind_command("hrir_db")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@click.command("hrir-slice")
@click.argument("db", type=click.Path(dir_okay=False))
@click.option("--sector", type=click.IntRange(0), required=True, help="Sector index.")
@click.option("--light", type=click.IntRange(0), required=True, help="Light angle index.")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Output EXR (Y = reflectance, A = alpha).")
def hrir_slice_cmd(db, sector, light, out):
    """Export one sector under one light as an EXR image: rows = view angles, columns = pixels.

    \b
    Examples:
      hairlut bake hrir --recipe tables/hrir-default.toml --out tables/hrir-default.h5
      hairlut hrir-slice tables/hrir-default.h5 --sector 0 --light 3 --out slice.exr
    """
    from hairlut.hrir import export_slice

    click.echo(f"wrote {export_slice(db, out, sector, light)}")
