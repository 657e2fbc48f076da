"""The one shard path of every table kind that declares :class:`hairlut.bake.protocol.Units`.

A bake of ``count`` units is cut into fixed blocks of ``block`` units (the same blocks
however the work is shared).  Each block is baked once into ``<out>.parts/`` (see
:mod:`hairlut.assets.parts`) and reused by a rerun when it validates against the recipe hash,
so an interrupted bake resumes and writes the same data as an uninterrupted one.

Who bakes which blocks:
- a plain bake: all of them, on every local device (:func:`hairlut.bake.devices.map_units`);
- ``shard='K/N'``: the K-th of N contiguous runs of blocks, joined into one shard file for ``merge``;
- ``distributed``: process K of N bakes the K-th run; after a barrier, process 0 writes the
  final asset, as HDF5 virtual datasets over the parts (``merge='virtual'``, the default:
  nothing is copied) or as one self-contained file (``merge='copy'``).

Each process holds its own lock (``<out>.parts.lock[.K]``), so a second bake of the same
output waits for the first and then reuses its asset.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import canonical_json, open_table, read_table, recipe_hash
from ..assets.parts import (
    clean_temporaries,
    locked,
    open_folder,
    part_name,
    read_share,
    remove_folder,
    share_name,
    stamp,
    write_share,
)
from ..assets.virtual_write import write_virtual
from ..files import not_an_input
from .cache import is_valid
from .devices import Process, agree, barrier, current
from .protocol import Baker, parse_shard

MERGES = ("virtual", "copy")


def blocks_of(total: int, block: int, share: tuple[int, int] | None = None) -> list[tuple[int, int]]:
    """The (start, stop) blocks of a bake, or of share (K, N): the K-th of N contiguous runs of blocks."""
    blocks = [(s, min(s + block, total)) for s in range(0, total, block)]
    if share is None:
        return blocks
    k, n = share
    return blocks[k * len(blocks) // n : (k + 1) * len(blocks) // n]


def header(path, baker: Baker) -> tuple[int, int, int, str, dict]:
    """(start, stop, total, recipe hash, recipe) of a part or shard file of ``baker``'s kind."""
    axis = baker.units.axis
    with open_table(path, baker.shard_kind) as f:
        try:
            start, stop, total = (int(f.attrs[f"{axis}_{k}"]) for k in ("start", "stop", "total"))
        except KeyError as exc:
            raise errors.MissingDatasetError(path, f"root attribute {exc} is missing") from None
        digest = f.attrs["recipe_hash"]
        digest = digest.decode() if isinstance(digest, bytes) else str(digest)
        recipe = json.loads(f.attrs["recipe"])
    if not 0 <= start < stop <= total:
        raise errors.CorruptAssetError(path, f"{axis} range {start}..{stop} of {total} is not a range")
    return start, stop, total, digest, recipe


def _intact(part: Path, baker: Baker, digest: str, start: int, stop: int, total: int, full: bool = True) -> bool:
    """Whether a finished part validates for this recipe and range: resumable.  ``full``: every checksum and
    everything the kind reads (else the header only: a part its own process has just validated or written)."""
    if part.is_symlink() or not part.is_file():
        return False
    try:
        head = header(part, baker)
        if head[:4] != (start, stop, total, digest):
            return False
        if not full:
            return True
        if baker.units.check is not None:
            baker.units.check(head[4], part)  # everything the kind reads from a part (older formats fail here)
        else:
            read_table(part, baker.shard_kind)
    except errors.AssetError:
        return False
    return True


COPY_NOTE = (
    "a copied asset (a plain bake, --merge copy, hairlut merge) holds every unit at once; a virtual one "
    "(--merge virtual, the default with --distributed) holds one block per process"
)


def held(total: int, block: int, want: int, merge: str, shard, leader: bool) -> tuple[int, str]:
    """(units whose tables this process holds at once, why): what its memory budget counts."""
    if shard is not None:
        return want, "a --shard file holds its slice at once"
    if merge == "copy" and leader:
        return total, COPY_NOTE
    return min(block, total), ""


