"""What ran a benchmark: host (CPU model, cores, memory), JAX's backend and devices (kind, memory
where the backend reports it), the NVIDIA driver and CUDA version where there is one, and the
versions of Python, jax, jaxlib, numpy, h5py and hairlut.  Every results file carries it, so a
GPU figure and a CPU figure can be told apart."""

from __future__ import annotations

import functools
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path


def _cpu_model() -> str | None:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def _memory_bytes() -> int | None:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def _nvidia_smi() -> dict:
    """Driver, CUDA version and each GPU's name and memory from nvidia-smi, or {} without one."""
    try:
        out = subprocess.run(
            ["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout
        cuda = subprocess.run(["nvidia-smi"], capture_output=True, text=True, timeout=10).stdout
    except (OSError, subprocess.SubprocessError):
        return {}
    gpus = [
        dict(zip(("name", "driver", "memory"), (f.strip() for f in line.split(",")))) for line in out.splitlines() if line.strip()
    ]
    info = {"gpus": gpus, "driver": gpus[0]["driver"] if gpus else None}
    if "CUDA Version:" in cuda:
        info["cuda"] = cuda.split("CUDA Version:", 1)[1].split()[0]
    return info


@functools.lru_cache(maxsize=1)
def machine() -> dict:
    """What ran the benchmark: host (CPU model, cores, memory), JAX's backend and devices (kind,
    memory where the backend reports it), the GPU driver where there is one, and library versions."""
    info = {
        "cpu": _cpu_model(),
        "cpus": os.cpu_count(),
        "memory_bytes": _memory_bytes(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": {d: _version(d) for d in ("jax", "jaxlib", "numpy", "h5py", "hairlut")},
    }
    try:
        import jax

        devs = jax.devices()
        info["jax_backend"] = jax.default_backend()
        info["devices"] = []
        for d in devs:
            entry = {"kind": d.device_kind, "platform": d.platform}
            try:
                stats = d.memory_stats() or {}
            except Exception:
                stats = {}
            if "bytes_limit" in stats:
                entry["memory_bytes"] = int(stats["bytes_limit"])
            info["devices"].append(entry)
        info["x64"] = bool(jax.config.jax_enable_x64)
        plugins = {d: _version(d) for d in ("jax-cuda12-plugin", "jax-cuda13-plugin", "jax-cuda12-pjrt", "jax-cuda13-pjrt")}
        info["versions"].update({k: v for k, v in plugins.items() if v})
    except Exception as exc:
        info["jax_error"] = repr(exc)
    if info.get("jax_backend") == "gpu" or any(d.get("platform") == "gpu" for d in info.get("devices", [])):
        info.update(_nvidia_smi())
    return info


def machine_line(info: dict | None = None) -> str:
    """One line for a table's caption, e.g. ``machine: 2 × Intel Xeon …, 7.8 GiB; jax 0.10.2 on cpu (cpu)``."""
    m = machine() if info is None else info

    def gib(b):
        return f"{b / 2**30:.0f} GiB" if b else "? GiB"

    devs = m.get("devices") or []
    kinds = sorted({d["kind"] for d in devs})
    dev = ", ".join(f"{sum(d['kind'] == k for d in devs)} × {k}" for k in kinds)
    mem = [d["memory_bytes"] for d in devs if d.get("memory_bytes")]
    parts = [
        f"machine: {m.get('cpus')} × {m.get('cpu') or 'unknown CPU'}, {gib(m.get('memory_bytes'))}",
        f"jax {m['versions'].get('jax')} on {m.get('jax_backend', '?')} ({dev or 'no devices'}"
        + (f", {gib(mem[0])} each" if mem else "")
        + ")",
    ]
    if m.get("driver"):
        parts.append(f"driver {m['driver']}" + (f", CUDA {m['cuda']}" if m.get("cuda") else ""))
    return "; ".join(parts)
