"""A distributed bake's failures end as hairlut failures: one line on stderr naming this process, the peer and the
cause, exit status 2, never JAX's SIGABRT (status 134) or a C++ stack trace as the last word; and a rerun resumes.

Each case runs real `hairlut bake hrir --distributed` processes on loopback (issue 29: N4, N5, N6, m13)."""

import os
import signal
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner

from hairlut.assets.parts import parts_dir
from hairlut_cli.main import cli

from .test_distributed_bake import CODE, _assert_same_data, _env, _free_port

RECIPE = [
    "--set",
    "sectors.count=12",
    "--set",
    "sectors.grid=[8, 8]",
    "--set",
    "angles.views=4",
    "--set",
    "angles.lights=3",
    "--set",
    "trace.pixels=8",
    "--set",
    "trace.steps=12",
]


def _start(out, port, k, n=2, *extra, timeout=60):
    """Process ``k`` of ``n`` of a small HRIR bake into ``out`` (one CPU device each)."""
    cmd = [
        sys.executable,
        "-c",
        CODE,
        "bake",
        "hrir",
        *RECIPE,
        "--out",
        str(out),
        "--no-progress",
        "--distributed",
        "--coordinator",
        f"127.0.0.1:{port}",
        "--num-processes",
        str(n),
        "--process-id",
        str(k),
        "--timeout",
        str(timeout),
        *extra,
    ]
    return subprocess.Popen(cmd, env=_env(1), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=str(out.parent))


def _end(proc, limit=240) -> tuple[int, str, str]:
    """(status, stdout, the last line of stderr), asserting that the last word is hairlut's."""
    out, err = proc.communicate(timeout=limit)
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines, f"status {proc.returncode}, no stderr"
    assert "Traceback" not in err, err[-3000:]
    return proc.returncode, out, lines[-1]


def _failed(proc, *words, limit=240) -> str:
    status, _, last = _end(proc, limit)
    assert status == 2 and last.startswith("hairlut: error: distributed: process "), (status, last)
    assert all(w in last for w in words), last
    return last


def test_timeout_goes_with_distributed_and_is_documented(tmp_path):
    res = CliRunner().invoke(cli, ["bake", "hrir", "--out", str(tmp_path / "x.h5"), "--timeout", "5"])
    assert res.exit_code == 2 and "--timeout go with --distributed" in res.output
    res = CliRunner().invoke(cli, ["bake", "hrir", "--help"])
    assert res.exit_code == 0 and "--timeout SECONDS" in res.output and "[default: 120]" in res.output


def test_a_peer_that_never_comes(tmp_path):
    """N5: a lone process 0 and a lone process 1 each give up after --timeout with one line, not SIGABRT."""
    out, port = tmp_path / "db.h5", _free_port()
    status, _, last = _end(_start(out, port, 0, timeout=3))
    at = f"127.0.0.1:{port}"
    assert status == 2 and last == (
        f"hairlut: error: distributed: process 0 of 2: process 1 did not join the coordinator "
        f"at {at} within 3 s (--timeout): start every process with --coordinator {at} "
        "--num-processes 2 and its own --process-id"
    )
    assert not parts_dir(out).exists()
    _failed(_start(out, _free_port(), 1, timeout=3), "process 1 of 2: no coordinator answered at", "within 3 s")
    assert not parts_dir(out).exists()


def test_a_process_id_given_twice(tmp_path):
    """N5: a second process 0 is refused before JAX starts (the port is taken); a second process 1 is refused by
    the claim, and the bake stops everywhere with lines that say why."""
    out, port = tmp_path / "db.h5", _free_port()
    first = _start(out, port, 0, timeout=8)
    time.sleep(1.0)
    _failed(_start(out, port, 0, timeout=8), "process 0 of 2: the coordinator's port", "is in use", "repeated --process-id 0")
    _failed(first, "process 0 of 2: process 1 did not join")
    port, extra = _free_port(), ("--set", "sectors.count=64", "--block", "2")
    procs = [_start(out, port, k, 2, *extra, timeout=30) for k in (0, 1)]
    _wait_for(parts_dir(out) / "part-64x2-16.h5", procs)  # process 1 has joined and bakes its share
    _failed(
        _start(out, port, 1, 2, *extra, timeout=30),
        f"process 1 of 2: process 1 was started twice: pid {procs[1].pid} on ",
        "joined first",
    )
    _failed(procs[0], "process 0 of 2: process 1 failed: process 1 was started twice")
    _failed(procs[1], "process 1 of 2: ")


