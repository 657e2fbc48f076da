"""What the investigations share: where the repository's example scenes and results are, timing, markdown tables,
the machine record and JSON output.

Every JSON that :func:`save` writes carries ``machine`` (:func:`hairlut.bench.machine`: CPU model, cores, memory;
JAX backend, device kind and memory; the NVIDIA driver and CUDA version where there is one; the
versions of Python, jax, jaxlib, numpy and h5py), and :func:`save` prints :func:`machine_line`
beside the script's table, so that a GPU figure and a CPU figure of the same script can be told apart.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from hairlut.bench import machine, machine_line

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"
#: The vendored grooms' scenes (tables/grooms/): Sintel, then the denser Ratboy crest.
SCENES = [ROOT / "tables" / "scenes" / "sintel-groom.toml", ROOT / "tables" / "scenes" / "ratboy-groom.toml"]


def best_of(fn, repeat: int = 5, min_time: float = 0.0):
    """Best wall time of ``fn()`` over ``repeat`` runs (the result of the last run is returned too)."""
    best, out = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
        if min_time and best > min_time:
            break
    return best, out


def best_wall_cpu(fn, n: int, *, warm: bool = False) -> tuple[float, float]:
    """(best wall seconds, best process CPU seconds: every thread) of ``n`` calls of ``fn``; with ``warm``, after
    one untimed call, each call's result waited for (``jax.block_until_ready``)."""

    def ready(x):
        return x

    if warm:
        import jax

        ready = jax.block_until_ready
        ready(fn())
    wall, cpu = [], []
    for _ in range(n):
        t0, c0 = time.perf_counter(), time.process_time()
        ready(fn())
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu)


def table(rows: list[dict], columns: list[tuple[str, str, str]]) -> str:
    """Markdown table; ``columns`` are (key, header, format)."""
    head = "| " + " | ".join(h for _, h, _ in columns) + " |"
    rule = "|" + "|".join("---" for _ in columns) + "|"
    body = ["| " + " | ".join(format(r[k], f) if r.get(k) is not None else "-" for k, _, f in columns) + " |" for r in rows]
    return "\n".join([head, rule, *body])


def save(name: str, payload: dict) -> Path:
    """Write ``payload`` with the :func:`machine` record to results/<name>.json and print the machine line."""
    RESULTS.mkdir(exist_ok=True)
    payload = {"machine": machine(), **payload}
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps(payload, indent=2, default=str))
    print(machine_line())
    return path


def emit(name: str, payload: dict, json_path: Path | None = None) -> Path:
    """``payload`` to ``json_path`` (a script's ``--json OUT``) when given, else :func:`save` under ``name``."""
    if json_path is None:
        return save(name, payload)
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(payload, indent=2, default=float))
    return json_path
