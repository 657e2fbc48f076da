"""The final asset's assembly, timed (``scaling.py``'s second table; its module docstring): virtual
datasets against a copy from the same parts, as the leader of a 2-process bake takes it."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

from _common import table

#: the assembly's parts: the production's density grid (the default 32 x 32) and float16, the cheapest trace
ASSEMBLY = {"sectors": {"count": 1024}, "angles": {"views": 1, "lights": 1}, "trace": {"pixels": 2, "steps": 2},
            "storage": {"dtype": "float16"}}


def timed(fn):
    """((result, CPU seconds), wall seconds) of ``fn()``."""
    t0 = time.perf_counter()
    got = cpu(fn)
    return got, time.perf_counter() - t0


def cpu(fn):
    """(result, CPU seconds of every thread) of ``fn()``."""
    c0 = time.process_time()
    out = fn()
    return out, time.process_time() - c0


def assemble_times(recipe: dict, paths: list[Path], scratch: Path, repeat: int, processes: int = 2,
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


def assembly(sizes: list[int], blocks: list[int], tmp: Path, repeat: int, copy_max: int, keep: Path | None) -> list[dict]:
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
            (rep, cpu), wall = timed(lambda: bake(given, out, block=b, keep_parts=True, distributed=True, merge="virtual"))
            out.unlink()
            parts = sorted(parts_dir(out).glob("part-*.h5"))
            t = assemble_times(resolve_recipe(given), parts, tmp, repeat, copy=n <= copy_max)
            rows.append({"sectors": n, "parts": len(parts), "part_bytes": sum(p.stat().st_size for p in parts), **t,
                         "bake_s": wall, "bake_cpu_s": cpu, "resumed": rep["resumed"],
                         "copy_x_virtual": t["copy_cpu_s"] / t["virtual_cpu_s"] if "copy_cpu_s" in t else None})
            if keep is None:
                shutil.rmtree(parts_dir(out))
    return rows


def print_assembly(asm: list[dict]) -> None:
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
