"""Virtual assets whose assembly does not grow with the part count (issue 16): one printf-style mapping
(``part-<total>x<block>-%b.h5``) over the whole blocks and one fixed mapping for the last block, per table."""

import os
import shutil
import subprocess

import h5py
import numpy as np
import pytest

from hairlut import errors
from hairlut.assets import Axis, Variable, read_table
from hairlut.assets.parts import open_folder, part_name, parts_dir, stamp
from hairlut.assets.virtual_write import check_virtual, write_virtual
from hairlut.hrir import bake, load_hrir_db

from ._tables import RECIPE, declare_rows, lobes_table

NT, NV = 3, 2


def _parts(out, total: int, block: int, recipe=RECIPE) -> tuple[list, np.ndarray]:
    """kk_lobes parts of ``block`` exponents each over ``total`` (the last one shorter): one table written, the
    others copies of it with their own rows (fast enough for 4,096 parts); returns (parts, the whole specular)."""
    folder = open_folder(out)
    whole = np.arange(total * NT * NV, dtype=np.float32).reshape(total, NT, NV)
    first = lobes_table(folder / "first.h5", recipe=recipe, size=(block, NT, NV))[0]
    parts = []
    for start in range(0, total, block):
        stop = min(start + block, total)
        path = folder / part_name(start, stop, total, block)
        if stop - start == block:
            shutil.copyfile(first, path)
        else:
            lobes_table(path, recipe=recipe, size=(stop - start, NT, NV))
        with h5py.File(path, "r+") as f:
            f["specular"][...] = whole[start:stop]
        declare_rows(path, start, stop)  # as every kind's parts do
        parts.append((path, start, stop))
    first.unlink()
    return parts, whole


def _write(out, parts, total: int):
    with h5py.File(parts[0][0], "r") as f:
        theta, theta_v, diffuse = f["theta"][()], f["theta_v"][()], f["diffuse"][()]
    axes = [
        Axis("theta", theta, "rad", "angle(light, tangent)"),
        Axis("theta_v", theta_v, "rad", "angle(tangent, view)", period=None),
        Axis("exponent", np.arange(1.0, total + 1), "1", "specular exponent"),
    ]
    return write_virtual(
        out, "kk_lobes", RECIPE, "exponent", parts, axes, [Variable("diffuse", diffuse, ("theta",), "1", "sin theta")]
    )


