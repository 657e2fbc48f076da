"""``hairlut bench``: run time against error for every part of hairlut, as one report with plots.

Each part sweeps its quality knobs and returns :class:`Figure` s (a setting, its warm run time,
its error against the part's reference), grouped into tables that each carry one same-run
baseline; :func:`run_bench` derives the ratios against that baseline and the Pareto front of
time against error, then writes ``results.json`` (every figure and the :func:`machine`),
``report.md`` and ``plots/*.png``.  :data:`PARTS` is the registry the command runs; a caller
may pass its own (``registry=``) with parts built from :class:`Part`.

Every study a part runs is here, as a function that returns its records (the ``*_study`` functions,
:func:`needed_only_bake`, :func:`full_bake`, :func:`database_coverage`, :func:`sh_radiance_figures`), and so
are the studies the investigations of the repository's ``benchmarks/`` folder print (:func:`hrir_bake_study`,
:func:`light_oriented_study`, :func:`opacity_maps_study`, :func:`footprint_study`) and the pieces they share
(:func:`ring_model`, :func:`with_config`, the maps truth :func:`map_truth` with :func:`map_scene`,
:func:`map_angles` and :func:`map_errors`, :func:`strand_transmittance`, :func:`numpy_opacity_maps`).
:func:`example` finds the example recipes, scenes and grooms the parts read, in a clone or an installed wheel.
"""

from __future__ import annotations

from importlib import import_module

from .._lazy import lazy_exports
from ._figure import Figure, derive, pareto_front, tables
from ._machine import machine, machine_line
from ._parts import Context, Part, example, select, timed
from ._run import BenchInterrupted, run_bench


def _runner(module: str):
    """A part's run function, imported on first call (so that listing parts loads no JAX)."""
    return lambda ctx: import_module(f".{module}", __name__).run(ctx)


def _unavailable(module: str, name: str):
    return lambda: getattr(import_module(f".{module}", __name__), name)()


PARTS: dict[str, Part] = {
    p.name: p
    for p in (
        Part("sh", "SH convolution tables: bake and per-vertex radiance (xing §4)", _runner("_sh")),
        Part(
            "hair_bsdf",
            "Hair BSDF tables: converged quadrature against Unreal-style Monte Carlo (issue 28)",
            _runner("_hairbsdf"),
        ),
        Part("hrir", "HRIR database bake: density grid, march steps, rays per pixel (satf §4–5)", _runner("_hrir")),
        Part("maps", "Online maps: every map method against a converged truth, and the online frame (satf §6)", _runner("_maps")),
        Part("render", "Camera renders: the layered model and the strand render's levels", _runner("_render")),
        Part(
            "picture",
            "The picture with the defaults: layered against the converged strand render on untuned grooms",
            _runner("_picture"),
        ),
        Part("shadows", "Shadow methods against an exact strand-level transmittance", _runner("_shadows")),
        Part("plan", "The planner: needed-only bakes against a full bake", _runner("_plan")),
        Part(
            "scale",
            "Scaling of a bake over devices and processes",
            _runner("_scale"),
            _unavailable("_scale", "scale_unavailable"),
        ),
    )
}

_LAZY = {
    "hrir_bake_study": "_hrir",
    "sh_radiance_figures": "_sh",
    "map_accuracy_study": "_map_accuracy",
    "map_angles": "_map_accuracy",
    "map_errors": "_map_accuracy",
    "map_scene": "_map_accuracy",
    "map_truth": "_map_accuracy",
    "online_frame_study": "_online_frame",
    "ring_model": "_online_frame",
    "render_study": "_render",
    "picture_study": "_picture",
    "GROOM_KINDS": "_grooms",
    "GROOM_VIEWS": "_grooms",
    "write_groom": "_grooms",
    "with_config": "_render",
    "scaling_study": "_scale",
    "strand_transmittance": "_shadows",
    "light_oriented_study": "_shadow_studies",
    "opacity_maps_study": "_shadow_studies",
    "numpy_opacity_maps": "_shadow_studies",
    "footprint_study": "_shadow_studies",
    "needed_only_bake": "_plan",
    "full_bake": "_plan",
    "database_coverage": "_plan",
}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = ["BenchInterrupted", "Context", "Figure", "PARTS", "Part", "example", "machine", "run_bench", "select"]
