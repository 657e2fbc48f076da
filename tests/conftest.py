import os
import sys
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