def test_processes_that_disagree_are_refused_before_any_work(tmp_path):
    """N6: another recipe, another --out or another process count is refused at once on every process, naming
    the difference; nothing is baked."""
    out = tmp_path / "db.h5"
    port = _free_port()
    a, b = _start(out, port, 0), _start(out, port, 1, 2, "--set", "sectors.count=16")
    _failed(a, "process 0 of 2: process 1 bakes another recipe: sectors.count = 12 here, 16 at process 1")
    _failed(b, "process 1 of 2: process 0 bakes another recipe: sectors.count = 16 here, 12 at process 0")
    assert not parts_dir(out).exists()
    port = _free_port()
    a, b = _start(out, port, 0), _start(tmp_path / "other.h5", port, 1)
    _failed(a, f"--out is {out} here and {tmp_path / 'other.h5'} at process 1")
    _failed(b, f"--out is {tmp_path / 'other.h5'} here and {out} at process 0")
    port = _free_port()
    a, b = _start(out, port, 0), _start(out, port, 1, 3)
    _failed(a, "process 0 of 2: --num-processes is 2 here and 3 at process 1")
    _failed(b, "process 1 of 3: --num-processes is 3 here and 2 at process 0")
    assert not parts_dir(out).exists() and not (tmp_path / "other.h5.parts").exists()


def _wait_for(part, procs) -> None:
    """Until ``part`` (a path, or a callable that returns one that exists, or None) exists; all ``procs`` alive."""
    found = part if callable(part) else (lambda: part if part.exists() else None)
    deadline = time.time() + 180
    while time.time() < deadline and found() is None and all(p.poll() is None for p in procs):
        time.sleep(0.05)
    assert found() is not None, [p.poll() for p in procs]


def _kill_when(procs, victim: int, part) -> None:
    _wait_for(part, procs)
    os.kill(procs[victim].pid, signal.SIGKILL)
    procs[victim].wait()


@pytest.mark.slow
def test_a_killed_peer_ends_the_survivor_with_one_line_and_a_rerun_resumes(tmp_path):
    """N4: process 1 killed mid-bake: process 0 names it after --timeout; process 0 killed: process 1 names the
    lost coordinator at once.  Nothing is lost: the rerun resumes and equals a one-process bake, bit for bit; m13:
    process 1 says what it baked, not `wrote`."""
    out = tmp_path / "db.h5"
    extra = ("--set", "sectors.count=16", "--block", "2")
    port = _free_port()
    procs = [_start(out, port, k, 2, *extra, timeout=10) for k in range(2)]
    _kill_when(procs, 1, parts_dir(out) / "part-16x2-4.h5")  # process 1's first part (sectors 8..9)
    _failed(procs[0], "process 0 of 2: process 1 stopped answering", "no heartbeat for 10 s", "run every process again to resume")
    assert not out.exists()
    kept = {p.name for p in parts_dir(out).glob("part-*.h5")}
    port = _free_port()
    procs = [_start(out, port, k, 2, *extra, timeout=10) for k in range(2)]
    fresh = [parts_dir(out) / f"part-16x2-{b}{'-last' if b == 7 else ''}.h5" for b in range(4, 8)]  # process 1's
    _kill_when(procs, 0, lambda: next((p for p in fresh if p.name not in kept and p.exists()), None))
    _failed(procs[1], f"process 1 of 2: lost the coordinator: process 0 at 127.0.0.1:{port} is gone")
    assert not out.exists() and kept <= {p.name for p in parts_dir(out).glob("part-*.h5")}
    port = _free_port()
    procs = [_start(out, port, k, 2, *extra) for k in range(2)]
    done = [proc.communicate(timeout=240) for proc in procs]
    assert [p.returncode for p in procs] == [0, 0], [d[1][-2000:] for d in done]
    assert done[0][0].startswith(f"wrote {out} ") and "resumed" in done[0][0]
    line = done[1][0].strip()
    assert line.startswith("process 1 of 2: baked sectors 8..15 into ") and line.endswith(f"process 0 wrote {out}")
    assert "0 resumed" not in line  # process 1 kept its parts from before
    one = tmp_path / "one.h5"
    subprocess.run(
        [sys.executable, "-c", CODE, "bake", "hrir", *RECIPE, *extra, "--out", str(one), "--no-progress"],
        env=_env(1),
        check=True,
        capture_output=True,
    )
    _assert_same_data(one, out)
