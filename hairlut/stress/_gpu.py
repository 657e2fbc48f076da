"""The GPU stress case: the float32 kernels run on a GPU must meet their CPU tolerances.

Where JAX sees a GPU, the float32 cases (the SH basis, the radiance, the ray tracer) run again
with that GPU as the default device, each against its own case's tolerance; the row's error is
the worst ratio error / tolerance (so its tolerance is 1).  Where there is none, the row says
so and is skipped: it never passes on a CPU.
"""

from __future__ import annotations

from ._density import CASES as DENSITY
from ._sh import CASES as SH
from ._tally import Case, Context, Tally

#: The float32 cases rerun on the GPU.
GPU_CASES = ("sh.basis_f32", "sh.radiance_f32", "hrir.densities", "hrir.grazing", "hrir.corner_strand")
#: error / the case's own CPU tolerance: the GPU must meet the same tolerances.
GPU_RATIO_TOL = 1.0


def _gpu(tally, ctx):
    import jax

    gpus = [d for d in jax.devices() if d.platform == "gpu"]
    if not gpus:
        tally.skip(f"no GPU present (JAX backend {jax.default_backend()}): not run")
        return
    for case in (c for c in (*SH, *DENSITY) if c.name in GPU_CASES):
        sub = Tally(case.tolerance)
        with jax.default_device(gpus[0]):
            case.body(sub, Context(ctx.quick, case.reference, ctx.workdir))
        tally.non_finite += sub.non_finite
        tally.out_of_bounds += sub.out_of_bounds
        tally.faults.extend(f"{case.name}: {f}" for f in sub.faults)
        for k, v in sub.counted.items():
            tally.count(f"{case.name} {k}", v)
        if sub.worst is not None:
            tally.error(case.name, sub.worst / case.tolerance)
            tally.note(f"{case.name} {sub.worst:.1e}")
    tally.note(f"on {gpus[0].device_kind}; error is the worst error / the case's CPU tolerance")


CASES = (
    Case(
        "gpu.float32",
        "the float32 cases on a GPU against their CPU tolerances",
        GPU_RATIO_TOL,
        "a GPU must meet the CPU tolerance of every float32 case (error / tolerance ≤ 1)",
        None,
        _gpu,
    ),
)
