"""The production database on 8 H200s, projected term by term: the device from the last H200 rate, the host measured
on this CPU, the disk, and the assembly (issue 16).

The production database (65,536 sectors, 64 × 64 angles, 64 px, float16: 34.9 GB) on 8 H200s, labelled "projected,
not measured on a GPU": the device time from the last H200 rate (issue 15, commit 937d29b: 94 default sectors/s,
host-bound then), scaled by a production sector's tracing work; the host's work per sector measured now on this CPU
with the production's shapes (:func:`host_terms`: serial inputs and HDF5/checks/index, and the chunk filters, which
the chunk writer runs on every core, divided over the GPU machine's 16 cores); the disk (this machine's write
bandwidth); and the virtual assembly (``benchmarks.assembly``) at ``--sizes`` sectors in parts of each of
``--blocks`` (65,536 for the production's own).  A bake overlaps device, host and disk, so projected =
max(device, host, write) + assembly.  With ``--repeat R`` (R > 0) the scale part's study
(``hairlut.bench.scaling_study``: 1 and 2 devices, 1 and 2 processes, cores pinned) runs first, R rounds of
``--sectors``, and the production database is also projected from its one-core CPU rate.

    .venv/bin/python -m benchmarks.production [--sizes 1024] [--blocks 1,4,64] [--repeat 0] [--sectors 256]
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from ._common import save, table
from .assembly import assembly, cpu, print_assembly

PRODUCTION = {
    "sectors": {"count": 65_536},
    "angles": {"views": 64, "lights": 64},
    "trace": {"pixels": 64},
    "storage": {"dtype": "float16"},
}
DEFAULT = {"sectors": {"count": 512}, "angles": {"views": 32, "lights": 32}, "trace": {"pixels": 64, "steps": 64}}
#: The last H200 measurement (issue 15): `hairlut bake hrir` of DEFAULT on one H200 traced 94 sectors/s at commit 937d29b
#: (JAX 0.11.2, CUDA 13).  The bake was host-bound there, so the device's own rate was at least this; none since.
H200 = {"rate": 94.0, "commit": "937d29b", "recipe": DEFAULT}
GPUS = 8
#: cores per GPU on the GPU machine (the H200 machine of issue 15: one GPU, 16 cores); an 8-GPU node is assumed to give each
#: GPU's process as many
GPU_HOST_CORES = 16
#: the production recipe's shapes (angles, pixels, density grid, float16) with a 2-step trace: the host's work per sector
#: (sampling, densities, geometry, checks, filters, HDF5, index) is the production's, the CPU trace cheap
HOST = {**PRODUCTION, "sectors": {"count": 96}, "trace": {"pixels": 64, "steps": 2}}


def host_terms(tmp: Path, block: int = 32) -> dict:
    """The host's work per sector of a production-shaped bake, CPU seconds on this machine (module docstring).

    A HOST recipe (the production's angles, pixels, density grid and float16; a 2-step trace) is baked twice in
    blocks of ``block`` (the first compiles) through the public ``bake`` (``--merge virtual``: no copy).  Its CPU time
    per sector splits into: the trace (``trace_sectors`` on the same sectors, timed alone); the inputs
    (``sample_block``, ``sector_density``, ``sector_geometry``: serial Python and small kernels); the chunk filters
    (shuffle, gzip, fletcher32 of α and reflectance, ``hairlut.assets.chunks.filter_chunk``: run on every core by the
    chunk writer); and the rest (HDF5 calls, checks, the part index: serial), the bake's CPU less the other three."""
    from hairlut.assets.chunks import filter_chunk
    from hairlut.geometry import sector_density
    from hairlut.hrir import bake, resolve_recipe, sample_block, trace_sectors
    from hairlut.march import sector_geometry

    r = resolve_recipe(HOST)
    n = r["sectors"]["count"]
    bake(HOST, tmp / "host-warm.h5", block=block, distributed=True, merge="virtual")
    _, bake_cpu = cpu(lambda: bake(HOST, tmp / "host.h5", block=block, distributed=True, merge="virtual"))
    prep = trace = filters = 0.0
    dtype = r["storage"]["dtype"]
    for s in range(0, n, block):
        (splats, params), c1 = cpu(lambda: sample_block(r, s, min(s + block, n)))
        dens, c2 = cpu(
            lambda: sector_density(splats, tuple(r["sectors"]["grid"]), density_scale=r["sectors"]["density_scale"], chunk=1)
        )
        geom, c3 = cpu(
            lambda: sector_geometry(
                params, kappa=r["trace"]["extinction"], n_pix=r["trace"]["pixels"], smooth_ratio=r["trace"]["smooth_ratio"]
            )
        )
        (alpha, refl), c4 = cpu(lambda: trace_sectors(dens, geom, r))
        prep += c1 + c2 + c3
        trace += c4
        a16, r16 = np.asarray(alpha, dtype), np.asarray(refl, dtype)  # the stored chunks: α 16 sectors, reflectance 1
        _, c5 = cpu(
            lambda: (
                [filter_chunk(a16[i : i + 16], 4) for i in range(0, len(a16), 16)]
                + [filter_chunk(r16[i : i + 1], 4) for i in range(len(r16))]
            )
        )
        filters += c5
    terms = {"prep": prep / n, "filters": filters / n, "trace_cpu": trace / n}
    terms["rest"] = max(bake_cpu / n - terms["prep"] - terms["filters"] - terms["trace_cpu"], 0.0)
    return {
        **terms,
        "bake_cpu": bake_cpu / n,
        "recipe": HOST,
        "block": block,
        "bytes_per_sector": sum(p.stat().st_size for p in (tmp / "host.h5.parts").glob("part-*.h5")) / n,
    }


def write_bandwidth(tmp: Path, mib: int = 256) -> float:
    """Bytes per second this machine's disk takes (``mib`` MiB written in 8 MiB pieces, then fsync): wall clock."""
    piece = os.urandom(8 << 20)
    t0 = time.perf_counter()
    with open(tmp / "bandwidth.bin", "wb") as f:
        for _ in range(mib // 8):
            f.write(piece)
        f.flush()
        os.fsync(f.fileno())
    seconds = time.perf_counter() - t0
    (tmp / "bandwidth.bin").unlink()
    return (mib << 20) / seconds


def projection(asm: list[dict], host: dict) -> dict:
    """The production database on GPUS H200s, projected term by term (printed): the device from the last H200 rate, the
    host from this machine's CPU, the disk, and the leader's assembly; a bake overlaps the first three, so
    projected = max(device, host, write) + assembly."""
    from hairlut.bake import registry

    prod_bytes, _ = registry.get("hrir_db").estimate(PRODUCTION)
    n = PRODUCTION["sectors"]["count"]
    each = n / GPUS
    ratio = work(PRODUCTION) / n / (work(DEFAULT) / DEFAULT["sectors"]["count"])
    device_rate = H200["rate"] / ratio  # production sectors per second on one H200, at least
    serial, parallel = host["prep"] + host["rest"], host["filters"]
    host_s = each * (serial + parallel / GPU_HOST_CORES)
    write_s = prod_bytes / host["write_bytes_per_s"]
    at_size = [r for r in asm if r["sectors"] == n]
    assembly_s = min((r["virtual_s"] for r in at_size), default=None)
    out = {
        "bytes": prod_bytes,
        "sectors_per_gpu": each,
        "work_ratio_default": ratio,
        "device_rate": device_rate,
        "device_s": each / device_rate,
        "host_serial_s_per_sector": serial,
        "host_parallel_cpu_s_per_sector": parallel,
        "host_s": host_s,
        "write_s": write_s,
        "assembly_s": assembly_s,
        "host": host,
    }
    out["projected_s"] = max(out["device_s"], host_s, write_s) + (assembly_s or 0.0)
    print(
        f"\nproduction database (65,536 sectors, 64 x 64 angles, 64 px, 64 steps, float16: {prod_bytes / 1e9:.1f} GB) on "
        f"{GPUS} H200s: projected, not measured on a GPU; {each:,.0f} sectors per GPU"
    )
    print(
        f"  device:   {out['device_s']:7.1f} s  the last H200 rate, {H200['rate']:.0f} default sectors/s at {H200['commit']} "
        f"(host-bound then: the device's rate was at least this), / {ratio:.0f} (a production sector's tracing work)"
    )
    print(
        f"  host:     {host_s:7.1f} s  this CPU, per sector {1e3 * serial:.2f} CPU-ms serial (inputs {1e3 * host['prep']:.2f},"
        f" HDF5/checks/index {1e3 * host['rest']:.2f}) + {1e3 * parallel:.2f} CPU-ms of chunk filters over "
        f"{GPU_HOST_CORES} cores (HOST recipe: production shapes, 2-step trace; same per-core speed assumed)"
    )
    need = prod_bytes / max(out["device_s"], host_s)
    out["write_bytes_per_s_needed"] = need
    print(
        f"  write:    {write_s:7.1f} s  {prod_bytes / 1e9:.1f} GB at this machine's disk, "
        f"{host['write_bytes_per_s'] / 1e6:.0f} MB/s (a VM disk shared with other jobs; the GPU node's storage decides: "
        f"{need / 1e6:.0f} MB/s keeps the disk off the critical path)"
    )
    print(
        "  assembly: "
        + (
            f"{assembly_s:7.3f} s  virtual, measured here at {n:,} sectors (best part count's wall)"
            if assembly_s is not None
            else "   not measured in this run (--sizes 65536)"
        )
    )
    print(f"  projected = max(device, host, write) + assembly = {out['projected_s'] / 60:.1f} min")
    return out


def work(recipe: dict) -> float:
    """Tracing work of a bake: sector · view · light · pixel · step · ray (what hrir_db's estimate counts)."""
    from hairlut.hrir import resolve_recipe

    r = resolve_recipe(recipe, budget=False)
    t = r["trace"]
    return float(
        r["sectors"]["count"] * r["angles"]["views"] * r["angles"]["lights"] * t["pixels"] * t["steps"] * t["rays_per_pixel"]
    )


def main(argv=None) -> dict:
    import argparse
    import tempfile

    from hairlut.bench import scaling_study

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1024", help="database sizes (sectors) of the assembly timing")
    ap.add_argument("--blocks", default="1,4,64", help="sectors per part of the assembly timing")
    ap.add_argument("--copy-max", type=int, default=4096, help="time the copy only up to this many sectors")
    ap.add_argument("--keep", type=Path, help="bake the assembly's parts here and keep them (a rerun resumes them)")
    ap.add_argument("--no-projection", action="store_true", help="skip the host measurement and the projection")
    ap.add_argument("--repeat", type=int, default=0, help="rounds of the scale part's study first (0: none)")
    ap.add_argument("--sectors", type=int, default=256, help="sectors of the scaling rounds (256: compilation amortised)")
    ap.add_argument("--name", default="production", help="results/<name>.json")
    a = ap.parse_args(argv)
    load_before = os.getloadavg()
    scaling = scaling_study(a.sectors, a.repeat, progress=print) if a.repeat else None
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        asm = assembly(
            [int(s) for s in a.sizes.split(",") if s],
            [int(g) for g in a.blocks.split(",") if g],
            tmp,
            repeat=2,
            copy_max=a.copy_max,
            keep=a.keep,
        )
        hosts = None if a.no_projection else {**host_terms(tmp), "write_bytes_per_s": write_bandwidth(tmp)}
    print_assembly(asm)
    out = projection(asm, hosts) if hosts else {}
    if scaling:
        print(
            table(
                scaling["rows"],
                [
                    ("config", "config", ""),
                    ("cores", "cores", ""),
                    ("rate_best", "sectors/s best", ".2f"),
                    ("x_base", "x 1 core", ".2f"),
                    ("cores_got", "cores got", ".2f"),
                    ("x_base_full_cores", "x 1 core, full cores", ".2f"),
                    ("bake_s", "bake s", ".1f"),
                    ("peak_rss_mib", "peak MiB", ".0f"),
                ],
            )
        )
        core_rate = scaling["rows"][0]["rate_best"] * work(scaling["recipe"]) / a.sectors  # work per second, one core
        out.update(one_core_s=work(PRODUCTION) / core_rate, cpu_cores_8_s=work(PRODUCTION) / core_rate / GPUS)
        print(
            f"\nproduction database from this run's one-core CPU rate: {out['one_core_s'] / 3600:.0f} core-hours; 8 "
            f"such devices {out['cpu_cores_8_s'] / 3600:.1f} h (linear scaling assumed)"
        )
    doc = {
        "assembly": asm,
        "load_before": load_before,
        "load_after": os.getloadavg(),
        "projection": out or None,
        "scaling": scaling,
    }
    save(a.name, doc)
    return doc


if __name__ == "__main__":
    main()
