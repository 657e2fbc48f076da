"""HDF5 table files: round trips, the stored layout, and every way a file can be bad."""

import json
import shutil
import subprocess

import h5py
import numpy as np
import pytest

from hairlut import errors
from hairlut.assets import Axis, Variable, read_table, recipe_hash, write_table
from hairlut.assets.kinds import SCHEMA

from ._tables import RECIPE, lobes_table


def test_round_trip(tmp_path):
    path, ref = lobes_table(tmp_path / "t.h5")
    t = read_table(path, kind="kk_lobes")
    assert t.kind == "kk_lobes" and t.schema == SCHEMA
    assert t.recipe == json.loads(json.dumps(RECIPE))
    assert t.recipe_hash == recipe_hash(RECIPE)
    np.testing.assert_array_equal(t["specular"], ref["specular"])
    np.testing.assert_array_equal(t["diffuse"], ref["diffuse"])
    assert t["specular"].dtype == np.float32
    assert t.variables["specular"].dims == ("exponent", "theta", "theta_v")
    np.testing.assert_array_equal(t.axes["theta"].values, ref["theta"])
    assert t.axes["theta"].units == "rad"
    assert t.attrs["note"] == "test"


def test_layout_follows_the_design(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    raw = path.read_bytes()
    assert raw[8] == 0, "superblock version 0: libver earliest"
    with h5py.File(path, "r") as f:
        for key in ("hairlut_schema", "kind", "hairlut_version", "created", "recipe", "recipe_hash"):
            assert key in f.attrs
        datasets = []
        f.visititems(lambda n, o: datasets.append(o) if isinstance(o, h5py.Dataset) else None)
        assert len(datasets) == 5  # 3 axes + 2 tables
        for ds in datasets:
            assert ds.chunks is not None and ds.compression == "gzip" and ds.shuffle and ds.fletcher32, ds.name
            assert "units" in ds.attrs and "long_name" in ds.attrs
        spec = f["specular"]
        assert spec.chunks == (1, 33, 17)
        for dim, name in zip(spec.dims, ("exponent", "theta", "theta_v")):
            assert dim.label == name
            assert len(dim) == 1 and dim[0].name == f"/axes/{name}"
            assert f[f"axes/{name}"].is_scale


def test_same_recipe_gives_identical_bytes(tmp_path, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    a, _ = lobes_table(tmp_path / "a.h5")
    b, _ = lobes_table(tmp_path / "b.h5")
    assert a.read_bytes() == b.read_bytes()
    assert read_table(a).created == "2023-11-14T22:13:20+00:00"


def test_periodic_axis_round_trips(tmp_path):
    phi = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    write_table(
        tmp_path / "p.h5", "kk_lobes", {"k": 1},
        [Axis("theta", phi, "rad", "azimuth", period=2 * np.pi), Axis("p", [1.0], "1", "p")],
        [Variable("diffuse", np.sin(phi), ("theta",), "1", "d"), Variable("specular", np.ones((1, 8)), ("p", "theta"), "1", "s")],
    )
    t = read_table(tmp_path / "p.h5")
    assert t.axes["theta"].periodic and t.axes["theta"].period == pytest.approx(2 * np.pi)
    assert not t.axes["p"].periodic


@pytest.mark.parametrize(
    "axes, variables, field",
    [
        ([Axis("a", [1.0, 2.0], "1", "a")], [Variable("diffuse", np.ones(3), ("a",), "1", "x")], "diffuse.dims[0]"),
        ([Axis("a", [1.0, 2.0], "1", "a")], [Variable("diffuse", np.ones(2), ("b",), "1", "x")], "diffuse.dims[0]"),
        ([Axis("a", [1.0, 2.0], "1", "a")], [Variable("diffuse", np.ones((2, 2)), ("a",), "1", "x")], "diffuse.dims"),
        ([Axis("a", [], "1", "a")], [], "axes.a.values"),
        ([Axis("a", [1.0], "1", "a")], [Variable("bad name", np.ones(1), ("a",), "1", "x")], "variable.name"),
        ([Axis("a", [1.0], "1", "a")], [Variable("diffuse", np.array(["x"]), ("a",), "1", "x")], "diffuse.dtype"),
        ([Axis("a", [1.0], "1", "a")], [Variable("diffuse", np.ones(1), ("a",), "1", "x")], "variables"),  # no specular
    ],
)
def test_writer_rejects_bad_tables_and_writes_nothing(tmp_path, axes, variables, field):
    with pytest.raises(errors.ValidationError) as info:
        write_table(tmp_path / "x.h5", "kk_lobes", {}, axes, variables)
    assert info.value.field == field
    assert list(tmp_path.iterdir()) == []


def test_unknown_kind_is_rejected(tmp_path):
    with pytest.raises(errors.ValidationError, match="kind"):
        write_table(tmp_path / "x.h5", "nonsense", {}, [], [])


# ----------------------------------------------------------------------------- bad files


def test_missing_file(tmp_path):
    with pytest.raises(errors.AssetNotFoundError, match="no such file") as info:
        read_table(tmp_path / "absent.h5")
    assert "absent.h5" in str(info.value)


@pytest.mark.parametrize("content", [b"", b"not hdf5 at all", b"\x76\x2f\x31\x01 exr magic"])
def test_not_hdf5(tmp_path, content):
    (tmp_path / "x.h5").write_bytes(content)
    with pytest.raises(errors.FormatError, match="not an HDF5 file"):
        read_table(tmp_path / "x.h5")


def test_directory_is_not_a_table(tmp_path):
    with pytest.raises(errors.FormatError):
        read_table(tmp_path)


@pytest.mark.parametrize("fraction", [0.02, 0.1, 0.3, 0.5, 0.9, 0.999])
def test_truncated(tmp_path, fraction):
    path, _ = lobes_table(tmp_path / "t.h5")
    raw = path.read_bytes()
    cut = max(8, int(len(raw) * fraction))
    path.write_bytes(raw[:cut])
    with pytest.raises(errors.TruncatedAssetError, match="truncated") as info:
        read_table(path)
    assert str(path) in str(info.value)


def _chunk_span(path, name, index=0):
    with h5py.File(path, "r") as f:
        info = f[name].id.get_chunk_info(index)
        return info.byte_offset, info.size


@pytest.mark.parametrize("where", [0.1, 0.5, 0.9])
def test_flipped_byte_inside_a_chunk_fails_the_checksum(tmp_path, where):
    path, _ = lobes_table(tmp_path / "t.h5")
    offset, size = _chunk_span(path, "specular", 1)
    raw = bytearray(path.read_bytes())
    raw[offset + int(size * where)] ^= 0x40
    path.write_bytes(bytes(raw))
    with pytest.raises(errors.ChecksumError, match="'specular' fails its fletcher32 checksum"):
        read_table(path)


def test_flipped_byte_in_an_axis_is_caught(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    offset, size = _chunk_span(path, "axes/theta")
    raw = bytearray(path.read_bytes())
    raw[offset + size // 2] ^= 0x01
    path.write_bytes(bytes(raw))
    with pytest.raises(errors.ChecksumError, match="axes/theta"):
        read_table(path)


def _edit(path, fn):
    with h5py.File(path, "r+") as f:
        fn(f)


def test_wrong_kind(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    with pytest.raises(errors.KindError, match="holds kind 'kk_lobes', expected 'sh_tables'"):
        read_table(path, kind="sh_tables")


def test_unknown_kind_in_file(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    _edit(path, lambda f: f.attrs.__setitem__("kind", "martian"))
    with pytest.raises(errors.KindError, match="unknown kind 'martian'"):
        read_table(path)


@pytest.mark.parametrize("schema", [0, 2, 99])
def test_unknown_schema(tmp_path, schema):
    path, _ = lobes_table(tmp_path / "t.h5")
    _edit(path, lambda f: f.attrs.__setitem__("hairlut_schema", np.int32(schema)))
    with pytest.raises(errors.SchemaError, match=f"unknown hairlut_schema {schema}"):
        read_table(path)


def test_foreign_hdf5_is_not_a_table(tmp_path):
    with h5py.File(tmp_path / "f.h5", "w") as f:
        f["x"] = np.ones(3)
    with pytest.raises(errors.FormatError, match="not a hairlut table"):
        read_table(tmp_path / "f.h5")


def test_missing_required_dataset(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    _edit(path, lambda f: f.__delitem__("specular"))
    with pytest.raises(errors.MissingDatasetError, match="required dataset 'specular' is missing"):
        read_table(path)
    path2, _ = lobes_table(tmp_path / "u.h5")
    with pytest.raises(errors.MissingDatasetError, match="'extra'"):
        read_table(path2, required=["extra"])


def test_tampered_recipe_fails_its_hash(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    _edit(path, lambda f: f.attrs.__setitem__("recipe", '{"n_theta":34}'))
    with pytest.raises(errors.ChecksumError, match="recipe_hash"):
        read_table(path)


@pytest.mark.skipif(shutil.which("h5dump") is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_h5dump_lists_a_table(tmp_path):
    path, _ = lobes_table(tmp_path / "t.h5")
    run = subprocess.run(["h5dump", "-H", str(path)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert "error" not in (run.stdout + run.stderr).lower()
    for word in ('DATASET "specular"', 'DATASET "theta"', "H5T_IEEE_F32LE", 'ATTRIBUTE "recipe_hash"', "DIMENSION_LIST"):
        assert word in run.stdout
    data = subprocess.run(["h5dump", "-d", "/diffuse", str(path)], capture_output=True, text=True, timeout=60)
    assert data.returncode == 0 and "error" not in data.stderr.lower()
