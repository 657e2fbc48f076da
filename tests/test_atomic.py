"""A writer killed at any moment leaves the old complete file or none, never a partial one."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from hairlut.assets import atomic_path, read_exr, read_table, stale_temporaries

from . import _tables  # noqa: F401  (declares the test kind kk_lobes)
from ._readonly import read_only_dir  # noqa: F401  (a fixture)

WRITER = textwrap.dedent(
    """
    import sys, numpy as np
    from hairlut.assets import Axis, Variable, register_kind, write_exr, write_table
    register_kind("kk_lobes", ("diffuse", "specular"), "Kajiya-Kay diffuse and specular kernels sampled on (theta, theta') grids")
    path, fmt = sys.argv[1], sys.argv[2]
    seed = 0
    while True:
        seed += 1
        data = np.random.default_rng(seed).random((64, 256, 256)).astype(np.float32)
        if fmt == "h5":
            axes = [Axis("p", np.arange(64.0), "1", "p"), Axis("theta", np.arange(256.0), "rad", "t"),
                    Axis("theta_v", np.arange(256.0), "rad", "v")]
            write_table(path, "kk_lobes", {"seed": seed}, axes,
                        [Variable("diffuse", data[0, 0], ("theta",), "1", "d"),
                         Variable("specular", data, ("p", "theta", "theta_v"), "1", "s")])
        else:
            write_exr(path, {f"l{i}.Y": data[i] for i in range(16)}, recipe={"seed": seed})
        print(seed, flush=True)
    """
)


def _check(path, fmt):
    if fmt == "h5":
        t = read_table(path)
        seed = t.recipe["seed"]
        expect = np.random.default_rng(seed).random((64, 256, 256)).astype(np.float32)
        np.testing.assert_array_equal(t["specular"], expect)
    else:
        im = read_exr(path)
        seed = im.recipe["seed"]
        expect = np.random.default_rng(seed).random((64, 256, 256)).astype(np.float32)
        np.testing.assert_array_equal(im.channel("l3.Y"), expect[3])
    return seed


@pytest.mark.parametrize("fmt", ["h5", "exr"])
def test_sigkill_never_leaves_a_partial_file(tmp_path, fmt):
    path = tmp_path / f"table.{fmt}"
    rng = np.random.default_rng(7)
    seen_complete = 0
    for attempt in range(6):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(path), fmt], stdout=subprocess.PIPE, text=True)
        if attempt == 0:  # one writer completes a file first (however slow its start), so the check is not vacuous
            proc.stdout.readline()
        time.sleep(float(rng.uniform(0.3, 2.5)))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if path.exists():
            _check(path, fmt)
            seen_complete += 1
        for tmp in stale_temporaries(tmp_path):
            tmp.unlink()
    assert seen_complete > 0, "the writer never completed a file; the test proved nothing"


def test_failed_body_leaves_target_untouched(tmp_path):
    target = tmp_path / "x.bin"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_bytes(b"new partial")
            raise RuntimeError("boom")
    assert target.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["x.bin"]


def test_check_writable_refuses_what_cannot_be_written_and_creates_nothing(tmp_path, read_only_dir):
    """Issue 29 m5: an output that cannot be written is refused before any work, naming the user's path (a
    render computed its whole frame, then named its hidden temporary file)."""
    from hairlut import errors
    from hairlut.atomic import atomic_write_bytes, check_writable

    for target, folder in (
        (read_only_dir / "r.exr", False),
        (read_only_dir / "a" / "b" / "r.exr", False),
        (read_only_dir / "out", True),
    ):
        with pytest.raises(errors.AssetError, match="cannot write") as exc:
            check_writable(target, folder=folder)
        assert exc.value.path == str(target) and str(read_only_dir) in str(exc.value)
    with pytest.raises(errors.AssetError) as exc:  # the write itself, past the check, names the user's file too
        atomic_write_bytes(read_only_dir / "r.png", b"x")
    assert exc.value.path == str(read_only_dir / "r.png") and ".tmp" not in str(exc.value)
    (tmp_path / "file").write_bytes(b"")
    for target, folder, words in (
        (tmp_path / "file" / "r.exr", False, "is a file, not a folder"),
        (tmp_path, False, "is a folder"),
        (tmp_path / "file", True, "is a file"),
    ):
        with pytest.raises(errors.AssetError, match=words):
            check_writable(target, folder=folder)
    fresh = tmp_path / "new" / "deeper" / "r.exr"
    assert check_writable(fresh) == fresh and check_writable(tmp_path / "new2", folder=True) == tmp_path / "new2"
    assert not (tmp_path / "new").exists() and not (tmp_path / "new2").exists()
    assert sorted(os.listdir(tmp_path)) == ["file", "ro"] and os.listdir(read_only_dir) == []
