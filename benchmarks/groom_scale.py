"""Scale with the groom (issue 26): where the time of a production-size groom goes before its first frame, stage by
stage, for the working tree and a base revision in the same run.

For each size (default 20,000 and 100,000 strands) a groom is generated (``hairlut.bench._grooms``: curly by default,
32 points a strand, seeded) and written as ``.hair`` (or ``.tfx``) with a minimal scene TOML: ``[groom] path``,
``[camera] view`` and resolution, one light (``[lights] directions``), a hair colour (``[material] hair_color``), every
other key hairlut's default.  Then, for each tree (the working tree, ``new``; ``--base REV``, a detached git worktree
of REV made for the run and removed after, ``base``), each in its own processes on the same groom and scene, with an
empty table cache and an empty JAX compilation cache of its own:

* ``read``: ``hairlut.geometry.read_strands`` of the groom;
* ``clusters``: ``hairlut.scene.scene_clusters`` cold (reading, the checks, the cluster fit, the split per cluster);
* ``sectors``: ``hairlut.scene.scene_sectors`` with the clusters in memory (the sector assignment and its measures);
* ``plan``: ``hairlut plan`` (a process: imports included), the cache empty;
* ``bake``: ``hairlut bake --scene`` right after;
* ``render``: the first ``hairlut render``, tables baked;
* ``cold total``: plan + bake + render, the issue's 3-minute target;
* ``warm plan``, ``warm render``: both again; ``warm pre-frame`` is the warm render's wall time less its frame
  (``--json``'s ``seconds``: maps, shade, setup, trim, camera pass, first raster), the issue's 5-second target.

Every stage is wall time on a shared machine (the ``cpu`` rows: the process's user + system CPU seconds, less
sensitive to the other processes' load): compare the trees' figures of one run (the ratio column), not runs.
``--profile`` runs the working tree's CLI stages under cProfile (results/groom_scale-SIZE-STAGE.prof) and prints each
one's heaviest hairlut functions.  Writes benchmarks/results/groom_scale.json.

Usage: python -m benchmarks.groom_scale [--sizes 20000 100000] [--base REV] [--kind curly] [--format hair]
                                        [--no-base] [--profile] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ._common import RESULTS, ROOT, emit, table

#: The scene's one light and hair colour (the rest is hairlut's default).
LIGHT = [0.5, 0.8, 1.0]
COLOR = [0.45, 0.3, 0.2]
FRAME_PARTS = ("maps", "shade", "setup", "trim", "plan", "raster_first")

#: What the in-process stages run (the same public names in both trees).
_PROBE = r"""
import json, sys, time
from hairlut.geometry import read_strands
from hairlut.scene import load_scene, scene_clusters, scene_sectors
sc = load_scene(sys.argv[1])
out = {}
t = time.perf_counter(); s = read_strands(sc.groom_path); out["read"] = time.perf_counter() - t
out["strands"], out["points"] = int(s.n_strands), int(s.n_points)
t = time.perf_counter(); pairs = scene_clusters(sc); out["clusters"] = time.perf_counter() - t
out["n_clusters"] = len(pairs)
t = time.perf_counter(); ss = scene_sectors(sc); out["sectors"] = time.perf_counter() - t
out["n_sectors"] = int(len(ss.aspect))
print(json.dumps(out))
"""


def write_groom(folder: Path, n: int, kind: str, fmt: str, points: int, seed: int, resolution: int) -> Path:
    """Generate a ``kind`` groom of ``n`` strands (``hairlut.bench.GROOM_KINDS``), write it as ``fmt`` and a minimal scene beside
    it; the scene's path."""
    from hairlut.bench import GROOM_KINDS as KINDS
    from hairlut.bench import GROOM_VIEWS as VIEWS
    from hairlut.bench import write_groom as write

    folder.mkdir(parents=True, exist_ok=True)
    groom = write(folder, f"{kind}{n}", KINDS[kind](n, points, seed=seed), formats=(fmt,))[fmt]
    scene = folder / f"{kind}{n}.toml"
    vec = lambda v: "[" + ", ".join(f"{x:g}" for x in v) + "]"  # noqa: E731
    scene.write_text(
        f'[groom]\npath = "{groom.name}"\n\n'
        f"[camera]\nview = {vec(VIEWS['front'])}\nresolution = [{resolution}, {resolution}]\n\n"
        f"[lights]\ndirections = [{vec(LIGHT)}]\n\n"
        f"[material]\nhair_color = {vec(COLOR)}\n"
    )
    return scene


def _env(tree: Path, work: Path) -> dict:
    env = dict(os.environ)
    env.update(
        PYTHONPATH=str(tree),
        HAIRLUT_CACHE=str(work / "tables"),
        JAX_COMPILATION_CACHE_DIR=str(work / "xla"),
        PYTHONHASHSEED="0",
    )
    return env


#: CPU seconds (user + system) of each finished child process, by the command's first words (``_run``).
CPU: dict = {}


