"""Readers take a virtual asset's tables from its checked parts directly (``hairlut.assets.virtual.read_virtual``, issue
16): the same bytes as a ``--merge copy`` asset of the same bake, and the same named errors for a missing part."""

import os

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets import h5 as store
from hairlut.assets import read_table, summarize
from hairlut.assets.layout import layout
from hairlut.assets.parts import parts_dir
from hairlut.hrir import bake, load_hrir_db
from hairlut_cli.main import cli

SMALL = {"sectors": {"count": 12, "grid": [8, 8]}, "angles": {"views": 3, "lights": 2}, "trace": {"pixels": 4, "steps": 4}}


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    where = tmp_path_factory.mktemp("vread")
    virtual, copy = where / "virtual.h5", where / "copy.h5"
    bake(SMALL, virtual, block=5, merge="virtual")  # blocks of 5, 5 and a last one of 2
    bake(SMALL, copy, block=5, merge="copy")
    return virtual, copy


def _virtual_tables(path) -> set:
    with h5py.File(path, "r") as f:
        return {name for name, ds in layout(f)[1].items() if ds.is_virtual}


def test_every_virtual_table_is_read_from_its_parts_and_equals_the_copy_bit_for_bit(assets, monkeypatch):
    virtual, copy = assets
    direct = []
    real = store.read_virtual
    monkeypatch.setattr(store, "read_virtual", lambda *a: (lambda got: (direct.extend(got), got)[1])(real(*a)))
    a, b = read_table(virtual, kind="hrir_db"), read_table(copy, kind="hrir_db")
    names = _virtual_tables(virtual)
    assert len(names) >= 20 and set(direct) == names  # none left for HDF5's virtual read
    assert not _virtual_tables(copy) and sorted(a.variables) == sorted(b.variables)
    for name in a.variables:
        x, y = a[name], b[name]
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name
        assert a.variables[name].dims == b.variables[name].dims, name
    with h5py.File(virtual, "r") as f:  # and what HDF5's own virtual read gives
        for name, ds in layout(f)[1].items():
            assert ds[()].tobytes() == a[name].tobytes(), name
    da, db = load_hrir_db(virtual), load_hrir_db(copy)
    for field in ("features", "alpha", "reflectance", "density"):
        assert getattr(da, field).tobytes() == getattr(db, field).tobytes(), field


def test_a_part_deleted_after_the_checks_were_cached_is_still_named(assets, tmp_path):
    virtual, _ = assets
    out = tmp_path / "db.h5"
    bake(SMALL, out, block=5, merge="virtual")
    load_hrir_db(out)  # every part checked and remembered by its stamp
    part = sorted(parts_dir(out).glob("part-*.h5"))[1]
    with store.open_table(out, kind="hrir_db") as f:  # checked with the part there, which goes before the read
        part.unlink()
        with pytest.raises(errors.AssetNotFoundError) as exc:
            store.read_virtual(out, f, layout(f)[1])
    assert exc.value.path == str(part) and "missing" in str(exc.value)
    with pytest.raises(errors.AssetNotFoundError) as exc:
        load_hrir_db(out)
    assert exc.value.path == str(part)
    with pytest.raises(errors.ForeignReferenceError, match=f"{part.name}:alpha, which does not exist"):
        read_table(out, kind="hrir_db")


def test_a_part_changed_between_its_check_and_the_read_is_not_read(tmp_path):
    out = tmp_path / "db.h5"
    bake(SMALL, out, block=5, merge="virtual")
    part = sorted(parts_dir(out).glob("part-*.h5"))[0]
    with store.open_table(out, kind="hrir_db") as f:
        st = part.stat()
        os.utime(part, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))  # another stamp: maybe other contents
        with pytest.raises(errors.CorruptAssetError, match="changed since it was checked") as exc:
            store.read_virtual(out, f, layout(f)[1])
    assert exc.value.path == str(part)
    assert read_table(out, kind="hrir_db")["alpha"].shape[0] == 12  # opened again: checked with its new stamp


def test_a_flipped_chunk_byte_in_a_part_fails_its_checksum_naming_the_part(tmp_path):
    out = tmp_path / "db.h5"
    bake(SMALL, out, block=5, merge="virtual")
    part = sorted(parts_dir(out).glob("part-*.h5"))[0]
    with h5py.File(part, "r") as f:
        chunk = f["density"].id.get_chunk_info(0)
    raw = bytearray(part.read_bytes())
    raw[chunk.byte_offset + chunk.size // 2] ^= 0x10
    part.write_bytes(bytes(raw))
    with pytest.raises(errors.ChecksumError) as exc:
        read_table(out, kind="hrir_db")
    assert exc.value.path == str(part) and "'density'" in str(exc.value) and "fletcher32" in str(exc.value)
    with pytest.raises(errors.ChecksumError) as exc:  # issue 29 m8: inspect named neither the part nor the checksum
        summarize(out)
    assert exc.value.path == str(part) and "'density'" in str(exc.value) and "fletcher32" in str(exc.value)
    res = CliRunner().invoke(cli, ["inspect", str(out)])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1
    assert str(part) in res.output and "'density' fails its fletcher32 checksum" in res.output


def test_inspect_reads_a_virtual_table_part_by_part_with_the_figures_of_hdf5s_own_read(assets):
    virtual, _ = assets
    got = {d["name"]: d for d in summarize(virtual)["datasets"]}
    with h5py.File(virtual, "r") as f:
        for name, ds in layout(f)[1].items():
            data = ds[()].astype(np.float64)
            assert got[name]["count"] == data.size, name
            assert (got[name]["min"], got[name]["max"]) == (float(np.min(data)), float(np.max(data))), name


def test_a_table_hdf5_must_fill_is_left_to_hdf5(tmp_path):
    """A mapping that leaves rows to the fill value is not read from the parts: HDF5 reads it, fill and all."""
    from ._tables import declare_rows, lobes_table

    path = lobes_table(tmp_path / "t.h5")[0]
    (tmp_path / "t.h5.parts").mkdir()
    part = lobes_table(tmp_path / "t.h5.parts" / "part-0.h5")[0]
    with h5py.File(part, "r") as f:
        spec = f["specular"][()]
    declare_rows(part, 0, spec.shape[0])
    with h5py.File(path, "r+") as f:
        lay = h5py.VirtualLayout(shape=(spec.shape[0] + 3, *spec.shape[1:]), dtype=spec.dtype)
        lay[: spec.shape[0]] = h5py.VirtualSource("t.h5.parts/part-0.h5", "specular", shape=spec.shape)
        f.create_virtual_dataset("ext", lay, fillvalue=7).dims[0].label = "exponent"
    with store.open_table(path) as f:
        assert store.read_virtual(path, f, layout(f)[1]) == {}
    got = read_table(path)["ext"]
    assert got[: spec.shape[0]].tobytes() == spec.tobytes() and np.all(got[spec.shape[0] :] == 7)
