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
        assert "axes" not in f, "schema 2 keeps the axes at the root, where netCDF-4 readers look"
        for ds in datasets:
            assert ds.chunks is not None and ds.compression == "gzip" and ds.shuffle and ds.fletcher32, ds.name
            assert "units" in ds.attrs and "long_name" in ds.attrs
        spec = f["specular"]
        assert spec.chunks == (1, 33, 17)
        for dim, name in zip(spec.dims, ("exponent", "theta", "theta_v")):
            assert dim.label == name
            assert len(dim) == 1 and dim[0].name == f"/{name}"
            assert f[name].is_scale
            assert f[name].attrs["NAME"] in (name, name.encode()), "a netCDF-4 coordinate variable, not a bare dimension"


def test_same_recipe_gives_identical_bytes(tmp_path, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    a, _ = lobes_table(tmp_path / "a.h5")
    b, _ = lobes_table(tmp_path / "b.h5")
    assert a.read_bytes() == b.read_bytes()
    assert read_table(a).created == "2023-11-14T22:13:20+00:00"


def test_periodic_axis_round_trips(tmp_path):
    phi = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    write_table(
        tmp_path / "p.h5",
        "kk_lobes",
        {"k": 1},
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
    offset, size = _chunk_span(path, "theta")
    raw = bytearray(path.read_bytes())
    raw[offset + size // 2] ^= 0x01
    path.write_bytes(bytes(raw))
    with pytest.raises(errors.ChecksumError, match="'theta' fails its fletcher32 checksum"):
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


@pytest.mark.parametrize("schema", [0, SCHEMA + 1, 99])
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


# ----------------------------------------------------------------------------- groups and the old layout


def _grouped(path):
    """A table whose group 'theta' shares its name with an axis, and a plain group 'extra'."""
    theta = np.linspace(0, np.pi, 5)
    phi = np.linspace(0, 2 * np.pi, 4, endpoint=False)
    axes = [Axis("theta", theta, "rad", "polar angle"), Axis("phi", phi, "rad", "azimuth", period=2 * np.pi)]
    variables = [
        Variable("diffuse", np.sin(theta), ("theta",), "1", "d"),
        Variable("specular", np.outer(theta, np.cos(phi)).astype(np.float32), ("theta", "phi"), "1", "s"),
        Variable("theta/weight", np.arange(5.0), ("theta",), "sr", "w", attrs={"names": "[1, 2]"}),
        Variable("extra/deep/phase", np.arange(4, dtype=np.int32), ("phi",), "1", "p"),
    ]
    write_table(path, "kk_lobes", {"g": 1}, axes, variables)
    return path, {v.name: v for v in variables}


def test_a_group_named_like_an_axis_is_stored_beside_it_and_read_back_under_its_name(tmp_path):
    path, ref = _grouped(tmp_path / "g.h5")
    t = read_table(path)
    assert list(t.variables) == ["diffuse", "specular", "theta/weight", "extra/deep/phase"]
    for name, var in ref.items():
        np.testing.assert_array_equal(t[name], var.data)
        assert t.variables[name].dims == var.dims and t.variables[name].units == var.units
    assert t.variables["theta/weight"].attrs["names"] == "[1, 2]"
    with h5py.File(path, "r") as f:
        assert f["theta"].is_scale and f["theta_group"].attrs["hairlut_name"] == "theta"
        assert f["theta_group/weight"].dims[0][0].name == "/theta"
        assert f["extra/deep/phase"].dims[0][0].name == "/phi" and "hairlut_name" not in f["extra"].attrs


@pytest.mark.parametrize(
    "names, message",
    [
        (["theta"], "shares its name with an axis"),
        (["theta_group"], "is taken by group of 'theta/w'"),
        (["diffuse/x"], "is taken by table 'diffuse'"),
    ],
)
def test_names_that_would_share_a_path_are_rejected(tmp_path, names, message):
    theta = np.linspace(0, 1, 3)
    variables = [Variable(n, theta, ("theta",), "1", n) for n in ["diffuse", "specular", "theta/w", *names]]
    with pytest.raises(errors.ValidationError, match=message) as info:
        write_table(tmp_path / "x.h5", "kk_lobes", {}, [Axis("theta", theta, "1", "t")], variables)
    assert info.value.field == "variable.name"
    assert list(tmp_path.iterdir()) == []


def test_inspect_and_preview_use_table_names(tmp_path):
    from hairlut.assets import preview, summarize

    path, ref = _grouped(tmp_path / "g.h5")
    s = summarize(path)
    assert s["schema"] == SCHEMA and list(s["axes"]) == ["theta", "phi"] and s["axes"]["phi"]["periodic"]
    by_name = {d["name"]: d for d in s["datasets"]}
    assert list(by_name) == ["diffuse", "specular", "theta/weight", "extra/deep/phase"]
    assert by_name["theta/weight"]["h5_path"] == "/theta_group/weight" and by_name["theta/weight"]["dims"] == ["theta"]
    assert by_name["specular"]["max"] == pytest.approx(float(ref["specular"].data.max()))
    png = preview(path, tmp_path / "w.png", dataset="theta/weight")
    assert png.read_bytes().startswith(b"\x89PNG")
    preview(path, tmp_path / "a.png", dataset="phi")
    with pytest.raises(errors.MissingDatasetError, match="no dataset 'nope'"):
        preview(path, tmp_path / "n.png", dataset="nope")


def _write_schema_1(path, t):
    """``t`` (a Table) in the schema 1 layout: axes as scales in /axes, tables at their names."""
    with h5py.File(path, "w", libver=("earliest", "v110"), track_order=True) as f:
        for key, value in {
            "hairlut_schema": np.int32(1),
            "kind": t.kind,
            "hairlut_version": t.version,
            "created": t.created,
            "recipe": json.dumps(t.recipe, sort_keys=True, separators=(",", ":")),
            "recipe_hash": t.recipe_hash,
        }.items():
            f.attrs[key] = value
        scales, group = {}, f.create_group("axes", track_order=True)
        for ax in t.axes.values():
            ds = group.create_dataset(ax.name, data=ax.values, chunks=True, fletcher32=True)
            ds.attrs.update({"units": ax.units, "long_name": ax.long_name, "periodic": np.int8(ax.periodic)})
            if ax.periodic:
                ds.attrs["period"] = ax.period
            ds.make_scale(ax.name)
            scales[ax.name] = ds
        for var in t.variables.values():
            ds = f.create_dataset(var.name, data=var.data, chunks=True, fletcher32=True)
            ds.attrs.update({"units": var.units, "long_name": var.long_name, **var.attrs})
            for i, dim in enumerate(var.dims):
                ds.dims[i].label = dim
                ds.dims[i].attach_scale(scales[dim])


def test_schema_1_files_are_still_read(tmp_path):
    from hairlut.assets import summarize

    path, _ = _grouped(tmp_path / "g.h5")
    new = read_table(path)
    _write_schema_1(tmp_path / "old.h5", new)
    old = read_table(tmp_path / "old.h5", kind="kk_lobes", required=["theta/weight"])
    assert old.schema == 1 and old.recipe_hash == new.recipe_hash
    assert list(old.axes) == list(new.axes) and list(old.variables) == list(new.variables)
    for name, ax in new.axes.items():
        np.testing.assert_array_equal(old.axes[name].values, ax.values)
        assert (old.axes[name].units, old.axes[name].period) == (ax.units, ax.period)
    for name, var in new.variables.items():
        np.testing.assert_array_equal(old[name], var.data)
        assert old.variables[name].dims == var.dims and old.variables[name].attrs == var.attrs
    s = summarize(tmp_path / "old.h5")
    assert s["schema"] == 1 and list(s["axes"]) == ["theta", "phi"]
    assert [d["name"] for d in s["datasets"]] == list(new.variables)


@pytest.mark.skipif(shutil.which("h5dump") is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_h5dump_reads_groups_and_root_scales(tmp_path):
    path, _ = _grouped(tmp_path / "g.h5")
    run = subprocess.run(["h5dump", "-A", str(path)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and "error" not in (run.stdout + run.stderr).lower(), run.stderr
    for word in ('GROUP "theta_group"', 'DATASET "weight"', 'DATASET "phase"', '"DIMENSION_SCALE"', "REFERENCE_LIST"):
        assert word in run.stdout
    data = subprocess.run(["h5dump", "-d", "/theta_group/weight", str(path)], capture_output=True, text=True, timeout=60)
    assert data.returncode == 0 and "error" not in data.stderr.lower() and "(0): 0, 1, 2, 3, 4" in data.stdout
