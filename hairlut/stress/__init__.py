"""Numerical stress cases: edge inputs through the public API, each checked for NaN/Inf, bounds,
and its error against a float64 reference within a stated tolerance (``hairlut stress``).

``run_stress(quick=, only=, references=)`` runs them and returns a :class:`Report`
(``table()``, ``as_dict()``, ``passed``) of one :class:`Result` per case; ``CASES`` lists every
:class:`Case` with its tolerance and the reason for it.  Areas: ``sh`` (basis to lmax 40, Kajiya–Kay exponents
1 … 1e4, tables at the poles, radiance and its ringing, bad tangents), ``hrir`` (densities
0 … 1e6, grazing angles, a strand at a sector's corner), ``shadow`` (empty, single-voxel and
one-strand grooms, transmittance underflow), ``storage`` (float16 against its rounding
bound, every table kind), ``gpu`` (the float32 kernels on a GPU, where one is present).
JAX loads on first use of a name."""

from .._lazy import lazy_exports

_LAZY = {
    "CASES": "_cases",
    "case_names": "_cases",
    "run_case": "_cases",
    "run_stress": "_cases",
    "select": "_cases",
    "Report": "_report",
    "machine": "_report",
    "Case": "_tally",
    "Context": "_tally",
    "Result": "_tally",
    "Tally": "_tally",
}

__all__ = ["CASES", "Case", "Report", "Result", "run_stress"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
