"""Scaling of a bake: 1 and 2 local devices, 1 and 2 jax.distributed processes (loopback), cores pinned.

Each configuration runs `hairlut bake hrir` in fresh processes, each pinned to its cores with
``taskset -c`` (``os.sched_setaffinity`` where taskset is missing), JAX_NUM_CPU_DEVICES set:

* ``plain 1 dev``        one process, one device, core 0: the baseline;
* ``dist 1 x 1``         the same bake through ``--distributed`` (one process, ``--merge virtual``), core 0:
                         what the distributed path costs on the same core;
* ``plain 2 dev``        one process, two devices, cores 0 and 1;
* ``2 x plain (pair)``   two independent plain bakes of the whole recipe at once, ``taskset -c 0`` and ``-c 1``:
                         what two processes reach on this machine with no distributed runtime at all;
* ``dist 2 x 1 virtual`` two jax.distributed processes on loopback, one device each, ``taskset -c 0`` and
                         ``-c 1``; ``dist 2 x 1 copy`` the same with ``--merge copy``.

The configurations run interleaved, ``--repeat`` rounds (the machine is shared: a round sees one
load for all of them).  Per configuration: the steady throughput (sectors per second, summed over
processes) as best of the rounds and median, taken at each process's median block: a block that
meets a new array shape compiles (the first, and a few more as sector sizes vary), and every
process compiles for itself, which ``compile CPU-s`` (the CPU seconds beyond median blocks)
shows; the bake's own seconds (the slowest process's report: imports excluded); the leader's time
to write the final asset; bytes per sector; each process's peak memory (``os.wait4``).  Ratios are
of the best rates; ``range`` is the spread of the same ratio taken round by round.  Because other
work may hold the pinned cores, each block's CPU time is recorded too: ``cores got`` (CPU seconds
per wall second of a median block, summed over processes), ``sectors/CPU-s``, and ``x 1 core,
full cores``: sectors per CPU-second times the configuration's cores against the same for one
core, the speed-up if every pinned core were given in full (derived, not a wall-clock figure).

Then the time to assemble the final asset, virtual datasets against a copy, from the same parts, at
a few part counts (``--sizes`` sectors in blocks of each of ``--blocks``), as the leader of a 2-process
bake takes it (``hairlut.sharding.finish``: its own parts' indexes in memory, the other process's share
file), wall and CPU seconds (the machine is shared: CPU seconds are the work), per part and per sector,
and what indexing a part costs each process while it bakes.  The parts are baked with the ASSEMBLY
recipe: the production's density grid (32 × 32, which the feature index reads) and float16, with one
view, one light, 2 px and 2 steps, so that 65,536 sectors bake in minutes (``--keep DIR`` keeps them for
a rerun); the copy is timed up to ``--copy-max`` sectors.  ``--repeat 0`` runs the assembly and the
projection alone.

Then the projected time of the production database (65,536 sectors, 64 × 64 angles, 64 px, float16:
34.9 GB) on 8 H200s, term by term and labelled "projected, not measured on a GPU": the device time from
the last H200 rate (issue 15, commit 937d29b: 94 default sectors/s, host-bound then), scaled by a
production sector's tracing work; the host's work per sector measured now on this CPU with the
production's shapes (``_host_terms``: serial inputs and HDF5/checks/index, and the chunk filters, which
the chunk writer runs on every core, divided over the GPU machine's 16 cores); the disk (this machine's
write bandwidth); and the virtual assembly measured at 65,536 sectors.  A bake overlaps device, host and
disk, so projected = max(device, host, write) + assembly.

    .venv/bin/python benchmarks/scaling.py [--sectors 256] [--repeat 3] [--sizes 1024] [--blocks 1,4,64]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import save, table

CODE = "import sys; from hairlut_cli.main import cli; cli(sys.argv[1:])"
#: name, devices per process, the cores of each process, how (plain: one bake; dist: --distributed; pair: independent
#: plain bakes of the whole recipe, one per core, at once: what two processes can reach on this machine), merge
CONFIGS = [("plain 1 dev", 1, [{0}], "plain", None), ("dist 1 x 1", 1, [{0}], "dist", "virtual"),
           ("plain 2 dev", 2, [{0, 1}], "plain", None), ("2 x plain (pair)", 1, [{0}, {1}], "pair", None),
           ("dist 2 x 1 virtual", 1, [{0}, {1}], "dist", "virtual"), ("dist 2 x 1 copy", 1, [{0}, {1}], "dist", "copy")]
#: (config, baseline): the distributed path against plain bakes on the same cores
SAME_CORES = [("dist 1 x 1", "plain 1 dev"), ("dist 2 x 1 virtual", "plain 2 dev"), ("dist 2 x 1 copy", "plain 2 dev"),
              ("dist 2 x 1 virtual", "2 x plain (pair)"), ("dist 2 x 1 copy", "2 x plain (pair)")]
BLOCK = 4
TRACE = {"angles": {"views": 16, "lights": 16}, "trace": {"pixels": 32, "steps": 32}, "sectors": {"grid": [16, 16]}}
PRODUCTION = {"sectors": {"count": 65_536}, "angles": {"views": 64, "lights": 64}, "trace": {"pixels": 64},
              "storage": {"dtype": "float16"}}
#: the assembly's parts: the production's density grid (the default 32 x 32) and float16, the cheapest trace
ASSEMBLY = {"sectors": {"count": 1024}, "angles": {"views": 1, "lights": 1}, "trace": {"pixels": 2, "steps": 2},
            "storage": {"dtype": "float16"}}
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


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _pinned(cmd: list[str], cores: set[int]):
    """(command, preexec): ``taskset -c CORES cmd``, or sched_setaffinity in the child where taskset is missing."""
    if shutil.which("taskset"):
        return ["taskset", "-c", ",".join(map(str, sorted(cores))), *cmd], None
    return cmd, lambda: os.sched_setaffinity(0, cores)


def _toml(recipe: dict) -> str:
    lines = []
    for section, body in recipe.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in body.items()]
    return "\n".join(lines) + "\n"


def _run(recipe: Path, out: Path, devices: int, cores: list[set[int]], how: str, merge: str | None) -> dict:
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(devices)}
    port, n = _port(), len(cores)

    def cmd(k):
        dest = out.with_name(f"{out.stem}-{k}{out.suffix}") if how == "pair" else out
        base = [sys.executable, "-c", CODE, "bake", "hrir", "--recipe", str(recipe), "--out", str(dest), "--no-progress",
                "--json", "--block", str(BLOCK)]
        return base + (["--distributed", "--coordinator", f"127.0.0.1:{port}", "--num-processes", str(n), "--process-id",
                        str(k), "--merge", merge] if how == "dist" else [])

    cmds = [cmd(k) for k in range(n)]
    t0 = time.perf_counter()
    procs = []
    for c, cs in zip(cmds, cores):
        cmd, pre = _pinned(c, cs)
        procs.append(subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                                      preexec_fn=pre))
    outs, peaks = [], []
    for p in procs:
        outs.append(p.stdout.read())
        _, status, usage = os.wait4(p.pid, 0)  # this child's own peak memory
        p.returncode = os.waitstatus_to_exitcode(status)
        peaks.append(usage.ru_maxrss / 1024)
    wall = time.perf_counter() - t0
    if any(p.returncode for p in procs):
        raise SystemExit(f"bake failed: devices={devices} cores={cores} merge={merge}")
    reports = [json.loads(o[o.index("\n{") + 1 if not o.startswith("{") else 0:]) for o in outs]
    lead = reports[0]
    return {"bake_s": max(r["seconds"] for r in reports), "wall_s": wall, "assemble_s": lead.get("assemble_s"),
            "blocks_s": [r["blocks_s"] for r in reports],
            # steady: each process's median block (blocks that meet a new shape compile, the first above all)
            "steady_rate": sum(BLOCK / statistics.median(r["block_seconds"]) for r in reports),
            # CPU-time normalised: sectors per CPU-second of a median block, and the cores it received
            "cpu_rate": sum(r["computed"] for r in reports) / sum(len(r["block_cpu_seconds"]) * statistics.median(
                r["block_cpu_seconds"]) for r in reports),
            "cores_got": sum(statistics.median(r["block_cpu_seconds"]) / statistics.median(r["block_seconds"]) for r in reports),
            # the CPU seconds of blocks beyond a median block's: compilation, which every process does for itself
            "compile_cpu_s": sum(sum(r["block_cpu_seconds"]) - len(r["block_cpu_seconds"]) * statistics.median(
                r["block_cpu_seconds"]) for r in reports),
            "peak_rss_mib": max(peaks), "bytes": lead["bytes"], "sectors": sum(r["sectors"] for r in reports)}


def _assemble_times(recipe: dict, paths: list[Path], scratch: Path, repeat: int, processes: int = 2,
                    copy: bool = True) -> dict:
    """Seconds (wall and CPU, best of ``repeat``) of the leader's last step of a ``processes``-process bake, as
    ``hairlut.sharding.run`` takes it: virtual datasets over the parts (the index from the leader's own parts
    and the other processes' share files) and a copy; and what indexing costs each process per part (paid
    before the barrier, while it bakes)."""
    from hairlut import registry
    from hairlut.assets import canonical_json, recipe_hash
    from hairlut.distributed import Process
    from hairlut.parts import share_name, stamp, write_share
    from hairlut.sharding import blocks_of, finish, header

    baker = registry.get("hrir_db")
    spans = [header(p, baker)[:2] for p in paths]
    total, block = spans[-1][1], spans[0][1] - spans[0][0]
    folder = paths[0].parent
    out = folder.with_name(folder.name[:-len(".parts")])
    digest = recipe_hash(canonical_json(recipe))
    t0, c0 = time.perf_counter(), time.process_time()
    own = {}
    for k in range(processes):  # what each process does after its blocks: index them, write its share file
        mine = {b: (stamp(folder / Path(paths[spans.index(b)]).name), baker.units.index(recipe, paths[spans.index(b)]))
                for b in blocks_of(total, block, (k, processes))}
        if k == 0:
            own = mine
        else:
            write_share(folder / share_name(k, processes), digest, total, mine)
    index = {"index_cpu_s_per_part": (time.process_time() - c0) / len(paths),
             "index_s_per_part": (time.perf_counter() - t0) / len(paths)}
    times = {m: [] for m in (("virtual", "copy") if copy else ("virtual",))}
    for i in range(repeat):
        for merge in times:
            t0, c0 = time.perf_counter(), time.process_time()
            finish(baker, recipe, out, total, block, merge, Process(0, processes), own if merge == "virtual" else None)
            times[merge].append((time.perf_counter() - t0, time.process_time() - c0))
            size = out.stat().st_size
            index[f"{merge}_bytes"] = size
            out.unlink()
    return {**index, **{f"{m}_s": min(t[0] for t in v) for m, v in times.items()},
            **{f"{m}_cpu_s": min(t[1] for t in v) for m, v in times.items()}}


def _assembly(sizes: list[int], blocks: list[int], tmp: Path, repeat: int, copy_max: int, keep: Path | None) -> list[dict]:
    """Virtual against copy assembly: each size baked once for each block size (parts of ``block`` sectors), with the
    ASSEMBLY recipe (the production's density grid and float16, one view and light, 2 px, 2 steps), as one
    ``--merge virtual`` process (no copy at the end); the copy is timed up to ``copy_max`` sectors.  ``keep``: bake
    there and keep the parts (a rerun resumes them)."""
    from hairlut.hrir import bake, resolve_recipe
    from hairlut.parts import parts_dir

    rows = []
    where = keep or tmp
    for n in sizes:
        given = {**ASSEMBLY, "sectors": {**ASSEMBLY["sectors"], "count": n}}
        for b in blocks:
            out = where / f"asm{n}-{b}.h5"
            (rep, cpu), wall = _timed(lambda: bake(given, out, block=b, keep_parts=True, distributed=True, merge="virtual"))
            out.unlink()
            parts = sorted(parts_dir(out).glob("part-*.h5"))
            t = _assemble_times(resolve_recipe(given), parts, tmp, repeat, copy=n <= copy_max)
            rows.append({"sectors": n, "parts": len(parts), "part_bytes": sum(p.stat().st_size for p in parts), **t,
                         "bake_s": wall, "bake_cpu_s": cpu, "resumed": rep["resumed"],
                         "copy_x_virtual": t["copy_cpu_s"] / t["virtual_cpu_s"] if "copy_cpu_s" in t else None})
            if keep is None:
                shutil.rmtree(parts_dir(out))
    return rows


def _timed(fn):
    """((result, CPU seconds), wall seconds) of ``fn()``."""
    t0 = time.perf_counter()
    got = _cpu(fn)
    return got, time.perf_counter() - t0


def _cpu(fn):
    """(result, CPU seconds of every thread) of ``fn()``."""
    c0 = time.process_time()
    out = fn()
    return out, time.process_time() - c0


def _host_terms(tmp: Path, block: int = 32) -> dict:
    """The host's work per sector of a production-shaped bake, CPU seconds on this machine (module docstring).

    A HOST recipe (the production's angles, pixels, density grid and float16; a 2-step trace) is baked twice in
    blocks of ``block`` (the first compiles) through the public ``bake`` (``--merge virtual``: no copy).  Its CPU time
    per sector splits into: the trace (``trace_sectors`` on the same sectors, timed alone); the inputs
    (``sample_block``, ``sector_density``, ``sector_geometry``: serial Python and small kernels); the chunk filters
    (shuffle, gzip, fletcher32 of α and reflectance, ``hairlut.assets.chunks.filter_chunk``: run on every core by the
    chunk writer); and the rest (HDF5 calls, checks, the part index: serial), the bake's CPU less the other three."""
    from hairlut.assets.chunks import filter_chunk
    from hairlut.geometry import sector_density
    from hairlut.hrir import bake, resolve_recipe, sample_block, sector_geometry, trace_sectors

    r = resolve_recipe(HOST)
    n = r["sectors"]["count"]
    bake(HOST, tmp / "host-warm.h5", block=block, distributed=True, merge="virtual")
    _, bake_cpu = _cpu(lambda: bake(HOST, tmp / "host.h5", block=block, distributed=True, merge="virtual"))
    prep = trace = filters = 0.0
    dtype = r["storage"]["dtype"]
    for s in range(0, n, block):
        (splats, params), c1 = _cpu(lambda: sample_block(r, s, min(s + block, n)))
        dens, c2 = _cpu(lambda: sector_density(splats, tuple(r["sectors"]["grid"]),
                                               density_scale=r["sectors"]["density_scale"], chunk=1))
        geom, c3 = _cpu(lambda: sector_geometry(params, kappa=r["trace"]["extinction"], n_pix=r["trace"]["pixels"],
                                                smooth_ratio=r["trace"]["smooth_ratio"]))
        (alpha, refl), c4 = _cpu(lambda: trace_sectors(dens, geom, r))
        prep += c1 + c2 + c3
        trace += c4
        a16, r16 = np.asarray(alpha, dtype), np.asarray(refl, dtype)  # the stored chunks: α 16 sectors, reflectance 1
        _, c5 = _cpu(lambda: [filter_chunk(a16[i:i + 16], 4) for i in range(0, len(a16), 16)]
                     + [filter_chunk(r16[i:i + 1], 4) for i in range(len(r16))])
        filters += c5
    terms = {"prep": prep / n, "filters": filters / n, "trace_cpu": trace / n}
    terms["rest"] = max(bake_cpu / n - terms["prep"] - terms["filters"] - terms["trace_cpu"], 0.0)
    return {**terms, "bake_cpu": bake_cpu / n, "recipe": HOST, "block": block,
            "bytes_per_sector": sum(p.stat().st_size for p in (tmp / "host.h5.parts").glob("part-*.h5")) / n}


def _write_bandwidth(tmp: Path, mib: int = 256) -> float:
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


def _projection(asm: list[dict], host: dict) -> dict:
    """The production database on GPUS H200s, projected term by term (printed): the device from the last H200 rate, the
    host from this machine's CPU, the disk, and the leader's assembly; a bake overlaps the first three, so
    projected = max(device, host, write) + assembly."""
    from hairlut import registry

    prod_bytes, _ = registry.get("hrir_db").estimate(PRODUCTION)
    n = PRODUCTION["sectors"]["count"]
    each = n / GPUS
    ratio = _work(PRODUCTION) / n / (_work(DEFAULT) / DEFAULT["sectors"]["count"])
    device_rate = H200["rate"] / ratio  # production sectors per second on one H200, at least
    serial, parallel = host["prep"] + host["rest"], host["filters"]
    host_s = each * (serial + parallel / GPU_HOST_CORES)
    write_s = prod_bytes / host["write_bytes_per_s"]
    at_size = [r for r in asm if r["sectors"] == n]
    assembly_s = min((r["virtual_s"] for r in at_size), default=None)
    out = {"bytes": prod_bytes, "sectors_per_gpu": each, "work_ratio_default": ratio, "device_rate": device_rate,
           "device_s": each / device_rate, "host_serial_s_per_sector": serial, "host_parallel_cpu_s_per_sector": parallel,
           "host_s": host_s, "write_s": write_s, "assembly_s": assembly_s, "host": host}
    out["projected_s"] = max(out["device_s"], host_s, write_s) + (assembly_s or 0.0)
    print(f"\nproduction database (65,536 sectors, 64 x 64 angles, 64 px, 64 steps, float16: {prod_bytes / 1e9:.1f} GB) on "
          f"{GPUS} H200s: projected, not measured on a GPU; {each:,.0f} sectors per GPU")
    print(f"  device:   {out['device_s']:7.1f} s  the last H200 rate, {H200['rate']:.0f} default sectors/s at {H200['commit']} "
          f"(host-bound then: the device's rate was at least this), / {ratio:.0f} (a production sector's tracing work)")
    print(f"  host:     {host_s:7.1f} s  this CPU, per sector {1e3 * serial:.2f} CPU-ms serial (inputs {1e3 * host['prep']:.2f},"
          f" HDF5/checks/index {1e3 * host['rest']:.2f}) + {1e3 * parallel:.2f} CPU-ms of chunk filters over "
          f"{GPU_HOST_CORES} cores (HOST recipe: production shapes, 2-step trace; same per-core speed assumed)")
    need = prod_bytes / max(out["device_s"], host_s)
    out["write_bytes_per_s_needed"] = need
    print(f"  write:    {write_s:7.1f} s  {prod_bytes / 1e9:.1f} GB at this machine's disk, "
          f"{host['write_bytes_per_s'] / 1e6:.0f} MB/s (a VM disk shared with other jobs; the GPU node's storage decides: "
          f"{need / 1e6:.0f} MB/s keeps the disk off the critical path)")
    print("  assembly: " + (f"{assembly_s:7.3f} s  virtual, measured here at {n:,} sectors (best part count's wall)"
                            if assembly_s is not None else "   not measured in this run (--sizes 65536)"))
    print(f"  projected = max(device, host, write) + assembly = {out['projected_s'] / 60:.1f} min")
    return out


def _work(recipe: dict) -> float:
    """Tracing work of a bake: sector · view · light · pixel · step · ray (what hrir_db's estimate counts)."""
    from hairlut.hrir import resolve_recipe

    r = resolve_recipe(recipe, budget=False)
    t = r["trace"]
    return float(r["sectors"]["count"] * r["angles"]["views"] * r["angles"]["lights"] * t["pixels"] * t["steps"]
                 * t["rays_per_pixel"])


def _spread(rounds: list[dict], name: str, base: str, key=lambda r: r["steady_rate"]) -> list[float]:
    """The ratio name/base taken round by round: (min, median, max)."""
    ratios = [key(r[name]) / key(r[base]) for r in rounds]
    return [min(ratios), statistics.median(ratios), max(ratios)]


def _print_assembly(asm: list[dict]) -> None:
    if not asm:
        return
    print(f"assembling the final asset from the same parts, the leader's step of a 2-process bake (best of 2, "
          f"in-process; load average {os.getloadavg()[0]:.1f}; copy timed up to --copy-max sectors):\n")
    for r in asm:
        r["index_ms_per_part"] = 1e3 * r["index_cpu_s_per_part"]
        r["virtual_cpu_ms_per_part"] = 1e3 * r["virtual_cpu_s"] / r["parts"]
        r["virtual_cpu_us_per_sector"] = 1e6 * r["virtual_cpu_s"] / r["sectors"]
    print(table(asm, [("sectors", "sectors", ""), ("parts", "parts", ""), ("part_bytes", "part bytes", ",.0f"),
                      ("index_ms_per_part", "index CPU-ms/part", ".1f"),
                      ("virtual_s", "virtual s", ".3f"), ("virtual_cpu_s", "virtual CPU-s", ".3f"),
                      ("virtual_cpu_ms_per_part", "CPU-ms/part", ".2f"), ("virtual_cpu_us_per_sector", "CPU-us/sector", ".2f"),
                      ("virtual_bytes", "virtual bytes", ",.0f"), ("copy_s", "copy s", ".3f"),
                      ("copy_cpu_s", "copy CPU-s", ".3f"), ("copy_bytes", "copy bytes", ",.0f"),
                      ("copy_x_virtual", "copy/virtual CPU", ".1f")]))
    print()


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sectors", type=int, default=256, help="sectors of the scaling rounds (256: compilation amortised)")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved rounds of every configuration")
    ap.add_argument("--sizes", default="1024", help="database sizes (sectors) of the assembly timing")
    ap.add_argument("--blocks", default="1,4,64", help="sectors per part of the assembly timing")
    ap.add_argument("--copy-max", type=int, default=4096, help="time the copy only up to this many sectors")
    ap.add_argument("--keep", type=Path, help="bake the assembly's parts here and keep them (a rerun resumes them)")
    ap.add_argument("--no-projection", action="store_true", help="skip the host measurement and the projection")
    ap.add_argument("--name", default="scaling", help="results/<name>.json")
    a = ap.parse_args(argv)
    if len(os.sched_getaffinity(0)) < 2:
        raise SystemExit("needs two cores")
    load_before = os.getloadavg()
    rounds = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        recipe = tmp / "r.toml"
        recipe.write_text(_toml({**TRACE, "sectors": {**TRACE["sectors"], "count": a.sectors}}))
        for i in range(a.repeat):
            got = {}
            for name, devices, cores, how, merge in CONFIGS:
                got[name] = _run(recipe, tmp / f"{name.replace(' ', '_')}-{i}.h5", devices, cores, how, merge)
                print(f"round {i + 1}/{a.repeat} {name}: {got[name]['steady_rate']:.2f} sectors/s, "
                      f"bake {got[name]['bake_s']:.1f} s", file=sys.stderr)
            rounds.append(got)
        sizes = [int(s) for s in a.sizes.split(",") if s]
        blocks = [int(g) for g in a.blocks.split(",") if g]
        asm = _assembly(sizes, blocks, tmp, repeat=2, copy_max=a.copy_max, keep=a.keep)
        hosts = None if a.no_projection else {**_host_terms(tmp), "write_bytes_per_s": _write_bandwidth(tmp)}
    _print_assembly(asm)
    if not rounds:  # --repeat 0: the assembly and the projection only
        doc = {"assembly": asm, "load_before": load_before, "load_after": os.getloadavg(),
               "projection": _projection(asm, hosts) if hosts else None}
        save(a.name, doc)
        return doc
    base = "plain 1 dev"
    rows = []
    for name, devices, cores, how, merge in CONFIGS:
        runs = [r[name] for r in rounds]
        best = max(runs, key=lambda r: r["steady_rate"])
        rows.append({"config": name, "devices": devices, "processes": len(cores), "cores": "+".join(
            ",".join(map(str, sorted(c))) for c in cores), "merge": merge or "copy",
            "rate_best": best["steady_rate"], "rate_median": statistics.median(r["steady_rate"] for r in runs),
            "x_base": best["steady_rate"] / max(r[base]["steady_rate"] for r in rounds),
            "x_base_range": _spread(rounds, name, base), "bake_s": min(r["bake_s"] for r in runs),
            "wall_s": min(r["wall_s"] for r in runs), "assemble_s": min((r["assemble_s"] for r in runs if r["assemble_s"]
                                                                        is not None), default=None),
            "cpu_rate": max(r["cpu_rate"] for r in runs), "cores_got": statistics.median(r["cores_got"] for r in runs),
            "compile_cpu_s": min(r["compile_cpu_s"] for r in runs),
            "bytes_per_sector": best["bytes"] / best["sectors"] if how != "pair" else None,  # a pair bakes it twice
            "peak_rss_mib": max(r["peak_rss_mib"] for r in runs),
            "rates": [r["steady_rate"] for r in runs]})
    for r in rows:  # if every pinned core were given in full: sectors per CPU-second times the cores
        r["full_cores_rate"] = r["cpu_rate"] * len(r["cores"].replace("+", ",").split(","))
        r["x_base_full_cores"] = r["full_cores_rate"] / rows[0]["full_cores_rate"]
    by = {r["config"]: r for r in rows}
    costs = []
    for name, ref in SAME_CORES:
        rate = by[ref]["rate_best"] / by[name]["rate_best"] - 1
        lo, mid, hi = _spread(rounds, ref, name)
        bake = by[name]["bake_s"] / by[ref]["bake_s"] - 1
        costs.append({"config": name, "against": ref, "rate_cost": rate, "rate_cost_median": mid - 1,
                      "rate_cost_range": [lo - 1, hi - 1], "bake_s_cost": bake})
    print(f"{a.sectors} sectors, {TRACE['angles']['views']}x{TRACE['angles']['lights']} angles, {TRACE['trace']['pixels']} px, "
          f"{TRACE['trace']['steps']} steps, blocks of {BLOCK}; {a.repeat} interleaved rounds; load average before "
          f"{load_before[0]:.1f} on {os.cpu_count()} cores (a shared machine)\n")
    print(table(rows, [("config", "config", ""), ("cores", "cores", ""), ("rate_best", "sectors/s best", ".2f"),
                       ("rate_median", "median", ".2f"), ("x_base", "x 1 core", ".2f"), ("cores_got", "cores got", ".2f"),
                       ("cpu_rate", "sectors/CPU-s", ".2f"), ("x_base_full_cores", "x 1 core, full cores", ".2f"),
                       ("compile_cpu_s", "compile CPU-s", ".1f"),
                       ("bake_s", "bake s", ".1f"),
                       ("assemble_s", "assemble s", ".3f"), ("bytes_per_sector", "B/sector", ".0f"),
                       ("peak_rss_mib", "peak MiB", ".0f")]))
    print()
    for r in rows[1:]:
        lo, mid, hi = r["x_base_range"]
        print(f"  {r['config']:<19} x 1 core: best rates {r['x_base']:.2f}; round by round median {mid:.2f} "
              f"(range {lo:.2f}..{hi:.2f})")
    for c in costs:
        lo, hi = c["rate_cost_range"]
        print(f"  {c['config']:<19} against {c['against']} on the same cores: throughput cost, best rates "
              f"{100 * c['rate_cost']:+.0f}%, round by round median {100 * c['rate_cost_median']:+.0f}% (range "
              f"{100 * lo:+.0f}..{100 * hi:+.0f}%); whole-bake seconds {100 * c['bake_s_cost']:+.0f}%")
    bench = {**TRACE, "sectors": {**TRACE["sectors"], "count": a.sectors}}
    per_sector = _work(bench) / a.sectors
    core_rate = by[base]["rate_best"] * per_sector  # work per second, one core
    prod_work = _work(PRODUCTION)
    print(f"\nproduction database from this run's one-core CPU rate: {prod_work / core_rate / 3600:.0f} core-hours; 8 such "
          f"devices {prod_work / core_rate / GPUS / 3600:.1f} h (linear scaling assumed)")
    projection = {**(_projection(asm, hosts) if hosts else {}), "one_core_s": prod_work / core_rate,
                  "cpu_cores_8_s": prod_work / core_rate / GPUS}
    doc = {"sectors": a.sectors, "recipe": bench, "block": BLOCK, "rounds": a.repeat, "load_before": load_before,
           "load_after": os.getloadavg(), "rows": rows, "same_cores": costs, "assembly": asm, "projection": projection}
    save(a.name, doc)
    return doc


if __name__ == "__main__":
    main()