def _bake_blocks(
    units, recipe: dict, todo, parts, total: int, digest: str, baker: Baker, report: dict, progress, want: int, inputs: dict
) -> None:
    """Bake (or resume) each block of ``todo`` into its part, the device's work on one block overlapping the
    host's on the one before when ``bake_part`` returns its last step (see :class:`hairlut.bake.protocol.Units`).

    A block's ``block_seconds`` (and ``block_cpu_seconds``) run from the later of its start and the previous
    block's completion to its own completion: with the overlap they add up to the loop's time."""
    done = 0
    pending = None  # (finish, start, stop, started) of the block whose last step is still to run
    mark = time.perf_counter(), time.process_time()

    def complete(finish, s, e, started) -> None:
        nonlocal done, mark
        finish()
        now = time.perf_counter(), time.process_time()
        since = max(started, mark, key=lambda m: m[0])
        report["computed"] += e - s
        report.setdefault("block_seconds", []).append(now[0] - since[0])  # the first compiles
        report.setdefault("block_cpu_seconds", []).append(now[1] - since[1])  # every thread's CPU time
        mark = now
        done += e - s
        if progress:
            progress(done, want)

    intact = [part.exists() and _intact(part, baker, digest, s, e, total) for (s, e), part in zip(todo, parts)]
    report["resumed"] = done = sum(e - s for (s, e), ok in zip(todo, intact) if ok)
    if progress:  # once, before any work: the resumed units (a progress bar's rate leaves them out)
        progress(done, want)
    for (s, e), part, ok in zip(todo, parts, intact):
        if ok:
            continue
        started = time.perf_counter(), time.process_time()
        try:
            step = units.bake_part(recipe, s, e, total, part, **inputs)
        except BaseException:
            if pending:  # the block before is computed: keep it
                complete(*pending)
            raise
        if pending:
            complete(*pending)  # the host writes block i while the devices compute block i + 1
        pending = (step, s, e, started) if callable(step) else None
        if pending is None:
            complete(lambda: None, s, e, started)
    if pending:
        complete(*pending)


def bake(
    baker: Baker,
    recipe: dict,
    out,
    *,
    progress=None,
    shard=None,
    distributed=False,
    merge: str | None = None,
    block: int | None = None,
    keep_parts: bool = False,
    **inputs,
) -> dict:
    """Bake a resolved ``recipe`` of ``baker``'s kind into ``out``: by units (:func:`run`) when the kind declares
    them and the recipe splits, else by the kind's own ``bake``, which refuses the split options."""
    units = baker.units
    if units is not None and units.applies(recipe):
        if units.start is not None:
            units.start(recipe, shard=shard, **inputs)
        t0 = time.perf_counter()
        report = run(
            baker,
            recipe,
            out,
            progress=progress,
            shard=shard,
            block=block,
            keep_parts=keep_parts,
            distributed=distributed,
            merge=merge,
            **inputs,
        )
        if units.report is not None:
            report.update(units.report(recipe, report, **inputs))
        report["seconds"] = time.perf_counter() - t0
        return report
    if units is None:  # a kind that does not split shards by its own bake (or refuses to: protocol.no_shard)
        for name, value in (("distributed", distributed), ("merge", merge)):
            if value:
                raise errors.ValidationError(name, value, f"{baker.kind} bakes cannot be split across processes")
        return baker.bake(recipe, out, progress=progress, shard=shard, **inputs)
    for name, value in (("shard", shard), ("distributed", distributed), ("merge", merge), ("block", block)):
        if value:
            raise errors.ValidationError(name, value, units.unsplit)
    return baker.bake(recipe, out, progress=progress, **inputs)


