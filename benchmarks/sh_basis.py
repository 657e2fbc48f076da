"""Real SH basis: hairlut's jitted kernel against the NumPy reference and SciPy.

    python -m benchmarks.sh_basis [--n 1000000] [--lmax 15] [--n-scipy 100000]

Times ``hairlut.sh.real_sh`` for N random unit directions at lmax = 15 (float64 and
float32, warm: the jit compile is timed separately), the slow float64 NumPy reference
(``real_sh_reference``: angles + unnormalised Legendre + log-space normalisation) and
SciPy (``scipy.special.sph_harm_y`` converted to the real basis).  SciPy is timed on a
subset of ``--n-scipy`` directions and its time scaled linearly to N (it is a per-point
ufunc, so the scaling is fair); the table says so.

Error: max |Y − Y_ref| over all (point, coefficient) pairs against the reference, plus
the rounding that storing the float64 result as float32 / float16 adds (DESIGN.md:
every benchmark reports the error that the storage precision adds).

Prints a table and writes benchmarks/results/sh_basis.json.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import jax
import numpy as np

from hairlut.sh import check_dirs, n_coeffs, real_sh, real_sh_reference, real_sh_scipy

from ._common import best_of, save, table


def max_abs_diff(a, b, rows: int = 65536) -> float:
    """max |a − b| in row chunks (keeps temporaries small for 10⁶ × 256 arrays)."""
    worst = 0.0
    for s in range(0, a.shape[0], rows):
        d = np.abs(np.asarray(a[s : s + rows], np.float64) - np.asarray(b[s : s + rows], np.float64))
        worst = max(worst, float(d.max()))
    return worst


def warm_best(fn, repeat: int, keep: bool = True):
    """Best wall time of ``fn().block_until_ready()``; each run's multi-GB output is freed
    before the next run starts, so every run pays the same allocation cost."""
    best, out = float("inf"), None
    for _ in range(repeat):
        out = None
        start = time.perf_counter()
        out = fn().block_until_ready()
        best = min(best, time.perf_counter() - start)
    return best, (out if keep else None)


def storage_error(y, dtype, rows: int = 65536) -> float:
    """max |y − y.astype(dtype)|: the rounding a stored table of that precision adds."""
    return max(max_abs_diff(y[s : s + rows].astype(dtype), y[s : s + rows]) for s in range(0, y.shape[0], rows))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="number of directions (default 10^6)")
    ap.add_argument("--lmax", type=int, default=15, help="band limit (default 15: 256 coefficients)")
    ap.add_argument("--n-scipy", type=int, default=100_000, help="SciPy subset, time scaled to --n")
    ap.add_argument("--repeat", type=int, default=2, help="best of this many warm runs (hairlut)")
    args = ap.parse_args(argv)
    n, lmax, n_sc = args.n, args.lmax, min(args.n_scipy, args.n)

    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    dirs32 = dirs.astype(np.float32)
    rows = []

    # Host-side validation inside real_sh (finite, unit length), timed on its own.
    t_validate = best_of(lambda: check_dirs(dirs), repeat=2)[0]

    # hairlut float64: public entry point (validation + transfer + kernel).  The first call
    # compiles for this shape; time it apart.
    start = time.perf_counter()
    real_sh(lmax, dirs).block_until_ready()
    first_call = time.perf_counter() - start
    t64, y64 = warm_best(lambda: real_sh(lmax, dirs), args.repeat)
    y64 = np.asarray(y64)

    real_sh(lmax, dirs32).block_until_ready()
    t32, y32 = warm_best(lambda: real_sh(lmax, dirs32), args.repeat)
    y32 = np.asarray(y32)

    t_ref, y_ref = best_of(lambda: real_sh_reference(lmax, dirs), repeat=1)

    real_sh_scipy(lmax, dirs[:10])  # import and first-call overhead out of the timing
    t_sc_sub, y_sc = best_of(lambda: real_sh_scipy(lmax, dirs[:n_sc]), repeat=1)
    t_sc = t_sc_sub * n / n_sc

    scale = float(np.abs(y_ref).max())
    rows.append(dict(impl="hairlut real_sh float64 (jit, warm)", seconds=t64, err=max_abs_diff(y64, y_ref), points=n))
    rows.append(dict(impl="hairlut real_sh float32 (jit, warm)", seconds=t32, err=max_abs_diff(y32, y_ref), points=n))
    rows.append(dict(impl="NumPy reference float64 (angles + Legendre)", seconds=t_ref, err=0.0, points=n))
    scipy_label = "SciPy sph_harm_y → real" + (f" (timed on {n_sc:,}, scaled ×{n / n_sc:g})" if n_sc < n else "")
    rows.append(dict(impl=scipy_label, seconds=t_sc, err=max_abs_diff(y_sc, y_ref[:n_sc]), points=n_sc))
    for r in rows:
        r["ratio"] = r["seconds"] / t64
        r["rel_err"] = None if r["err"] is None else r["err"] / scale

    storage = {"float32": storage_error(y64, np.float32), "float16": storage_error(y64, np.float16)}
    del y64, y32, y_ref, y_sc

    print(
        f"real SH, lmax = {lmax} ({n_coeffs(lmax)} coefficients), {n:,} random unit directions; "
        f"jax {jax.__version__} on {jax.devices()[0].platform}"
    )
    print(
        table(
            rows,
            [
                ("impl", "implementation", "s"),
                ("seconds", "seconds", ".3f"),
                ("ratio", "× hairlut f64", ".2f"),
                ("err", "max abs err vs reference", ".2e"),
                ("rel_err", "÷ max|Y|", ".1e"),
            ],
        )
    )
    print(
        f"\nfirst hairlut float64 call (jit compile + run): {first_call:.2f} s;  of each real_sh call, host-side "
        f"validation takes {t_validate:.3f} s;  max|Y| = {scale:.4f};  "
        f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs"
    )
    print("storage rounding of the float64 result: " + ", ".join(f"{k} adds {v:.2e}" for k, v in storage.items()))

    path = save(
        "sh_basis",
        {
            "benchmark": "sh_basis",
            "lmax": lmax,
            "n_coeffs": n_coeffs(lmax),
            "n_dirs": n,
            "n_scipy_timed": n_sc,
            "jax_version": jax.__version__,
            "device": str(jax.devices()[0]),
            "first_call_seconds": first_call,
            "validation_seconds": t_validate,
            "max_abs_Y": scale,
            "load_average_1min": os.getloadavg()[0],
            "rows": rows,
            "storage_error": storage,
            "notes": "seconds are best-of-N warm wall times; SciPy time measured on n_scipy_timed points and scaled to n_dirs",
        },
    )
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
