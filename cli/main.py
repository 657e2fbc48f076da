"""Entry point of the ``hairlut`` command and the shared error handling.

Any :class:`hairlut.errors.HairlutError` becomes one line on stderr and exit
status 2 (the same status click uses for usage errors); no traceback.
"""

from __future__ import annotations

import logging
import os
import sys

import click

from hairlut import __version__
from hairlut.errors import HairlutError


class Failure(click.ClickException):
    """A hairlut error, shown as ``hairlut: error: <file or field>: <fault>``."""

    exit_code = 2

    def show(self, file=None) -> None:
        click.echo(f"hairlut: error: {self.message}", err=True)


class Group(click.Group):
    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except HairlutError as exc:
            raise Failure(str(exc)) from exc
        except OSError as exc:  # disk full, permission denied, ...
            where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
            raise Failure(f"{where}{exc.strerror or exc}") from exc


@click.group(cls=Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "-V", "--version", prog_name="hairlut")
@click.option("-v", "--verbose", count=True, help="More log output on stderr (-vv for debug).")
@click.option("-q", "--quiet", is_flag=True, help="Only errors on stderr.")
def cli(verbose: int, quiet: bool) -> None:
    """Bake, inspect and query lookup tables for real-time hair rendering.

    \b
    Tables are HDF5 files, images are OpenEXR; both carry the recipe that made
    them.  Start with `hairlut demo`, then `hairlut inspect FILE`.
    """
    level = logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    logger = logging.getLogger("hairlut")
    logger.setLevel(level)
    if not any(getattr(h, "_hairlut", False) for h in logger.handlers):
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("hairlut: %(levelname)s: %(message)s"))
        handler._hairlut = True
        logger.addHandler(handler)


def _register() -> None:
    from . import bake, cache, demo, hrir, inspect, plan, sh, strands, synth
    from . import bench, render, stress

    for command in (bake.bake_group,  # its KIND sub-commands come from hairlut.registry
                    bake.merge_cmd, hrir.hrir_slice_cmd, cache.cache_group, demo.demo_cmd, inspect.inspect_cmd, sh.sh_group,
                    strands.strands_group, synth.synth_cmd, plan.plan_cmd, render.render_cmd, render.compare_cmd,
                    stress.stress_cmd, bench.bench_cmd):
        cli.add_command(command)


_register()


def _xla_cache() -> None:
    """Keep compiled JAX kernels between runs (a warm `hairlut demo` then skips most compilation):
    ``$JAX_COMPILATION_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/hairlut/xla`` (``~/.cache``)."""
    import jax

    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    jax.config.update("jax_compilation_cache_dir",
                      os.environ.get("JAX_COMPILATION_CACHE_DIR") or os.path.join(base, "hairlut", "xla"))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)


def main() -> None:
    _xla_cache()  # before the first compilation
    cli(prog_name="hairlut")


if __name__ == "__main__":
    main()