def run(
    baker: Baker,
    recipe: dict,
    out,
    *,
    progress=None,
    shard=None,
    block: int | None = None,
    keep_parts: bool = False,
    distributed: bool | Process = False,
    merge: str | None = None,
    **inputs,
) -> dict:
    """Bake (or resume) ``recipe`` of ``baker``'s kind into ``out`` along its units; returns a report.

    ``progress(done, total)`` counts this process's units: first once with the resumed units (0 when none), then
    after each computed block.  ``distributed``:
    this process is one of JAX's distributed processes (:func:`hairlut.bake.devices.initialize` first).
    The leader's report says how long writing the final asset took (``assemble_s``: virtual or copy); each
    computed block's wall and CPU seconds are ``block_seconds`` and ``block_cpu_seconds`` (CPU time over wall
    time: the cores the block received, which a shared machine may not give in full).
    """
    units = baker.units
    if units is None:
        raise errors.ValidationError("shard", shard, f"{baker.kind} bakes cannot be sharded")
    block = units.default_block(recipe, shard is not None or bool(distributed)) if block is None else block
    if isinstance(block, bool) or not isinstance(block, int) or block < 1:
        raise errors.ValidationError("block", block, "must be an integer ≥ 1")
    proc = (distributed if isinstance(distributed, Process) else current()) if distributed else Process()
    if shard is not None and proc.count > 1:
        raise errors.ValidationError(
            "shard", shard, "--shard and --distributed exclude each other: each distributed process bakes its own share"
        )
    merge = merge or ("virtual" if proc.count > 1 else "copy")
    if merge not in MERGES:
        raise errors.ValidationError("merge", merge, f"one of {', '.join(MERGES)}")
    if shard is not None and merge == "virtual":
        raise errors.ValidationError("merge", merge, "a --shard file is a copy; `hairlut merge` joins shards")
    total = units.count(recipe, **inputs)
    if total < 1:
        raise errors.ValidationError(units.axis, total, f"this {baker.kind} recipe has no {units.axis} axis to split")
    block = min(block, total)  # one block of all the units, named as such (a virtual asset reads its block from it)
    share = parse_shard(shard) if shard is not None else ((proc.index, proc.count) if proc.count > 1 else None)
    todo = blocks_of(total, block, share)
    if not todo and shard is not None:  # a distributed process with no block just waits for the others
        raise errors.ValidationError(
            "shard", shard, f"empty: {total} {units.axis} make {len(blocks_of(total, block))} blocks, fewer than shards"
        )
    want = todo[-1][1] - todo[0][0] if todo else 0
    digest = recipe_hash(canonical_json(recipe))
    out = Path(out)
    if proc.count > 1:  # before any work: every process bakes the same blocks of one recipe into one output
        agree(
            {"--out": str(out.absolute()), "recipe hash": digest, "--block": block, "--merge": merge, units.axis: total}, recipe
        )
    if units.budget is not None:  # before anything is made: what this process will hold at once
        units.budget(recipe, block, *held(total, block, want, merge, shard, proc.leader))
    t0 = time.perf_counter()
    writes_out = proc.leader or shard is not None
    report = {
        "out": str(out),
        "kind": baker.kind if shard is None else baker.shard_kind,
        "units": want,
        "unit_range": [todo[0][0], todo[-1][1]] if todo else [0, 0],
        "total_units": total,
        "computed": 0,
        "resumed": 0,
        "process": proc.index,
        "processes": proc.count,
        "merge": merge if shard is None else "shard",
        "recipe_hash": digest,
    }
    with locked(out, f".{proc.index}" if proc.count > 1 else "") as waited:
        if waited and share is None and is_valid(out, baker.kind, digest):
            report.update(resumed=want, seconds=time.perf_counter() - t0, bytes=out.stat().st_size, status="reused")
            return report  # another bake of this output finished while we waited for it
        folder = open_folder(out)
        indexed = merge == "virtual" and shard is None and units.index is not None
        share_file = folder / share_name(proc.index, proc.count)
        clean_temporaries(
            [folder / part_name(s, e, total, block) for s, e in todo]
            + ([out] if writes_out else [])
            + ([share_file] if indexed and proc.count > 1 else [])
        )
        mine = [folder / part_name(s, e, total, block) for s, e in todo]
        _bake_blocks(units, recipe, todo, mine, total, digest, baker, report, progress, want, inputs)
        indexes = _index_share(units, recipe, todo, mine, share_file, digest, total, proc, report, inputs) if indexed else None
        report["blocks_s"] = time.perf_counter() - t0
        if shard is not None:
            path = units.join(recipe, mine, out)
        else:
            barrier(f"hairlut:{out.name}:parts")
            path = out
            t_assemble = time.perf_counter()
            if proc.leader:
                finish(baker, recipe, out, total, block, merge, proc, indexes, **inputs)
                report["assemble_s"] = time.perf_counter() - t_assemble
            barrier(f"hairlut:{out.name}:final")
        if not keep_parts and merge == "copy" and writes_out:
            remove_folder(folder)
    report.update(seconds=time.perf_counter() - t0, bytes=Path(path).stat().st_size, out=str(path), status="baked")
    return report


def _index_share(
    units, recipe: dict, todo, parts, share_file: Path, digest: str, total: int, proc: Process, report: dict, inputs: dict
) -> dict:
    """{(start, stop): (stamp, index)} of this process's parts (``Units.index``: what the final asset stores from
    each), written as its share file for the leader when there are other processes; ``index_s`` in the report."""
    t = time.perf_counter()
    indexes = {b: (stamp(p), units.index(recipe, p, **inputs)) for b, p in zip(todo, parts)}
    if proc.count > 1 and indexes:
        write_share(share_file, digest, total, indexes)
    report["index_s"] = time.perf_counter() - t
    return indexes


