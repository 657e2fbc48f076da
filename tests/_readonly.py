"""A folder this process cannot write, for the output checks: chmod 555, or, for root (whom permissions do not
stop), a read-only tmpfs mounted over it; skipped where neither works."""

import os
import subprocess

import pytest


@pytest.fixture
def read_only_dir(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    mounted = False
    if os.access(d, os.W_OK):
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(d)], capture_output=True)
        mounted = r.returncode == 0
        if not mounted:
            d.chmod(0o755)
            pytest.skip("permissions do not stop this user and no read-only file system can be mounted here")
    try:
        yield d
    finally:
        if mounted:
            subprocess.run(["umount", str(d)], check=True)
        d.chmod(0o755)
