"""The parts folder of a bake (every table kind): its files, locks and share indexes.

``<out>.parts/`` holds a bake's finished blocks, one file each (the kind's shard kind),
named by the bake's unit count, its block size and the block's number (:func:`part_name`):
``part-<total>x<block>-<b>.h5``, and ``part-<total>x<block>-<b>-last.h5`` for the last block.  hairlut creates the folder atomically with a marker file
(:data:`MARKER`) inside, and refuses a folder without it, or a symlink, rather than touch
what it did not create; it deletes only the part files, temporaries and marker it wrote.
Bakes of one output take turns on an advisory lock (``fcntl.flock`` on
``<out>.parts.lock``, opened without following symlinks, removed by its holder on release:
:func:`lock_file`; ``hairlut cache prune`` removes the ones killed processes left,
:func:`remove_if_unused`).

The virtual asset built over the folder is :mod:`hairlut.assets.virtual_write`'s.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import secrets
import shutil
from pathlib import Path

import numpy as np

from .. import errors
from ..files import regular_file
from . import atomic_path

MARKER = ".hairlut-parts"
MARKER_TEXT = "hairlut parts folder: finished blocks of a bake; hairlut deletes only its own files here\n"
PART_GLOB = "part-*.h5"
SHARE_GLOB = "share-*-of-*.npz"


def parts_dir(out) -> Path:
    """The parts folder of an output file: ``OUT.parts/`` beside ``OUT``."""
    out = Path(out)
    return out.with_name(out.name + ".parts")


def part_name(start: int, stop: int, total: int, block: int) -> str:
    """The part file of units [start, stop) of a bake of ``total`` units in blocks of ``block``: named by the block's
    number, so that a virtual asset maps every whole block with one printf-style name (:func:`part_pattern`); the
    last block, whole or short, is ``…-last.h5``, outside that pattern (a short block cannot share its selection)."""
    if start % block or not 0 <= start < stop <= total or stop != min(start + block, total):
        raise errors.ValidationError("part", [start, stop], f"not a block of {total} units in blocks of {block}")
    return f"part-{total}x{block}-{start // block}{'-last' if stop == total else ''}.h5"


def part_pattern(total: int, block: int) -> str:
    """The HDF5 printf-style source name (``%b``: the block number) of the whole blocks' parts (:func:`part_name`)."""
    return f"part-{total}x{block}-%b.h5"


def _is_ours(folder: Path) -> bool:
    marker = folder / MARKER
    return not marker.is_symlink() and marker.is_file() and marker.read_text(errors="replace") == MARKER_TEXT