def finish(
    baker: Baker,
    recipe: dict,
    out,
    total: int,
    block: int,
    merge: str,
    proc: Process = Process(),
    own: dict | None = None,
    **inputs,
) -> Path:
    """The leader's last step, once every process's parts are in ``<out>.parts/``: write ``out``, as virtual
    datasets over the parts (``merge='virtual'``; the index from ``own`` and the share files, see
    :func:`gather`) or as a copy."""
    units, out = baker.units, Path(out)
    folder = out.with_name(out.name + ".parts")
    digest = recipe_hash(canonical_json(recipe))
    parts = [(folder / part_name(s, e, total, block), s, e) for s, e in blocks_of(total, block)]
    if merge == "virtual":
        index = gather(baker, recipe, folder, proc, digest, total, block, parts, own, inputs)
        axes, variables, attrs = units.whole(recipe, [p for p, _, _ in parts], **index, **inputs)
        return write_virtual(out, baker.kind, recipe, units.axis, parts, axes, variables, attrs)
    for p, s, e in parts:  # each process validated or wrote its own parts: the headers suffice
        _present(p, baker, digest, s, e, total)
    return units.assemble(recipe, [p for p, _, _ in parts], out, **inputs)


def _present(part: Path, baker: Baker, digest: str, start: int, stop: int, total: int) -> None:
    if not _intact(part, baker, digest, start, stop, total, full=False):
        raise errors.AssetNotFoundError(part, "part missing or damaged after every process finished")


def gather(
    baker: Baker, recipe: dict, folder: Path, proc: Process, digest: str, total: int, block: int, parts, own, inputs: dict
) -> dict:
    """The leader's ``whole`` keyword arguments: every part's index (``index=[...]``) from its own indexes and
    the other processes' share files, one file per process whatever the part count.  A part that no index
    covers unchanged (a share file missing or foreign, a part rewritten since) is checked and indexed here;
    without ``Units.index``, ``whole`` reads the parts itself ({})."""
    if baker.units.index is None:
        for p, s, e in parts:
            _present(p, baker, digest, s, e, total)
        return {}
    got = {}
    for b, (st, ix) in (own or {}).items():
        try:
            if np.array_equal(stamp(folder / part_name(*b, total, block)), st):
                got[b] = ix
        except (OSError, errors.ValidationError):
            pass
    for k in range(proc.count):
        if k != proc.index:
            got.update(read_share(folder / share_name(k, proc.count), digest, total, block, folder))
    for p, s, e in parts:
        if (s, e) not in got:
            _present(p, baker, digest, s, e, total)
            got[(s, e)] = baker.units.index(recipe, p, **inputs)
    return {"index": [got[(s, e)] for _, s, e in parts]}


def merge(baker: Baker, shards, out) -> dict:
    """Join ``shard_kind`` files covering every unit of one recipe into one self-contained asset."""
    shards = [Path(p) for p in shards]
    if not shards:
        raise errors.ValidationError("shards", shards, "give at least one shard")
    not_an_input(out, shards)
    items = sorted(((*header(p, baker), p) for p in shards), key=lambda x: x[0])
    total, digest, recipe = items[0][2], items[0][3], items[0][4]
    pos = 0
    for start, stop, t, h, _, p in items:
        if h != digest or t != total:
            raise errors.CorruptAssetError(p, "shard of a different bake (recipe or unit count differs)")
        if start != pos:
            raise errors.CorruptAssetError(
                p,
                f"{baker.units.axis} {pos}..{start - 1} are missing or overlap"
                if start > pos
                else f"overlaps the previous shard at {baker.units.axis} {start}",
            )
        pos = stop
    if pos != total:
        raise errors.ValidationError("shards", [str(i[5]) for i in items], f"cover {baker.units.axis} 0..{pos - 1} of {total}")
    if baker.units.budget is not None:
        baker.units.budget(recipe, baker.units.default_block(recipe, True), total, COPY_NOTE)
    path = baker.units.assemble(recipe, [i[5] for i in items], out)
    return {"out": str(path), "shards": len(items), "units": pos, "bytes": Path(path).stat().st_size, "recipe_hash": digest}
