"""Entry point of the ``hairlut`` command and the shared error handling.

Any :class:`hairlut.errors.HairlutError` becomes one line on stderr and exit
status 2 (the same status click uses for usage errors); no traceback.
"""

from __future__ import annotations

import importlib
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
    """A click group that turns hairlut errors into :class:`Failure`."""

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except HairlutError as exc:
            raise Failure(str(exc)) from exc
        except OSError as exc:  # disk full, permission denied, ...
            where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
            raise Failure(f"{where}{exc.strerror or exc}") from exc


class LazyGroup(Group):
    """The top-level group: its commands are :data:`COMMANDS`, each imported on first look-up."""

    def list_commands(self, ctx):
        return sorted({*super().list_commands(ctx), *COMMANDS})

    def get_command(self, ctx, cmd_name):
        cmd = super().get_command(ctx, cmd_name)
        if cmd is None and cmd_name in COMMANDS:
            module, attr = COMMANDS[cmd_name].split(":")
            cmd = getattr(importlib.import_module(f"{__package__}.{module}"), attr)
            self.add_command(cmd, cmd_name)
        return cmd


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
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


#: command name → ``module:attribute`` in this package.  A command's module is imported only when the command is
#: looked up (to run it, or for its line in ``hairlut --help``), so ``hairlut --version`` imports none of them, and
#: the command modules import hairlut's heavy parts (JAX, the bakers) inside their callbacks.
COMMANDS: dict[str, str] = {
    "bake": "bake:bake_group",  # its KIND sub-commands come from hairlut.bake.registry
    "merge": "bake:merge_cmd",
    "hrir-slice": "hrir:hrir_slice_cmd",
    "cache": "cache:cache_group",
    "demo": "demo:demo_cmd",
    "inspect": "inspect:inspect_cmd",
    "sh": "sh:sh_group",
    "strands": "strands:strands_group",
    "synth": "synth:synth_cmd",
    "plan": "plan:plan_cmd",
    "render": "render:render_cmd",
    "compare": "render:compare_cmd",
    "stress": "stress:stress_cmd",
    "bench": "bench:bench_cmd",
}


def _xla_cache() -> None:
    """Keep compiled JAX kernels between runs (a warm `hairlut demo` then compiles nothing):
    ``$JAX_COMPILATION_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/hairlut/xla`` (``~/.cache``).  Every kernel is
    kept, however quick its compile: a warm demo's ~200 kernels under 0.2 s each took 3.5 s to compile again
    (issue 29, Deliver 6); reading one back costs about 6 ms.

    JAX reads both settings from the environment when it is imported, so they go there while JAX is not
    loaded yet: ``hairlut --version`` and ``--help`` never import it."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    folder, min_secs = os.environ.get("JAX_COMPILATION_CACHE_DIR") or os.path.join(base, "hairlut", "xla"), 0.0
    if "jax" in sys.modules:
        import jax

        jax.config.update("jax_compilation_cache_dir", folder)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", min_secs)
    else:
        os.environ["JAX_COMPILATION_CACHE_DIR"] = folder
        os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = str(min_secs)


def main() -> None:
    _xla_cache()  # before the first compilation
    cli(prog_name="hairlut")


if __name__ == "__main__":
    main()