def open_folder(out) -> Path:
    """The parts folder of ``out``, created atomically with its marker; refuse anything hairlut did not make."""
    folder = parts_dir(out)
    if not folder.exists() and not folder.is_symlink():
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = folder.with_name(f".{folder.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
        tmp.mkdir()
        (tmp / MARKER).write_text(MARKER_TEXT)
        try:
            os.rename(tmp, folder)  # atomic; fails if another process made the folder first
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
    if folder.is_symlink():
        raise errors.ValidationError(
            "out", str(out), f"{folder} is a symlink; hairlut does not write through symlinks (remove it or choose another --out)"
        )
    if not folder.is_dir():
        raise errors.ValidationError(
            "out", str(out), f"{folder} exists and is not a folder hairlut made; move it away or choose another --out"
        )
    if not _is_ours(folder):
        raise errors.ValidationError(
            "out",
            str(out),
            f"{folder} exists but was not made by hairlut (no {MARKER} "
            "marker); hairlut will not write into or delete it: move it away or choose another --out",
        )
    return folder


def clean_temporaries(paths) -> list[Path]:
    """Remove the temporaries that killed writers of ``paths`` left beside them (``.<name>.<pid>.<token>.tmp``).

    Call with the output's lock held, for files only this process writes."""
    gone = []
    for path in map(Path, paths):
        gone += [p for p in path.parent.glob(f".{path.name}.*.tmp") if p.is_file() and not p.is_symlink()]
    for p in gone:
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    return gone


def remove_folder(folder: Path) -> None:
    """Delete the part files, temporaries and marker hairlut wrote, then the folder if it is empty."""
    if folder.is_symlink() or not folder.is_dir() or not _is_ours(folder):
        return
    for p in [*folder.glob(PART_GLOB), *folder.glob(".part-*.tmp"), *folder.glob(SHARE_GLOB), *folder.glob(".share-*.tmp")]:
        if p.is_file() and not p.is_symlink():
            p.unlink()
    with contextlib.suppress(OSError):  # something a user put here stays, with the folder and marker
        if not any(p.name != MARKER for p in folder.iterdir()):
            (folder / MARKER).unlink()
            folder.rmdir()


def _open_lock(path: Path, what: str) -> int:
    try:
        return os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise errors.ValidationError(what, str(path), f"{path} is a symlink; hairlut does not follow it") from None
        raise


def _same_file(fd: int, path: Path) -> bool:
    """Whether the locked descriptor is still the file at ``path`` (a releaser or prune may have unlinked it)."""
    try:
        st = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return False
    mine = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (mine.st_dev, mine.st_ino)


@contextlib.contextmanager
def lock_file(path, what: str = "out"):
    """Hold the advisory lock file ``path`` (flock; a symlink there is refused); yields whether it had to wait.

    The file exists only while someone holds or waits for it: the holder removes it on release, and a
    waiter that wakes on a removed file takes the lock again on the new one, so no lock files pile up
    beside outputs and two holders never hold different files of one name."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    waited = False
    while True:
        fd = _open_lock(path, what)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            waited = True
            fcntl.flock(fd, fcntl.LOCK_EX)
        if _same_file(fd, path):
            break
        os.close(fd)
    try:
        yield waited
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)  # while still held: a waiter on this file sees it gone and retries
        os.close(fd)  # closing releases the lock


def remove_if_unused(path, dry_run: bool = False) -> bool:
    """Remove the lock file ``path`` when nobody holds it (a leftover of a killed process); whether it was (would be)."""
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        return False
    try:
        fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW)
    except OSError:
        return False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False  # held: a bake is running
        if not _same_file(fd, path):
            return False
        if not dry_run:
            os.unlink(path)
        return True
    finally:
        os.close(fd)


def lock_path(out, suffix: str = "") -> Path:
    out = Path(out)
    return out.with_name(out.name + ".parts.lock" + suffix)


@contextlib.contextmanager
def locked(out, suffix: str = ""):
    """Hold ``<out>.parts.lock<suffix>`` (:func:`lock_file`); yields whether it had to wait."""
    with lock_file(lock_path(out, suffix), "out") as waited:
        yield waited


# ----------------------------------------------------------------------------- share indexes


def share_name(index: int, count: int) -> str:
    return f"share-{index:05d}-of-{count:05d}.npz"


def stamp(path) -> np.ndarray:
    """(inode, size, mtime in ns) of a file: a part replaced or rewritten since it was indexed differs."""
    st = os.stat(path, follow_symlinks=False)
    return np.array([st.st_ino, st.st_size, st.st_mtime_ns], np.int64)


def write_share(path, digest: str, total: int, blocks: dict) -> Path:
    """Write (atomically) one process's share index: ``blocks`` maps (start, stop) to (stamp, index dict).

    The leader of a virtual bake reads these (:func:`read_share`) instead of opening every part: one
    file per process, whatever the part count.  Each key of the index dicts is stored once, the blocks'
    arrays joined along their first axis, with each block's length."""
    spans = sorted(blocks)
    keys = sorted(blocks[spans[0]][1]) if spans else []
    arrays = {
        "spans": np.array(spans, np.int64).reshape(-1, 2),
        "stamps": np.array([blocks[b][0] for b in spans], np.int64).reshape(-1, 3),
        "head": np.array([digest, str(int(total)), json.dumps(keys)]),
    }
    for i, k in enumerate(keys):
        parts = [np.asarray(blocks[b][1][k]) for b in spans]
        arrays[f"rows{i}"] = np.array([len(a) for a in parts], np.int64)
        arrays[f"data{i}"] = np.concatenate(parts)
    with atomic_path(path) as tmp:
        with open(tmp, "xb") as fh:
            np.savez(fh, **arrays)
    return Path(path)


def read_share(path, digest: str, total: int, block: int, folder: Path) -> dict:
    """{(start, stop): index dict} of the blocks of a share index whose parts are unchanged since they were
    indexed (same inode, size and mtime) and which matches this recipe hash and unit count; {} for a missing
    or foreign share index, or one that is not a regular file (the leader then opens those parts itself)."""
    try:
        with np.load(regular_file(path, "a share index"), allow_pickle=False) as z:
            head = [str(x) for x in z["head"]]
            if head[:2] != [digest, str(int(total))]:
                return {}
            keys = json.loads(head[2])
            spans, stamps = z["spans"], z["stamps"]
            split = {}
            for i, k in enumerate(keys):
                rows = z[f"rows{i}"]
                split[k] = np.split(z[f"data{i}"], np.cumsum(rows)[:-1]) if len(rows) else []
    except (OSError, KeyError, ValueError, IndexError, errors.AssetError):
        return {}
    got = {}
    for j, ((s, e), st) in enumerate(zip(spans.tolist(), stamps)):
        try:
            if np.array_equal(stamp(folder / part_name(s, e, total, block)), st):
                got[(s, e)] = {k: split[k][j] for k in keys}
        except (OSError, errors.ValidationError):
            continue
    return got
