"""The bake pipeline: the devices compute block i + 1 while the host writes block i; blocks sized by memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hairlut import errors
from hairlut.bake.devices import dispatch_units, map_units
from hairlut.bake.sharding import _bake_blocks
from hairlut.hrir import _bake, resolve_recipe


class Toy:
    """Units whose ``bake_part`` starts a block and returns the step that writes it, logging both."""

    def __init__(self, fail_launch=None, fail_finish=None, steps=True):
        self.log, self.fail_launch, self.fail_finish, self.steps = [], fail_launch, fail_finish, steps

    def bake_part(self, recipe, s, e, total, path, **_):
        if s == self.fail_launch:
            raise errors.NonFiniteError(f"launch {s}")
        self.log.append(("launch", s))

        def finish():
            if s == self.fail_finish:
                raise errors.NonFiniteError(f"finish {s}")
            Path(path).write_text(f"{s}-{e}")
            self.log.append(("write", s))

        if not self.steps:
            finish()
            return None
        return finish


def _run(tmp_path, units, n_blocks=3):
    todo = [(8 * i, 8 * i + 8) for i in range(n_blocks)]
    parts = [tmp_path / f"part-{s}-{e}" for s, e in todo]
    report, seen = {"computed": 0, "resumed": 0}, []
    _bake_blocks(units, {}, todo, parts, 8 * n_blocks, "hash", None, report, lambda d, t: seen.append((d, t)), 8 * n_blocks, {})
    return report, seen, parts


def test_next_block_starts_before_the_previous_is_written(tmp_path):
    units = Toy()
    report, seen, parts = _run(tmp_path, units)
    assert units.log == [("launch", 0), ("launch", 8), ("write", 0), ("launch", 16), ("write", 8), ("write", 16)]
    assert all(p.read_text() == f"{8 * i}-{8 * i + 8}" for i, p in enumerate(parts))
    assert report["computed"] == 24 and len(report["block_seconds"]) == len(report["block_cpu_seconds"]) == 3
    assert seen == [(0, 24), (8, 24), (16, 24), (24, 24)]  # first the resumed units (none), before any work


def test_a_part_that_writes_itself_is_not_pipelined(tmp_path):
    units = Toy(steps=False)
    report, seen, _ = _run(tmp_path, units)
    assert units.log == [("launch", 0), ("write", 0), ("launch", 8), ("write", 8), ("launch", 16), ("write", 16)]
    assert report["computed"] == 24 and seen[-1] == (24, 24)


def test_a_failed_launch_still_writes_the_block_before(tmp_path):
    units = Toy(fail_launch=16)
    with pytest.raises(errors.NonFiniteError, match="launch 16"):
        _run(tmp_path, units)
    assert [p.name for p in sorted(tmp_path.iterdir())] == ["part-0-8", "part-8-16"]  # a rerun resumes both


def test_a_failed_write_stops_the_bake_with_the_blocks_before_kept(tmp_path):
    units = Toy(fail_finish=8)
    with pytest.raises(errors.NonFiniteError, match="finish 8"):
        _run(tmp_path, units)
    assert [p.name for p in tmp_path.iterdir()] == ["part-0-8"]


def _square(x, *, k):
    return (x * x + k,)


def test_dispatch_then_gather_equals_map_units():
    x = np.arange(10, dtype=np.float32).reshape(5, 2)
    gather = dispatch_units(_square, (x,), micro=2, k=1.0)
    (got,) = gather()
    (want,) = map_units(_square, (x,), micro=2, k=1.0)
    assert got.tobytes() == want.tobytes() and np.array_equal(got, x * x + 1)


def test_blocks_sized_to_the_bake_and_the_memory(monkeypatch):
    assert _bake.auto_block(resolve_recipe({})) == 32  # the default database keeps its blocks
    big = resolve_recipe({"sectors": {"count": 16384}}, budget=False)
    monkeypatch.setattr(_bake, "free_memory", lambda: 140 * 2**30)
    assert _bake.auto_block(big) == 16384 // _bake.PIPELINE_BLOCKS  # 16 blocks of 1,024
    assert _bake.auto_block(big, shared=True) == _bake.BLOCK  # every process must cut the same blocks
    per_sector = 4 * (32 * 64 * 33 + 32 * 32 + 32)
    monkeypatch.setattr(_bake, "free_memory", lambda: 8 * 100 * per_sector)  # room for 100 sectors
    assert _bake.auto_block(big) == 96
    monkeypatch.setattr(_bake, "free_memory", lambda: 1)
    assert _bake.auto_block(big) == _bake.BLOCK
    odd = resolve_recipe({"sectors": {"count": 1000}}, budget=False)
    monkeypatch.setattr(_bake, "free_memory", lambda: None)  # a CPU: the host's budget
    assert _bake.auto_block(odd) == 64 and _bake.auto_block(odd) % _bake.BLOCK == 0
