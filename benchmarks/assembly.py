"""The final asset's assembly, timed (:func:`assembly`, the last term of ``benchmarks.production``): virtual
datasets against a copy from the same parts, as the leader of a 2-process bake takes it.

Run on its own (issue 16), it times the leader's step by part count, 256 to 16,384 parts, on copies of one
baked part (:func:`synthetic_parts`), the printf mappings against the old one mapping per part in the same run,
and what a reader pays on the new asset::

    .venv/bin/python -m benchmarks.assembly [--parts 256,1024,4096,16384] [--block 16] [--repeat 2]

and, with ``--readers 256,1024``, what a reader pays on such an asset, the working tree against ``--base``::

    .venv/bin/python -m benchmarks.assembly --readers 256,1024 [--base a3c4b35] [--repeat 2]
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from pathlib import Path

from ._common import ROOT, table

#: the assembly's parts: the production's density grid (the default 32 x 32) and float16, the cheapest trace
ASSEMBLY = {
    "sectors": {"count": 1024},
    "angles": {"views": 1, "lights": 1},
    "trace": {"pixels": 2, "steps": 2},
    "storage": {"dtype": "float16"},
}


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


def assemble_times(recipe: dict, paths: list[Path], scratch: Path, repeat: int, processes: int = 2, copy: bool = True) -> dict:
    """Seconds (wall and CPU, best of ``repeat``) of the leader's last step of a ``processes``-process bake, as
    ``hairlut.bake.sharding.run`` takes it: virtual datasets over the parts (the index from the leader's own parts
    and the other processes' share files) and a copy; and what indexing costs each process per part (paid
    before the barrier, while it bakes)."""
    from hairlut.assets import canonical_json, recipe_hash
    from hairlut.assets.parts import share_name, stamp, write_share
    from hairlut.bake import registry
    from hairlut.bake.devices import Process
    from hairlut.bake.sharding import blocks_of, finish, header

    baker = registry.get("hrir_db")
    paths = sorted(paths, key=lambda p: header(p, baker)[0])  # in sector order (the names sort by text)
    spans = [header(p, baker)[:2] for p in paths]
    total, block = spans[-1][1], spans[0][1] - spans[0][0]
    folder = paths[0].parent
    out = folder.with_name(folder.name[: -len(".parts")])
    digest = recipe_hash(canonical_json(recipe))
    t0, c0 = time.perf_counter(), time.process_time()
    own = {}
    for k in range(processes):  # what each process does after its blocks: index them, write its share file
        mine = {
            b: (stamp(folder / Path(paths[spans.index(b)]).name), baker.units.index(recipe, paths[spans.index(b)]))
            for b in blocks_of(total, block, (k, processes))
        }
        if k == 0:
            own = mine
        else:
            write_share(folder / share_name(k, processes), digest, total, mine)
    index = {
        "index_cpu_s_per_part": (time.process_time() - c0) / len(paths),
        "index_s_per_part": (time.perf_counter() - t0) / len(paths),
    }
    times = {m: [] for m in (("virtual", "copy") if copy else ("virtual",))}
    for _ in range(repeat):
        for merge in times:
            t0, c0 = time.perf_counter(), time.process_time()
            finish(baker, recipe, out, total, block, merge, Process(0, processes), own if merge == "virtual" else None)
            times[merge].append((time.perf_counter() - t0, time.process_time() - c0))
            size = out.stat().st_size
            index[f"{merge}_bytes"] = size
            out.unlink()
    return {
        **index,
        **{f"{m}_s": min(t[0] for t in v) for m, v in times.items()},
        **{f"{m}_cpu_s": min(t[1] for t in v) for m, v in times.items()},
    }


def assembly(sizes: list[int], blocks: list[int], tmp: Path, repeat: int, copy_max: int, keep: Path | None) -> list[dict]:
    """Virtual against copy assembly: each size baked once for each block size (parts of ``block`` sectors), with the
    ASSEMBLY recipe (the production's density grid and float16, one view and light, 2 px, 2 steps), as one
    ``--merge virtual`` process (no copy at the end); the copy is timed up to ``copy_max`` sectors.  ``keep``: bake
    there and keep the parts (a rerun resumes them)."""
    from hairlut.assets.parts import parts_dir
    from hairlut.hrir import bake, resolve_recipe

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
            rows.append(
                {
                    "sectors": n,
                    "parts": len(parts),
                    "part_bytes": sum(p.stat().st_size for p in parts),
                    **t,
                    "bake_s": wall,
                    "bake_cpu_s": cpu,
                    "resumed": rep["resumed"],
                    "copy_x_virtual": t["copy_cpu_s"] / t["virtual_cpu_s"] if "copy_cpu_s" in t else None,
                }
            )
            if keep is None:
                shutil.rmtree(parts_dir(out))
    return rows


def print_assembly(asm: list[dict]) -> None:
    if not asm:
        return
    print(
        f"assembling the final asset from the same parts, the leader's step of a 2-process bake (best of 2, "
        f"in-process; load average {os.getloadavg()[0]:.1f}; copy timed up to --copy-max sectors):\n"
    )
    for r in asm:
        r["index_ms_per_part"] = 1e3 * r["index_cpu_s_per_part"]
        r["virtual_cpu_ms_per_part"] = 1e3 * r["virtual_cpu_s"] / r["parts"]
        r["virtual_cpu_us_per_sector"] = 1e6 * r["virtual_cpu_s"] / r["sectors"]
    print(
        table(
            asm,
            [
                ("sectors", "sectors", ""),
                ("parts", "parts", ""),
                ("part_bytes", "part bytes", ",.0f"),
                ("index_ms_per_part", "index CPU-ms/part", ".1f"),
                ("virtual_s", "virtual s", ".3f"),
                ("virtual_cpu_s", "virtual CPU-s", ".3f"),
                ("virtual_cpu_ms_per_part", "CPU-ms/part", ".2f"),
                ("virtual_cpu_us_per_sector", "CPU-us/sector", ".2f"),
                ("virtual_bytes", "virtual bytes", ",.0f"),
                ("copy_s", "copy s", ".3f"),
                ("copy_cpu_s", "copy CPU-s", ".3f"),
                ("copy_bytes", "copy bytes", ",.0f"),
                ("copy_x_virtual", "copy/virtual CPU", ".1f"),
            ],
        )
    )
    print()


# ----------------------------------------------------------------------------- part counts beyond a bake's reach


def old_mappings(total: int, block: int, rest: tuple, src: str, names: list[bytes], fill):
    """The mappings as written before issue 16's printf layout (``hairlut.assets.parts._mappings`` up to 7f422cc, now ``hairlut.assets.virtual_write._mappings``): one
    hyperslab and one ``H5Pset_virtual`` per part, each part named in full.  Kept here only to time the old
    assembly against the new in the same run, on the same parts (``names``: the new pattern and the last part,
    from which every part's name follows)."""
    import h5py
    import numpy as np

    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_layout(h5py.h5d.VIRTUAL)
    dcpl.set_fill_value(np.array([fill]))
    vspace = h5py.h5s.create_simple((total, *rest))
    zeros, spaces = (0,) * len(rest), {}
    dset = src.encode()
    for start in range(0, total, block):
        n = min(block, total - start)
        name = names[1] if start + n == total else names[0].replace(b"%b", str(start // block).encode())
        if n not in spaces:
            spaces[n] = h5py.h5s.create_simple((n, *rest))
        vspace.select_hyperslab((start, *zeros), (n, *rest))
        dcpl.set_virtual(vspace, name, dset, spaces[n])
    return dcpl


def synthetic_parts(where: Path, parts: int, block: int) -> tuple[dict, Path, dict]:
    """(recipe, out, index) of ``parts`` parts of ``block`` sectors each (the ASSEMBLY recipe at parts × block
    sectors) in ``out``'s parts folder.  Baking 4,096 or more parts takes too long on the shared machine, so one
    part is baked for real (a 2-part bake of ``block``-sector blocks) and copied, each copy's header attributes
    (sector range, total, recipe, recipe hash) rewritten: every part has a real part's layout and size, and its
    index (what the leader joins) is that part's, the same for every copy."""
    import h5py

    from hairlut.assets import canonical_json, recipe_hash
    from hairlut.assets.parts import open_folder, part_name, parts_dir
    from hairlut.bake import registry
    from hairlut.hrir import bake, resolve_recipe

    seed = where / f"seed-{block}.h5"
    if not parts_dir(seed).exists():
        bake(
            {**ASSEMBLY, "sectors": {**ASSEMBLY["sectors"], "count": 2 * block}},
            seed,
            block=block,
            keep_parts=True,
            distributed=True,
            merge="virtual",
        )
    template = parts_dir(seed) / part_name(0, block, 2 * block, block)
    total = parts * block
    recipe = resolve_recipe({**ASSEMBLY, "sectors": {**ASSEMBLY["sectors"], "count": total}})
    text = canonical_json(recipe)
    out = where / f"synth{parts}x{block}.h5"
    folder = open_folder(out)
    raw = template.read_bytes()
    for s in range(0, total, block):
        path = folder / part_name(s, s + block, total, block)
        path.write_bytes(raw)
        with h5py.File(path, "r+") as f:
            f.attrs.update(
                {
                    "sector_start": s,
                    "sector_stop": s + block,
                    "sector_total": total,
                    "recipe": text,
                    "recipe_hash": recipe_hash(text),
                }
            )
    index = registry.get("hrir_db").units.index(recipe, template)
    index["features"] = index["features"][:block]
    return recipe, out, index


def leader_times(recipe: dict, out: Path, block: int, index: dict, repeat: int, old: bool = True, readers: bool = True) -> dict:
    """Wall and CPU seconds (best of ``repeat``) of the leader's step of a 2-process bake over ``out``'s parts
    (``hairlut.bake.sharding.finish``: process 0's indexes in memory, process 1's share file), with the printf
    mappings (``new``) and, in the same run, with :func:`old_mappings` (``old``); then what a reader pays on the
    new asset: opening it and one per-sector table's shape (HDF5 finds the block files: ``open``), and
    ``check_virtual`` (every part checked, as readers, ``inspect`` and the cache do: ``check``)."""
    import h5py

    import hairlut.assets.virtual_write as virtual_mod
    from hairlut.assets import canonical_json, recipe_hash
    from hairlut.assets.parts import part_name, parts_dir, share_name, stamp, write_share
    from hairlut.assets.virtual_write import check_virtual
    from hairlut.bake import registry
    from hairlut.bake.devices import Process
    from hairlut.bake.sharding import blocks_of, finish

    baker = registry.get("hrir_db")
    total = recipe["sectors"]["count"]
    folder = parts_dir(out)
    digest = recipe_hash(canonical_json(recipe))
    entry = {b: (stamp(folder / part_name(*b, total, block)), index) for b in blocks_of(total, block)}
    own = {b: entry[b] for b in blocks_of(total, block, (0, 2))}
    write_share(folder / share_name(1, 2), digest, total, {b: entry[b] for b in blocks_of(total, block, (1, 2))})
    got = {}
    for label, mappings in (("new", virtual_mod._mappings), *((("old", old_mappings),) if old else ())):
        best = None
        for _ in range(repeat):
            saved, virtual_mod._mappings = virtual_mod._mappings, mappings
            try:
                (_, c), w = timed(lambda: finish(baker, recipe, out, total, block, "virtual", Process(0, 2), own))
            finally:
                virtual_mod._mappings = saved
            best = (w, c) if best is None or c < best[1] else best
            got[f"{label}_bytes"] = out.stat().st_size
            out.unlink()
        got[f"{label}_s"], got[f"{label}_cpu_s"] = best
    if readers:
        finish(baker, recipe, out, total, block, "virtual", Process(0, 2), own)

        def opened():
            with h5py.File(out, "r") as f:
                return f["reflectance"].shape

        (shape, got["open_cpu_s"]), got["open_s"] = timed(opened)
        assert shape[0] == total, shape
        (_, got["check_cpu_s"]), got["check_s"] = timed(lambda: check_virtual(out))
        out.unlink()
    return got


def part_counts(counts: list[int], block: int, tmp: Path, repeat: int, readers_max: int) -> list[dict]:
    """:func:`leader_times` at each part count of ``counts`` (synthetic parts of ``block`` sectors)."""
    rows = []
    for n in counts:
        c0 = time.process_time()
        recipe, out, index = synthetic_parts(tmp, n, block)
        made = time.process_time() - c0
        t = leader_times(recipe, out, block, index, repeat, readers=n <= readers_max)
        rows.append(
            {
                "parts": n,
                "sectors": n * block,
                "make_cpu_s": made,
                **t,
                "old_x_new": t["old_cpu_s"] / t["new_cpu_s"],
                "load": os.getloadavg()[0],
            }
        )
        shutil.rmtree(out.with_name(out.name + ".parts"))
        print(f"{n} parts: new {t['new_cpu_s']:.3f} CPU-s, old {t['old_cpu_s']:.3f} CPU-s", file=sys.stderr)
    return rows


def print_part_counts(rows: list[dict]) -> None:
    print(
        f"the leader's step of a 2-process bake by part count, printf mappings (new) against one mapping per part "
        f"(old), same run, same synthetic parts (best CPU time of --repeat; load average {os.getloadavg()[0]:.1f}):\n"
    )
    print(
        table(
            rows,
            [
                ("parts", "parts", ",d"),
                ("sectors", "sectors", ",d"),
                ("new_s", "new s", ".3f"),
                ("new_cpu_s", "new CPU-s", ".3f"),
                ("old_s", "old s", ".3f"),
                ("old_cpu_s", "old CPU-s", ".3f"),
                ("old_x_new", "old/new CPU", ".1f"),
                ("new_bytes", "new bytes", ",.0f"),
                ("old_bytes", "old bytes", ",.0f"),
                ("open_cpu_s", "reader open CPU-s", ".3f"),
                ("check_cpu_s", "check_virtual CPU-s", ".3f"),
                ("load", "load", ".1f"),
            ],
        )
    )
    print()


# ----------------------------------------------------------------------------- readers, before and after


#: Run in a fresh interpreter whose working folder is the tree under test (its ``hairlut`` first on the import path,
#: before the installed one): each step's CPU seconds (process
#: time, every thread) in order, and a digest of what ``load_hrir_db`` read (the same bytes before and after).
_READER = """
import hashlib, json, sys, time
from hairlut.hrir import load_hrir_db
from hairlut.assets.virtual_write import check_virtual
out, got = sys.argv[1], {}
for step in sys.argv[2].split(","):
    c0 = time.process_time()
    r = check_virtual(out) if step.startswith("check") else load_hrir_db(out)
    got[step] = time.process_time() - c0
    if not step.startswith("check"):
        h = hashlib.sha256()
        for a in (r.features, r.alpha, r.reflectance, r.density, *r.geometry.values(), *r.params.values()):
            h.update(a.tobytes())
        got["digest"] = h.hexdigest()
print(json.dumps(got))
"""


def tree_at(rev: str, where: Path) -> Path:
    """A copy of ``hairlut/`` as it was at git revision ``rev`` (``git archive``: the repository is only read)."""
    import subprocess
    import tarfile

    where.mkdir(parents=True, exist_ok=True)
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "hairlut"], check=True, capture_output=True).stdout
    import io

    with tarfile.open(fileobj=io.BytesIO(tar)) as t:
        t.extractall(where, filter="data")
    return where


def reader_steps(tree: Path, out: Path, steps: str) -> dict:
    """:data:`_READER`'s steps on ``out`` in a fresh interpreter that imports ``hairlut`` from ``tree`` (its working
    folder, which ``python -c`` puts first on the import path; ``PYTHONPATH`` names it too)."""
    import json
    import subprocess

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tree), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    res = subprocess.run(
        [sys.executable, "-c", _READER, str(out), steps], env=env, cwd=tree, capture_output=True, text=True, check=True
    )
    return json.loads(res.stdout.strip().splitlines()[-1])


def readers(counts: list[int], block: int, tmp: Path, base: str, repeat: int = 1) -> list[dict]:
    """What a reader pays on a virtual ``hrir_db`` of each part count (:func:`synthetic_parts`, written by the leader's
    step), the working tree's ``hairlut`` against revision ``base``'s on the same asset, each in fresh interpreters:
    ``load_hrir_db`` in a new process (``load_cold``: every part opened) and again in it (``load_warm``; the parts
    unchanged), ``check_virtual`` after them, and ``check_virtual`` alone in a new process (``check_cold``).  With
    ``repeat`` > 1 the two trees take turns that many times and each step keeps its least CPU time (the shared
    machine's load moves the CPU seconds of one run by up to 1.4×)."""
    from hairlut.assets.parts import part_name, stamp
    from hairlut.bake import registry
    from hairlut.bake.devices import Process
    from hairlut.bake.sharding import blocks_of, finish

    trees = {"base": tree_at(base, tmp / "base-tree"), "new": ROOT}
    rows = []
    for n in counts:
        recipe, out, index = synthetic_parts(tmp, n, block)
        total = n * block
        folder = out.with_name(out.name + ".parts")
        own = {b: (stamp(folder / part_name(*b, total, block)), index) for b in blocks_of(total, block)}
        finish(registry.get("hrir_db"), recipe, out, total, block, "virtual", Process(0, 1), own)
        row = {"parts": n, "sectors": total}
        for turn in range(repeat):
            for label, tree in trees.items():
                # the base caches nothing between calls: its load_hrir_db again costs what the first did
                got = reader_steps(tree, out, "load_cold,check_warm" if label == "base" else "load_cold,load_warm,check_warm")
                got.update(reader_steps(tree, out, "check_cold"))
                for k, v in got.items():
                    key = f"{label}_{k}"
                    if k == "digest":
                        assert row.setdefault(key, v) == v, f"{label} read other bytes on turn {turn + 1}"
                    else:
                        row[key] = min(row.get(key, v), v)
                print(
                    f"{n} parts, {label}: " + ", ".join(f"{k} {v:.3f}" for k, v in got.items() if k != "digest"), file=sys.stderr
                )
        row["same_data"] = row.pop("base_digest") == row.pop("new_digest")
        row["load_base_x_new"] = row["base_load_cold"] / row["new_load_cold"]
        row["load"] = os.getloadavg()[0]
        rows.append(row)
        shutil.rmtree(folder)
        out.unlink()
    return rows


def print_readers(rows: list[dict], base: str, repeat: int = 1) -> None:
    print(
        f"a reader of a virtual hrir_db by part count, revision {base} (base) against the working tree (new), same "
        f"run, same asset, CPU seconds in fresh interpreters, least of {repeat} turns each "
        f"(load average {os.getloadavg()[0]:.1f}):\n"
    )
    cols = [("parts", "parts", ",d")]
    for label in ("base", "new"):
        cols += [
            (f"{label}_load_cold", f"{label} load_hrir_db", ".2f"),
            (f"{label}_load_warm", f"{label} again", ".2f"),
            (f"{label}_check_cold", f"{label} check_virtual", ".3f"),
            (f"{label}_check_warm", f"{label} check again", ".3f"),
        ]
    print(
        table(
            rows, cols + [("load_base_x_new", "load base/new", ".1f"), ("same_data", "same bytes", ""), ("load", "load", ".1f")]
        )
    )
    print()


def main(argv=None) -> list[dict]:
    import argparse
    import tempfile

    from ._common import save

    ap = argparse.ArgumentParser(description="the virtual assembly's cost by part count (issue 16)")
    ap.add_argument("--parts", default="256,1024,4096,16384", help="part counts")
    ap.add_argument("--block", type=int, default=16, help="sectors per part (16: 4,096 parts are 65,536 sectors)")
    ap.add_argument("--repeat", type=int, default=2, help="best of this many assemblies (--readers: turns per tree)")
    ap.add_argument("--readers-max", type=int, default=4096, help="time the readers' open and check up to this many parts")
    ap.add_argument("--name", default="assembly", help="results/<name>.json")
    ap.add_argument(
        "--readers",
        default="",
        help="part counts (e.g. 256,1024): only a reader's cost, --base against the working tree (results/<name>-readers.json)",
    )
    ap.add_argument("--base", default="a3c4b35", help="the revision the readers are timed against")
    a = ap.parse_args(argv)
    if a.readers:
        with tempfile.TemporaryDirectory() as tmp:
            rows = readers([int(n) for n in a.readers.split(",") if n], a.block, Path(tmp), a.base, a.repeat)
        print_readers(rows, a.base, a.repeat)
        save(f"{a.name}-readers", {"rows": rows, "block": a.block, "base": a.base, "repeat": a.repeat})
        return rows
    with tempfile.TemporaryDirectory() as tmp:
        rows = part_counts([int(n) for n in a.parts.split(",") if n], a.block, Path(tmp), a.repeat, a.readers_max)
    print_part_counts(rows)
    save(a.name, {"rows": rows, "block": a.block})
    return rows


if __name__ == "__main__":
    main()