def _run(tree: Path, env: dict, args: list[str], profile: Path | None = None) -> tuple[float, str]:
    """Wall seconds and stdout of ``python [-m cProfile -o PROFILE] ARGS`` in ``tree`` (its CPU seconds in
    ``CPU["last"]``); raises on failure."""
    cmd = [sys.executable] + (["-m", "cProfile", "-o", str(profile)] if profile else []) + args
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU["last"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if r.returncode:
        raise RuntimeError(f"{' '.join(args[:4])} failed in {tree}:\n{r.stderr[-3000:]}")
    return wall, r.stdout


def _hairlut(*args) -> list[str]:
    """``hairlut ARGS`` of the tree the process runs in (its ``cli`` package; cProfile takes ``-m``, not ``-c``)."""
    return ["-m", "cli.main", *args]


def run_tree(tree: Path, scene: Path, work: Path, profile_to: Path | None = None) -> dict:
    """Every stage (module docstring) of ``scene`` by the hairlut in ``tree``, with caches under ``work``."""
    work.mkdir(parents=True, exist_ok=True)
    for sub in ("tables", "xla"):
        shutil.rmtree(work / sub, ignore_errors=True)
    env = _env(tree, work)
    out: dict = {}
    _, text = _run(tree, env, ["-c", _PROBE, str(scene)])
    out.update(json.loads(text.strip().splitlines()[-1]))
    shutil.rmtree(work / "tables", ignore_errors=True)  # the probe may have filled the groom cache

    def prof(stage):
        return None if profile_to is None else profile_to.with_name(f"{profile_to.name}-{stage}.prof")

    exr = work / "frame.exr"
    for stage, args in (
        ("plan", ["plan", str(scene)]),
        ("bake", ["bake", "--scene", str(scene), "--no-progress"]),
        ("render", ["render", str(scene), "--out", str(exr)]),
        ("warm plan", ["plan", str(scene)]),
    ):
        out[stage], _ = _run(tree, env, _hairlut(*args), prof(stage.replace(" ", "-")))
        out[f"{stage} cpu"] = CPU["last"]
    out["cold total"] = out["plan"] + out["bake"] + out["render"]
    out["cold total cpu"] = out["plan cpu"] + out["bake cpu"] + out["render cpu"]
    wall, text = _run(tree, env, _hairlut("render", str(scene), "--out", str(exr), "--json"), prof("warm-render"))
    sec = json.loads(text)["seconds"]
    out["warm render"], out["warm render cpu"] = wall, CPU["last"]
    out["warm frame"] = sum(sec.get(k, 0.0) for k in FRAME_PARTS)
    out["warm pre-frame"] = wall - out["warm frame"]
    out["warm prepare"] = sec.get("prepare", float("nan"))
    return out


def _top(path: Path, n: int = 12) -> str:
    import io
    import pstats

    buf = io.StringIO()
    pstats.Stats(str(path), stream=buf).sort_stats("cumulative").print_stats("hairlut/(geometry|scene|synth|render|planner)", n)
    return "\n".join(line for line in buf.getvalue().splitlines() if "hairlut/" in line)


STAGES = (
    "read",
    "clusters",
    "sectors",
    "plan",
    "bake",
    "render",
    "cold total",
    "cold total cpu",
    "warm plan",
    "warm plan cpu",
    "warm render",
    "warm render cpu",
    "warm frame",
    "warm pre-frame",
    "warm prepare",
)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[20000, 100000])
    ap.add_argument("--base", default="main", help="the base revision (a git worktree of it is made for the run)")
    ap.add_argument("--no-base", action="store_true", help="time the working tree only")
    ap.add_argument("--kind", default="curly", choices=("curly", "parted", "crop"))
    ap.add_argument("--format", default="hair", choices=("hair", "tfx"))
    ap.add_argument("--points", type=int, default=32)
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--keep", type=Path, help="generate and keep the grooms, scenes and caches here")
    ap.add_argument("--json", type=Path, help="write the results here instead of benchmarks/results/groom_scale.json")
    a = ap.parse_args(argv)

    top = a.keep or Path(tempfile.mkdtemp(prefix="groom-scale-"))
    trees = {"new": ROOT}
    base_tree = None
    if not a.no_base:
        base_tree = top / "base-tree"
        if base_tree.exists():
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_tree)], check=False)
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(base_tree), a.base], check=True, capture_output=True
        )
        trees = {"base": base_tree, "new": ROOT}
    rev = {
        k: subprocess.run(["git", "-C", str(t), "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        for k, t in trees.items()
    }
    results, rows = {}, []
    try:
        for n in a.sizes:
            scene = write_groom(top / f"groom-{n}", n, a.kind, a.format, a.points, a.seed, a.resolution)
            res = {}
            for name, tree in trees.items():
                prof = RESULTS / f"groom_scale-{n}" if (a.profile and name == "new") else None
                if prof:
                    RESULTS.mkdir(exist_ok=True)
                print(f"{n} strands, {name} ({rev[name]}) ...", flush=True)
                res[name] = run_tree(tree, scene, top / f"work-{n}-{name}", prof)
                print(json.dumps({k: round(v, 2) if isinstance(v, float) else v for k, v in res[name].items()}), flush=True)
                if prof:
                    for stage in ("plan", "bake", "render", "warm-plan", "warm-render"):
                        print(
                            f"-- cProfile, {n} strands, {stage} (cumulative):\n{_top(prof.with_name(f'{prof.name}-{stage}.prof'))}"
                        )
            results[n] = res
            for stage in STAGES:
                row = {"strands": n, "stage": stage, **{k: res[k].get(stage) for k in res}}
                if "base" in res and row.get("new"):
                    row["ratio"] = row["base"] / row["new"]
                rows.append(row)
    finally:
        if base_tree is not None:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_tree)], check=False)
        if a.keep is None:
            shutil.rmtree(top, ignore_errors=True)
    cols = [("strands", "strands", "d"), ("stage", "stage", "s")]
    cols += [(k, f"{k} {rev[k]} (s)", ".2f") for k in trees] + ([("ratio", "base / new", ".1f")] if "base" in trees else [])
    print(table(rows, cols))
    print(
        emit(
            "groom_scale",
            {"kind": a.kind, "format": a.format, "points": a.points, "revisions": rev, "results": results, "rows": rows},
            a.json,
        )
    )


if __name__ == "__main__":
    main()
