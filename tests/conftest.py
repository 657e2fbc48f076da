import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# JIT compiles make first examples slow, so no per-example deadline; CI replays a fixed
# set of examples (derandomized) so that a red run can be reproduced exactly.
settings.register_profile("dev", deadline=None)
settings.register_profile("ci", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

ROOT = Path(__file__).resolve().parents[1]

_OWN_XLA_CACHE = None


def pytest_configure(config):
    """One persistent XLA compilation cache for the whole test session, in a fresh temporary folder.

    Many tests build the same kernels again (a new ``jax.jit`` of the same function and shapes, a CLI
    subprocess, a forked bake): with the cache they load the compiled code instead of compiling it once
    more. The folder is new for each session, so nothing is read from a developer's ``~/.cache`` and a
    test never depends on an earlier run; subprocesses (``hairlut ...``) inherit it through
    ``JAX_COMPILATION_CACHE_DIR``, which ``hairlut_cli.main`` honours. ``HAIRLUT_TEST_XLA_CACHE=0`` turns
    it off (to measure what it saves). A pytest-xdist worker finds the variable set by the controller
    and shares its folder."""
    global _OWN_XLA_CACHE
    if os.environ.get("HAIRLUT_TEST_XLA_CACHE", "1") == "0":
        return
    if not os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        _OWN_XLA_CACHE = tempfile.mkdtemp(prefix="hairlut-test-xla-")
        os.environ["JAX_COMPILATION_CACHE_DIR"] = _OWN_XLA_CACHE
    import jax

    jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
    jax.config.update(
        "jax_persistent_cache_min_compile_time_secs", 0.2
    )  # hairlut_cli.main keeps every kernel (0); in-process tests keep the slower ones only


def pytest_unconfigure(config):
    if _OWN_XLA_CACHE is not None:
        shutil.rmtree(_OWN_XLA_CACHE, ignore_errors=True)
        os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)


#: The costliest test files first, by the CPU seconds measured per file (HAIRLUT_TEST_CPU_LOG, below, then
#: ``awk -F'\t' '{split($1, f, "::"); c[f[1]] += $3} END {for (k in c) print c[k], k}' LOG | sort -nr``).
#: Under pytest-xdist (``run.py test``: ``--dist loadfile --no-loadscope-reorder``) each file runs whole on one worker
#: and the workers take files in collection order, so the long files start first and the short ones fill in at the
#: end (longest-processing-time-first): the two workers end together instead of one waiting on a long file that
#: started last.  Only the order changes: every test still runs, and a file's own tests keep their order.
#: Measured on the loaded 2-core machine (load 3-30; file CPU seconds, some files only partly run): hostile_bitflips
#: 206, hostile_limits 172, distributed_bake 140, scale_devices 127, render_layered 105, direct_maps 72, reliability
#: 66, render_strands 62, plan 57, scale_faults 48, cli 47, env_bands 34, map_methods 33, bench_shadows 30, fit 28,
#: parts_features 20, satf_projection 19, bench 19, opacity_maps 15, atomic 14, density 10, cache 9; the other files
#: measured, under 5.  Not measured (time ran out): test_synth_track_reads.py (160-420 s of wall time in earlier
#: whole runs, so first), the hrir_*, kernels, light_oriented, sh_*, shadow*, stress*, synth_* (but track_reads),
#: validate, view_grid, xarray files: a file listed here or not still runs, only perhaps later than it should.
COSTLIEST_FIRST = (
    "test_packaging.py",  # its slow test builds a wheel and runs `hairlut bench --quick` from it
    "test_grooms.py",  # its slow tests plan, bake, render and compare three generated grooms (~140 s)
    "test_synth_track_reads.py",
    "test_hostile_bitflips.py",
    "test_hostile_limits.py",
    "test_distributed_bake.py",
    "test_scale_devices.py",
    "test_render_layered.py",
    "test_direct_maps.py",
    "test_reliability.py",
    "test_render_strands.py",
    "test_plan.py",
    "test_scale_faults.py",
    "test_cli.py",
    "test_env_bands.py",
    "test_map_methods.py",
    "test_bench_shadows.py",
    "test_fit.py",
    "test_parts_features.py",
    "test_satf_projection.py",
    "test_bench.py",
    "test_opacity_maps.py",
    "test_atomic.py",
    "test_density.py",
    "test_cache.py",
)


def pytest_collection_modifyitems(config, items):
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return  # one process: the order does not change the time
    rank = {name: i for i, name in enumerate(COSTLIEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest keep their order


GROOMS = ROOT / "tables" / "grooms"  # the example grooms kept in the repository (tables/grooms/README.md)


def groom_path(name: str) -> Path:
    """An example groom in tables/grooms/ (``sintel_lite.tfx``, ``ratboy_mohawk.tfx``).  They are
    part of the repository, so a missing one is a broken checkout: fail, never skip."""
    path = GROOMS / name
    if not path.is_file():
        raise FileNotFoundError(f"{path}: the example grooms are committed in tables/grooms/; the checkout is incomplete")
    return path


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture
def hairlut_exe() -> str:
    exe = Path(sys.executable).with_name("hairlut")
    if not exe.exists():
        pytest.skip(f"console script not installed beside {sys.executable}")
    return str(exe)


_CPU_LOG = os.environ.get("HAIRLUT_TEST_CPU_LOG")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """With HAIRLUT_TEST_CPU_LOG=PATH, append per test (setup + call + teardown) its wall time and the
    CPU seconds it used, this process's and its children's (subprocesses it waited for), as
    tab-separated lines: on a machine shared with other work, CPU time is the measure that holds."""
    if not _CPU_LOG:
        yield
        return
    import resource
    import time

    def cpu():
        return (
            time.process_time()
            + resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
            + resource.getrusage(resource.RUSAGE_CHILDREN).ru_stime
        )

    wall0, cpu0 = time.perf_counter(), cpu()
    yield
    wall, used = time.perf_counter() - wall0, cpu() - cpu0
    with open(_CPU_LOG, "a") as f:
        f.write(f"{item.nodeid}\t{wall:.3f}\t{used:.3f}\t{os.getloadavg()[0]:.2f}\n")
