"""``hairlut stress``: numerical edge cases through the library, as a pass/fail table."""

from __future__ import annotations

import json

import click

from .progress import Progress


@click.command("stress")
@click.option("--quick", is_flag=True, help="The smaller sweep the test suite runs (about a minute).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON (for scripts) instead of the table.")
@click.option(
    "--only", "only", metavar="CASE,...", help="Run only these cases or areas (sh, hrir, shadow, storage, gpu), comma-separated."
)
@click.option("--reasons", is_flag=True, help="Also print each tolerance's one-line reason.")
@click.option("--no-progress", is_flag=True, help="No progress bar on stderr.")
def stress_cmd(quick: bool, as_json: bool, only: str | None, reasons: bool, no_progress: bool) -> None:
    """Stress hairlut's numerics at the edges and print what broke, if anything.

    \b
    Every case feeds edge inputs through the public API and checks three things:
      - no NaN or Inf comes out;
      - bounds hold: α and T in [0, 1], radiance ≥ 0 where the model says so
        (SH ringing is counted, not hidden);
      - the error against a float64 reference is within the case's stated tolerance.
    \b
    Areas (name one with --only, or a case such as sh.basis_f32):
      sh       the basis to lmax 40 (float32, float64), Kajiya–Kay exponents 1 … 1e4,
               tangents on the poles and ±x ±y ±z, θ′ at 0, π/2, π, bad tangents
      hrir     densities 0 … 1e6, grazing in-plane angles, a strand at a sector's corner
      shadow   empty, single-voxel and one-strand grooms; exp() underflow (every method)
      storage  float16 storage of every table kind against its rounding bound
      gpu      the float32 cases on a GPU (skipped, and said so, where there is none)
    \b
    Exit status: 0 every case passed (or was skipped), 1 a case failed, 2 bad usage.
    \b
    Examples:
      hairlut stress --quick
      hairlut stress --only sh,storage --json > stress.json
    """
    from hairlut.stress import run_stress

    names = None if only is None else [w for w in only.split(",")]
    bar = Progress(not no_progress and not as_json, label="stress", unit="cases")
    try:
        report = run_stress(quick=quick, only=names, progress=lambda done, total, name: bar(done, total))
    finally:
        bar.close()
    if as_json:
        click.echo(json.dumps(report.as_dict(), indent=2))
    else:
        click.echo(report.table())
        if reasons:
            click.echo("\nTolerances:\n" + report.reasons())
    raise SystemExit(0 if report.passed else 1)
