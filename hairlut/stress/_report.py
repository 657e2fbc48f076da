"""The stress report: the machine it ran on, one :class:`~hairlut.stress.Result` per case, a
Markdown table for people and a dict for scripts (``--json``)."""

from __future__ import annotations

import os
import platform
from dataclasses import dataclass


def machine() -> dict:
    """Where the cases ran: CPU, cores, JAX backend and devices, library versions."""
    import h5py
    import jax
    import numpy as np

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    except OSError:
        pass
    devices = jax.devices()
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "backend": jax.default_backend(),
        "devices": [str(d.device_kind) for d in devices],
        "gpu": any(d.platform == "gpu" for d in devices),
        "jax": jax.__version__,
        "numpy": np.__version__,
        "h5py": h5py.__version__,
        "python": platform.python_version(),
    }


def _num(x) -> str:
    return "-" if x is None else f"{x:.1e}"


def _notes(r) -> str:
    parts = list(r.faults[:3])
    if len(r.faults) > 3:
        parts.append(f"… {len(r.faults) - 3} more faults")
    parts += list(r.notes)
    parts += [f"{k}: {v:.1e}" if isinstance(v, float) else f"{k}: {v}" for k, v in r.counted.items() if k != "rejected"]
    if r.counted.get("rejected"):
        parts.append(f"{r.counted['rejected']} bad inputs rejected")
    return "; ".join(parts).replace("|", "/")


@dataclass(frozen=True)
class Report:
    """The outcome of :func:`hairlut.stress.run_stress`."""

    results: tuple
    quick: bool
    machine: dict
    seconds: float

    @property
    def passed(self) -> bool:
        """No case failed (skipped cases, such as the GPU case on a CPU, do not fail the run)."""
        return all(r.passed for r in self.results)

    @property
    def failed(self) -> list[str]:
        return [r.name for r in self.results if not r.passed]

    def table(self) -> str:
        """A Markdown table: case, worst error, tolerance, result, notes."""
        m = self.machine
        head = (
            f"hairlut stress{' --quick' if self.quick else ''}: {len(self.results)} cases in {self.seconds:.0f} s "
            f"on {m['cpu']} ({m['cores']} cores), JAX {m['jax']} backend {m['backend']}"
            f"{'' if m['gpu'] else ' (no GPU present)'}"
        )
        rows = ["| case | worst error | tolerance | result | notes |", "|---|---|---|---|---|"]
        for r in self.results:
            rows.append(f"| {r.name} | {_num(r.worst)} | {_num(r.tolerance)} | {r.status} | {_notes(r)} |")
        n_pass = sum(r.status == "pass" for r in self.results)
        n_skip = sum(r.status == "skip" for r in self.results)
        tail = f"{n_pass} passed, {len(self.failed)} failed, {n_skip} skipped"
        return "\n".join([head, "", *rows, "", tail])

    def reasons(self) -> str:
        """Each case's tolerance and its one-line reason."""
        return "\n".join(f"- {r.name}: {_num(r.tolerance)}: {r.reason}" for r in self.results)

    def as_dict(self) -> dict:
        """The run as ``hairlut stress --json`` prints it: mode, counts, time, machine and every case."""
        return {
            "quick": self.quick,
            "passed": self.passed,
            "failed": self.failed,
            "seconds": self.seconds,
            "machine": self.machine,
            "cases": [r.as_dict() for r in self.results],
        }
