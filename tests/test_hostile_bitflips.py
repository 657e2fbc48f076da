"""Hostile HDF5 files, issue 14 item 1: every flipped metadata bit gives a typed error, never a crash of the
reader's process (each flip read in a forked child; ``test_hostile_files`` has items 2–5)."""

import json
import os
import select
import signal
import time
import traceback

import pytest

from hairlut import errors
from hairlut.assets import read_table, summarize
from hairlut.hrir import load_hrir_db
from hairlut.shtables import SHTables

from ._hostile import cli_fails, copy, hrir_file, sh_file  # noqa: F401  (module fixtures)
from ._tables import lobes_table

# ----------------------------------------------------------------------------- item 1: flipped metadata bits


CHILD_SECONDS = 5  # per offset: a child that computes this long (CPU seconds) without a result is stuck in HDF5
CHILD_WALL_SECONDS = 60  # ... or that reports nothing for this long at all (a loaded machine slows every child)


def _cpu_seconds(pid):
    """CPU time a child has used (Linux /proc); None where that cannot be read."""
    try:
        fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


BATCH = 64  # offsets per forked child; a fork of the test process costs more than reading one small file


def _child(raw, probe_dir, offs, readers, w):  # pragma: no cover (runs in the forked child)
    """Read each flipped file in turn, writing one JSON line of outcomes per offset as soon as it is known."""
    import gc

    gc.freeze()  # the parent's heap is never collected here: no copy-on-write of it, no time spent on it
    for off in offs:
        b = bytearray(raw)
        b[off] ^= 0xFF
        probe = probe_dir / f"flipped-{off}.h5"  # a name of its own: no open handle of an earlier probe aliases it
        probe.write_bytes(bytes(b))
        res = []
        for fn in readers:
            try:
                fn(probe)
                res.append("ok")
            except errors.HairlutError:
                res.append("typed")
            except BaseException as exc:
                res.append("".join(traceback.format_exception_only(exc)).strip()[-300:])
        probe.unlink()
        os.write(w, (json.dumps([off, res]) + "\n").encode())
    os._exit(0)


def _stuck(pid, since, cpu_then):
    """No result for CHILD_SECONDS of the child's own CPU time (wall time where /proc is missing), or for
    CHILD_WALL_SECONDS of wall time: on a loaded machine a slow child is not taken for a hang."""
    waited = time.monotonic() - since
    cpu_now = _cpu_seconds(pid)
    if cpu_then is None or cpu_now is None:
        return waited > CHILD_SECONDS
    return cpu_now - cpu_then > CHILD_SECONDS or waited > CHILD_WALL_SECONDS


def _run_child(raw, probe_dir, offs, readers):
    """Fork one child for ``offs``; return ({offset: outcomes} it reported, the offset it died or hung at, how)."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover (child)
        os.close(r)
        _child(raw, probe_dir, offs, readers, w)
    os.close(w)
    got, buf, fail = {}, b"", None
    last, last_cpu = time.monotonic(), _cpu_seconds(pid)
    while True:
        ready, _, _ = select.select([r], [], [], 0.05)
        if ready:
            chunk = os.read(r, 65536)
            if not chunk:
                break  # the child exited, or died
            buf += chunk
            *lines, buf = buf.split(b"\n")
            for line in lines:
                off, res = json.loads(line)
                got[off] = res
            last, last_cpu = time.monotonic(), _cpu_seconds(pid)
        elif _stuck(pid, last, last_cpu):
            os.kill(pid, signal.SIGKILL)
            fail = "hang"
            break
    os.close(r)
    os.waitpid(pid, 0)
    if len(got) < len(offs) and fail is None:
        fail = "native crash"
    return got, (offs[len(got)] if fail else None), fail


def _outcomes_of_flips(path, readers, step, offsets=None):
    """Flip one byte at every ``step``-th offset and read the file with each reader, in forked children (HDF5
    itself may crash or loop). Each outcome is the one a child of its own per offset gives: a child reads
    BATCH flipped files in turn, and where it crashes or hangs, that offset is read again alone in a fresh
    child (so a crash is never blamed on the wrong offset) and the rest of the batch goes on in another."""
    raw = bytes(path.read_bytes())
    probe_dir = path.parent
    todo = list(range(0, len(raw), step) if offsets is None else offsets)
    outcomes = {}
    while todo:
        batch, todo = todo[:BATCH], todo[BATCH:]
        got, bad, how = _run_child(raw, probe_dir, batch, readers)
        outcomes.update({int(k): v for k, v in got.items()})
        if bad is not None:
            alone, _, how_alone = _run_child(raw, probe_dir, [bad], readers) if len(got) else (got, None, how)
            outcomes[bad] = alone[bad] if bad in alone else [how_alone] * len(readers)
            todo = batch[len(got) + 1 :] + todo
    return {off: outcomes[off] for off in sorted(outcomes)}


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
@pytest.mark.parametrize(
    "which, step",
    [
        ("table", 211),
        ("sh", 97),
        ("hrir", 397),
        # denser sweeps, in CI: every 5th, 3rd and 3rd offset of the full sweeps (steps 11, 13, 41) once measured
        # offline with 0 untyped outcomes; the full sweeps take ~20 minutes on 2 cores
        pytest.param("table", 55, marks=pytest.mark.slow),
        pytest.param("sh", 39, marks=pytest.mark.slow),
        pytest.param("hrir", 123, marks=pytest.mark.slow),
    ],
)
def test_flipped_metadata_bits_give_typed_errors(tmp_path, which, step, sh_file, hrir_file):
    """Every flip that HDF5 survives gives ok or a hairlut error: no KeyError, OSError, ValueError ... tracebacks.

    A few flips make the HDF5 C library itself crash (double free) or loop while it
    reads a variable-length attribute; no Python code can catch those (see
    hairlut.assets.trust), so they are only counted and kept rare here."""
    if which == "table":
        path, readers = lobes_table(tmp_path / "t.h5")[0], (read_table, summarize)
    elif which == "sh":
        path, readers = copy(sh_file, tmp_path / "sh.h5"), (SHTables.load, summarize)
    else:
        path, readers = copy(hrir_file, tmp_path / "db.h5"), (load_hrir_db,)
    outcomes = _outcomes_of_flips(path, readers, step)
    native = ("native crash", "hang")
    untyped = {off: r for off, res in outcomes.items() for r in res if r not in ("ok", "typed", *native)}
    assert not untyped, untyped
    typed = sum(r == "typed" for res in outcomes.values() for r in res)
    lost = sum(res[0] in native for res in outcomes.values())
    assert typed > len(outcomes) // 10  # the sweep does reach metadata
    assert lost <= max(2, len(outcomes) // 50)  # HDF5's own crashes and loops stay rare


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_metadata_fault_is_one_line_at_the_cli(tmp_path):
    path = lobes_table(tmp_path / "t.h5")[0]
    raw = bytearray(path.read_bytes())
    near = raw.find(b"specular")  # the root group's link names the object; flips around it break metadata
    assert near > 0
    outcomes = _outcomes_of_flips(path, (summarize,), 1, range(max(0, near - 48), near + 48))
    typed = [off for off, res in outcomes.items() if res == ["typed"]]
    assert typed, outcomes
    for off in typed[:3]:
        b = bytearray(raw)
        b[off] ^= 0xFF
        bad = tmp_path / f"flip{off}.h5"
        bad.write_bytes(bytes(b))
        assert str(bad) in cli_fails("inspect", "--json", bad)
