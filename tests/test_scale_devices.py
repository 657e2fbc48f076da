"""Every kind in the registry bakes the same data on 1 and 2 local devices (JAX_NUM_CPU_DEVICES, set before JAX
starts, so each bake runs in its own process)."""

import os
import subprocess
import sys

import pytest

from hairlut.bake import registry

from .test_distributed_bake import _assert_same_data

BAKE = """
import sys
import jax
from hairlut.bake import registry
from tests.test_distributed_bake import split_cases

kind, out = sys.argv[1], sys.argv[2]
recipe, options, _ = split_cases()[kind]
assert len(jax.local_devices()) == int(sys.argv[3])
registry.bake(kind, recipe, out, options=options)
"""


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(registry.kinds()))
def test_one_and_two_local_devices_bake_the_same_data(kind, tmp_path):
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for d in (1, 2):
        env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(d)}
        run = subprocess.run(
            [sys.executable, "-c", BAKE, kind, str(tmp_path / f"d{d}.h5"), str(d)],
            cwd=root,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert run.returncode == 0, run.stderr[-2000:]
    _assert_same_data(tmp_path / "d1.h5", tmp_path / "d2.h5")


DIST = """
import sys
from hairlut.bake import registry
from hairlut.bake.devices import initialize
from tests.test_distributed_bake import split_cases

kind, out, port, k = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
proc = initialize(f"127.0.0.1:{port}", 2, k)  # first, as the CLI does: the scene recipe's grid choice runs JAX
recipe, options, _ = split_cases()[kind]
rep = registry.bake(kind, recipe, out, options=options, distributed=proc)
print("RANGE", *rep["unit_range"])
"""


@pytest.mark.slow
def test_two_processes_on_loopback_bake_the_scene_table_of_one(tmp_path):
    from hairlut.assets.parts import parts_dir
    from hairlut.assets.virtual_write import check_virtual

    from .test_distributed_bake import _free_port, split_cases

    recipe, options, _ = split_cases()["scene_maps"]
    one = registry.bake("scene_maps", recipe, tmp_path / "one.h5", options=options)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": "2"}
    port, out = _free_port(), tmp_path / "maps.h5"
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", DIST, "scene_maps", str(out), str(port), str(k)],
            cwd=root,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for k in range(2)
    ]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-2000:] for o in outs]
    ranges = [next(line.split()[1:] for line in o[0].splitlines() if line.startswith("RANGE")) for o in outs]
    assert ranges == [["0", "48"], ["48", "80"]]  # 4 blocks of 24 rows (80 live sectors): two each
    _assert_same_data(one["out"], out)
    assert len(check_virtual(out)) == len(list(parts_dir(out).glob("part-*.h5"))) == 4
    registry.get("scene_maps").load(out)
