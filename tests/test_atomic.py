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
