"""``hairlut bench``: run time against error for every part of hairlut, as one report with plots.

Each part sweeps its quality knobs and returns :class:`Figure` s (a setting, its warm run time,
its error against the part's reference), grouped into tables that each carry one same-run
baseline; :func:`run_bench` derives the ratios against that baseline and the Pareto front of
time against error, then writes ``results.json`` (every figure and the :func:`machine`),
``report.md`` and ``plots/*.png`` (on Ctrl-C, :class:`BenchInterrupted`, after a partial report).
:data:`PARTS` is the registry the command runs and :func:`select` picks parts of it by name; a caller
may pass its own (``registry=``) with parts built from :class:`Part`, whose runner gets a :class:`Context`.
The studies the parts run are importable by name for ``benchmarks/``, not listed."""

from __future__ import annotations

from importlib import import_module

from .._lazy import lazy_exports
from ._figure import Figure, derive, pareto_front, tables
from ._machine import machine, machine_line
from ._parts import Context, Part, select, timed
from ._run import BenchInterrupted, run_bench


def _runner(module: str):
    """A part's run function, imported on first call (so that listing parts loads no JAX)."""
    return lambda ctx: import_module(f".{module}", __name__).run(ctx)


def _unavailable(module: str, name: str):
    return lambda: getattr(import_module(f".{module}", __name__), name)()


PARTS: dict[str, Part] = {p.name: p for p in (
    Part("sh", "SH convolution tables: bake and per-vertex radiance (xing §4)", _runner("_sh")),
    Part("hrir", "HRIR database bake: density grid, march steps, rays per pixel (satf §4–5)", _runner("_hrir")),
    Part("maps", "Online maps: every map method against a converged truth, and the online step of one view (satf §6)",
         _runner("_maps"), _unavailable("_maps", "unavailable")),
    Part("render", "Camera renders: the layered model and the strand render's levels", _runner("_render"),
         _unavailable("_render", "unavailable")),
    Part("shadows", "Shadow methods against an exact strand-level transmittance", _runner("_shadows")),
    Part("plan", "The planner: needed-only bakes against a full bake", _runner("_plan")),
    Part("scale", "Scaling of a bake over devices and processes", _runner("_scale"), _unavailable("_scale", "unavailable")),
)}

_LAZY = {"dense_radiance": "_sh", "hrir_bake_study": "_hrir", "radiance_inputs": "_sh",
         "strand_transmittance": "_shadows", "light_oriented_study": "_shadow_studies",
         "opacity_maps_study": "_shadow_studies", "numpy_opacity_maps": "_shadow_studies",
         "footprint_study": "_shadow_studies",
         "needed_only_bake": "_plan", "full_bake": "_plan", "database_coverage": "_plan", "demo_runs": "_plan"}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = ["BenchInterrupted", "Context", "Figure", "PARTS", "Part", "machine", "run_bench", "select"]