@pytest.mark.parametrize("parts_count,block,short", [pytest.param(4096, 2, 1, marks=pytest.mark.slow), (64, 2, 1), (4, 3, 0)])
def test_one_mapping_for_every_whole_block_reads_back(tmp_path, parts_count, block, short):
    total = parts_count * block - short
    out = tmp_path / "t.h5"
    parts, whole = _parts(out, total, block)
    assert len(parts) == parts_count
    stamps = [tuple(stamp(p)) for p, _, _ in parts]
    _write(out, parts, total)
    assert [tuple(stamp(p)) for p, _, _ in parts] == stamps  # writing the asset opened no part for writing
    with h5py.File(out, "r") as f:
        sources = f["specular"].virtual_sources()
        assert [s.file_name for s in sources] == [f"t.h5.parts/part-{total}x{block}-%b.h5", f"t.h5.parts/{parts[-1][0].name}"]
        assert f["specular"].shape == (total, NT, NV) and not f["diffuse"].is_virtual
        assert f["specular"][()].tobytes() == whole.tobytes()  # HDF5 reads through every part
    if parts_count <= 64:  # every part checked: a few ms each
        assert check_virtual(out) == sorted(p for p, _, _ in parts)
        got = read_table(out, kind="kk_lobes")
        assert got["specular"].dtype == np.float32 and got["specular"].tobytes() == whole.tobytes()
    if shutil.which("h5dump"):
        dump = subprocess.run(
            ["h5dump", "-d", "/specular", "-s", f"{total - 1},0,0", "-c", "1,1,2", str(out)],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert dump.returncode == 0 and f"DATASPACE  SIMPLE {{ ( {total}, {NT}, {NV} )" in dump.stdout
        assert f"{whole[-1, 0, 0]:g}, {whole[-1, 0, 1]:g}" in dump.stdout


@pytest.mark.parametrize("which,fault", [(0, "missing"), (1, "missing"), (3, "missing"), (2, "foreign")])
def test_a_missing_or_foreign_part_is_named_and_the_extent_holds(tmp_path, which, fault):
    out = tmp_path / "t.h5"
    parts, _ = _parts(out, 12, 3)
    _write(out, parts, 12)
    part = parts[which][0]
    if fault == "missing":
        part.unlink()
        error, says, reader_says = errors.AssetNotFoundError, "missing", "does not exist"
    else:
        theirs, _ = _parts(tmp_path / "o.h5", 12, 3, recipe={**RECIPE, "n_theta": 34})
        part.write_bytes(theirs[which][0].read_bytes())
        error, says, reader_says = errors.CorruptAssetError, "another recipe", "another recipe hash"
    with h5py.File(out, "r") as f:
        assert f["specular"].shape == (12, NT, NV)  # the last block's fixed mapping pins the extent
    with pytest.raises(error) as exc:
        check_virtual(out)
    assert exc.value.path == str(part) and says in str(exc.value)
    with pytest.raises(errors.ForeignReferenceError, match=reader_says):
        read_table(out, kind="kk_lobes")


def test_a_block_after_the_last_whole_one_is_still_checked(tmp_path):
    """HDF5 opens the files of the blocks after the pattern's while they exist: they are sources too."""
    out = tmp_path / "t.h5"
    parts, _ = _parts(out, 11, 3)
    _write(out, parts, 11)
    extra = parts_dir(out) / "part-11x3-3.h5"  # the name the pattern would give the last block
    extra.write_bytes(b"not a part")
    with pytest.raises(errors.ForeignReferenceError, match="part-11x3-3.h5"):
        read_table(out, kind="kk_lobes")
    with pytest.raises(errors.CorruptAssetError, match="part-11x3-3.h5"):
        check_virtual(out)


def test_a_percent_sign_in_the_asset_name_is_literal(tmp_path):
    out = tmp_path / "100%b.h5"
    parts, whole = _parts(out, 7, 2)
    _write(out, parts, 7)
    assert read_table(out, kind="kk_lobes")["specular"].tobytes() == whole.tobytes()
    assert len(check_virtual(out)) == 4


def test_a_short_last_block_of_a_real_bake_matches_one_process(tmp_path):
    small = {"sectors": {"count": 12, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 8, "steps": 4}}
    ref = bake(small, tmp_path / "ref.h5")
    out = tmp_path / "db.h5"
    bake(small, out, block=5, merge="virtual")
    assert sorted(p.name for p in parts_dir(out).glob("part-*.h5")) == ["part-12x5-0.h5", "part-12x5-1.h5", "part-12x5-2-last.h5"]
    a, b = load_hrir_db(ref["out"]), load_hrir_db(out)
    assert a.reflectance.tobytes() == b.reflectance.tobytes() and a.alpha.tobytes() == b.alpha.tobytes()
    with h5py.File(out, "r") as f:
        assert len(f["reflectance"].virtual_sources()) == 2


def test_each_part_is_opened_once_per_asset_and_again_only_when_its_stamp_changes(tmp_path, monkeypatch):
    """Readers validate a virtual asset's parts once for all its tables (24 virtual tables here), remember them by
    their stat stamps for the process's lifetime, and open a part again only when it changed."""
    from pathlib import Path

    from hairlut.assets import sources

    small = {"sectors": {"count": 12, "grid": [8, 8]}, "angles": {"views": 2, "lights": 2}, "trace": {"pixels": 4, "steps": 4}}
    out = tmp_path / "db.h5"
    bake(small, out, block=5, merge="virtual")
    parts = sorted(parts_dir(out).glob("part-*.h5"))
    opened = []
    real = sources.guard
    monkeypatch.setattr(sources, "guard", lambda p, *a: (opened.append(Path(p)), real(p, *a))[1])
    monkeypatch.setattr(sources, "_PARTS", {})
    first = load_hrir_db(out)  # check_virtual, then read_table's validation of every table
    with h5py.File(out, "r") as f:
        assert sum(f[n].is_virtual for n in ("alpha", "reflectance", "density", "geometry/v0")) == 4
    assert sorted(p for p in opened if p.parent == parts_dir(out)) == parts  # once each, for every table
    opened.clear()
    assert check_virtual(out) == parts and load_hrir_db(out).reflectance.tobytes() == first.reflectance.tobytes()
    assert not [p for p in opened if p.parent == parts_dir(out)]  # unchanged: stamped, not opened
    st = parts[1].stat()
    os.utime(parts[1], ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    assert check_virtual(out) == parts
    assert [p for p in opened if p.parent == parts_dir(out)] == [parts[1]]  # only the touched part, once
    theirs = tmp_path / "o.h5"
    bake({**small, "trace": {"pixels": 4, "steps": 3}}, theirs, block=5, merge="virtual")
    parts[1].write_bytes((parts_dir(theirs) / parts[1].name).read_bytes())  # a foreign part under the same name
    with pytest.raises(errors.CorruptAssetError, match="another recipe"):
        check_virtual(out)
    with pytest.raises(errors.ForeignReferenceError, match="part-12x5-1.h5:alpha, which carries another recipe hash"):
        read_table(out, kind="hrir_db")
