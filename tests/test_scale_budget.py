"""What one process of a split bake holds and reads.

The memory budget counts a block (virtual) or every unit (copy): estimates only, nothing here allocates the
production database.  The leader of a virtual bake indexes parts from the processes' share files."""

from __future__ import annotations

import pytest

from hairlut import budget, errors
from hairlut.bake import registry
from hairlut.bake.sharding import held

#: issue 16's production database: 65,536 sectors, 64 × 64 angles, 64 px, float16 (34.9 GB stored)
PRODUCTION = {
    "sectors": {"count": 65_536},
    "angles": {"views": 64, "lights": 64},
    "trace": {"pixels": 64},
    "storage": {"dtype": "float16"},
}
TABLES = 65_536 * 64 * 64 * 65 * 4  # α and reflectance of every sector as float32, what a copy holds (69.8 GB)


@pytest.fixture
def limit(monkeypatch):
    monkeypatch.setenv(budget.ENV, "8G")  # a modest machine's half: deterministic whatever runs the test
    return 8 << 30


def _prod():
    from hairlut.hrir import resolve_recipe

    return resolve_recipe(PRODUCTION)  # passes: a recipe alone holds one block


def test_production_recipe_resolves_without_a_raised_limit(monkeypatch):
    monkeypatch.delenv(budget.ENV, raising=False)
    if (budget.physical_memory() or budget.FALLBACK) < 4 << 30:
        pytest.skip("a machine under 4 GiB cannot hold even the production index")
    r = _prod()
    baker = registry.get("hrir_db")
    baker.units.budget(r, 32, *held(65_536, 32, 32, "virtual", None, True))  # the virtual leader: one block


def test_production_virtual_passes_and_copy_is_refused_with_the_figure(limit):
    r = _prod()
    baker = registry.get("hrir_db")
    total = 65_536
    for leader in (True, False):  # every process of a virtual bake holds one block, the leader too
        n, note = held(total, 32, total // 8, "virtual", None, leader)
        assert (n, note) == (32, "")
        baker.units.budget(r, 32, n, note)
    n, _ = held(total, 32, total // 8, "copy", None, False)  # a copy's other processes hold a block
    assert n == 32
    n, note = held(total, 32, total, "copy", None, True)  # the copy's leader holds every sector
    assert n == total
    with pytest.raises(errors.BudgetError) as info:
        baker.units.budget(r, 32, n, note)
    e = info.value
    assert e.field == "sectors.count" and e.value == total
    assert e.estimate == TABLES and e.limit == limit
    assert "65536 sectors" in str(e) and "--merge copy" in str(e) and "GiB" in str(e)


def test_block_and_shard_sizes_are_what_is_held(limit):
    r = _prod()
    baker = registry.get("hrir_db")
    block = 8 * 1024  # --block 8192: 8192 × 64 × 64 × 65 × 4 bytes = 8.7 GB of tables, over 8 GiB
    with pytest.raises(errors.BudgetError) as info:
        baker.units.budget(r, block, *held(65_536, block, 65_536 // 2, "virtual", None, True))
    assert info.value.estimate == block * 64 * 64 * 65 * 4 and info.value.field == "angles.views"
    n, note = held(65_536, 32, 2_048, "copy", "3/32", False)  # a --shard slice is joined into one file
    assert n == 2_048 and "--shard" in note
    baker.units.budget(r, 32, n, note)  # 2,048 sectors: 2.2 GB, under 8 GiB


def test_copy_bake_is_refused_before_anything_is_written(tmp_path, limit):
    out = tmp_path / "prod.h5"
    with pytest.raises(errors.BudgetError, match=r"sectors\.count=65536.*GiB.*--merge copy"):
        registry.bake("hrir_db", PRODUCTION, out, merge="copy")
    assert list(tmp_path.iterdir()) == []  # no parts folder, no lock: refused before the bake began


# ----------------------------------------------------------------------------- the leader's share files


def _data(path) -> dict:
    import h5py

    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: out.__setitem__(n, o[()].tobytes()) if isinstance(o, h5py.Dataset) else None)
    return out


def test_leader_assembles_from_share_files_and_falls_back_to_parts(tmp_path, monkeypatch):
    """A leader writes the same virtual asset from share files (opening none of the parts they cover) as from the
    parts themselves; a foreign share file, or a part rewritten since it was indexed, is read from the part."""
    from hairlut.assets import canonical_json, recipe_hash
    from hairlut.assets.parts import part_name, parts_dir, share_name, stamp, write_share
    from hairlut.bake.devices import Process
    from hairlut.bake.sharding import blocks_of, finish
    from hairlut.hrir import bake, resolve_recipe

    small = {"sectors": {"count": 12, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 8, "steps": 4}}
    out = tmp_path / "db.h5"
    bake(small, out, block=4, merge="virtual")  # one process: its indexes in memory
    reference = _data(out)
    r = resolve_recipe(small)
    baker = registry.get("hrir_db")
    folder, digest = parts_dir(out), recipe_hash(canonical_json(r))
    part = {b: folder / part_name(*b, 12, 4) for b in blocks_of(12, 4)}
    own = {b: (stamp(part[b]), baker.units.index(r, part[b])) for b in blocks_of(12, 4, (0, 2))}
    theirs = {b: (stamp(part[b]), baker.units.index(r, part[b])) for b in blocks_of(12, 4, (1, 2))}
    write_share(folder / share_name(1, 2), digest, 12, theirs)
    import hairlut.hrir._parts as hrir_parts

    opened = []
    real = hrir_parts.part_index  # what hrir_db's Units.index calls: count the parts the leader opens
    monkeypatch.setattr(hrir_parts, "part_index", lambda recipe, path: opened.append(path.name) or real(recipe, path))
    out.unlink()
    finish(baker, r, out, 12, 4, "virtual", Process(0, 2), own)
    assert opened == [] and _data(out) == reference  # every index from memory or the share file

    write_share(folder / share_name(1, 2), "0" * 64, 12, theirs)  # another recipe's share file: not used
    out.unlink()
    finish(baker, r, out, 12, 4, "virtual", Process(0, 2), own)
    assert opened == [part[b].name for b in blocks_of(12, 4, (1, 2))] and _data(out) == reference

    opened.clear()
    write_share(folder / share_name(1, 2), digest, 12, theirs)
    stale = next(iter(theirs))
    part[stale].write_bytes(part[stale].read_bytes())  # rewritten since indexed: a new inode and time
    out.unlink()
    finish(baker, r, out, 12, 4, "virtual", Process(0, 2), own)
    assert opened == [part[stale].name] and _data(out) == reference
