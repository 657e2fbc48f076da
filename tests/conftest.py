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


def shared_dir() -> Path:
    """The shared/ folder beside the checkout (or $HAIRLUT_SHARED)."""
    return Path(os.environ.get("HAIRLUT_SHARED", ROOT.parent / "shared"))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture
def hairlut_exe() -> str:
    exe = Path(sys.executable).with_name("hairlut")
    if not exe.exists():
        pytest.skip(f"console script not installed beside {sys.executable}")
    return str(exe)
