"""Hostile and inconsistent HDF5 files (issue 14, items 2–5; item 1, flipped bits, in ``test_hostile_bitflips``): typed errors naming file and fault.

Each case is crafted the way the issue describes it, on a real table written by hairlut,
and read through read_table, summarize (inspect), the CLI and the kind loaders.
"""

import json
import os
import time

import h5py
import numpy as np
import pytest

from hairlut import errors
from hairlut.assets import allowed_virtual_sources, read_table, summarize
from hairlut.assets.preview import preview
from hairlut.hrir import load_hrir_db
from hairlut.shtables import SHTables

from ._hostile import cli_fails, copy, hrir_file, poke, set_recipe, sh_file  # noqa: F401  (module fixtures)
from ._tables import declare_rows, lobes_table, virtual_over

# ----------------------------------------------------------------------------- item 2: unexpected types, groups, text


@pytest.mark.parametrize("bad", ["string", "compound", "vlen"])
def test_non_numeric_datasets_are_refused(tmp_path, bad):
    path = lobes_table(tmp_path / "t.h5")[0]

    def add(f):
        if bad == "string":
            f["extra"] = np.array([b"abc", b"def"])
        elif bad == "compound":
            f["extra"] = np.zeros(3, dtype=[("a", "f4"), ("b", "i4")])
        else:
            f.create_dataset("extra", (2,), dtype=h5py.vlen_dtype(np.float32))

    poke(path, add)
    for fn in (read_table, summarize):
        with pytest.raises(errors.CorruptAssetError, match="'extra' holds .* not numbers"):
            fn(path)
    assert "extra" in cli_fails("inspect", "--json", path)


def test_group_in_schema1_axes_and_group_for_a_dataset(tmp_path, sh_file):
    path = lobes_table(tmp_path / "t.h5")[0]

    def to_schema1_with_group(f):
        f.attrs["hairlut_schema"] = np.int32(1)
        g = f.create_group("axes")
        g.create_group("theta").create_dataset("x", data=[1.0])

    poke(path, to_schema1_with_group)
    for fn in (read_table, summarize):
        with pytest.raises(errors.HairlutError):
            fn(path)
    cli_fails("inspect", "--json", path)

    sh = copy(sh_file, tmp_path / "sh.h5")

    def gaunt_as_group(f):
        del f["gaunt"]
        f.create_group("gaunt").create_dataset("x", data=np.zeros(3))

    poke(sh, gaunt_as_group)
    with pytest.raises(errors.MissingDatasetError, match="gaunt"):
        SHTables.load(sh)


@pytest.mark.parametrize("text", ["{not json", "[1, 2]", '"a string"', "NaN"])
def test_recipe_that_is_not_a_json_object(tmp_path, text, sh_file):
    path = poke(lobes_table(tmp_path / "t.h5")[0], lambda f: set_recipe(f, text))
    for fn in (read_table, summarize):
        with pytest.raises(errors.CorruptAssetError, match="'recipe'"):
            fn(path)
    assert "recipe" in cli_fails("inspect", "--json", path)
    sh = poke(copy(sh_file, tmp_path / "sh.h5"), lambda f: set_recipe(f, text))
    with pytest.raises(errors.CorruptAssetError, match="'recipe'"):
        SHTables.load(sh)


@pytest.mark.parametrize("names", ["rho_st, rho_s", "[1, 2, 3]", '["a", "b", "c"]'])
def test_feature_names_that_are_not_json_or_disagree(tmp_path, hrir_file, names):
    path = copy(hrir_file, tmp_path / "db.h5")
    poke(path, lambda f: f.attrs.__setitem__("feature_names", names))
    with pytest.raises(errors.CorruptAssetError, match="feature_names"):
        load_hrir_db(path)


# ----------------------------------------------------------------------------- item 3: declared shapes


def test_declared_shape_larger_than_memory_is_refused_before_reading(tmp_path, monkeypatch):
    path = lobes_table(tmp_path / "t.h5")[0]
    poke(path, lambda f: f.create_dataset("big", data=np.ones((64, 4096)), chunks=(8, 4096)))  # 2 MiB, all allocated
    monkeypatch.setenv("HAIRLUT_MEMORY_LIMIT", "1M")
    with pytest.raises(errors.AssetTooLargeError, match=r"'big'.*\(64, 4096\) float64.*1 MiB"):
        read_table(path)
    assert summarize(path)["datasets"][-1]["count"] == 64 * 4096  # the summary streams: no limit needed
    monkeypatch.delenv("HAIRLUT_MEMORY_LIMIT")
    assert read_table(path)["big"].shape == (64, 4096)
    with pytest.raises(errors.AssetTooLargeError):
        read_table(path, memory_limit=1 << 20)


@pytest.mark.parametrize("shape, chunks", [((1, 10**10), (1, 1 << 20)), ((10**12,), (1 << 20,))])
def test_unallocated_huge_datasets_are_refused_at_once(tmp_path, shape, chunks):
    path = lobes_table(tmp_path / "t.h5")[0]
    poke(path, lambda f: f.create_dataset("huge", shape=shape, dtype="f8", chunks=chunks))
    start = time.monotonic()
    for fn in (read_table, summarize):
        with pytest.raises(errors.CorruptAssetError, match="'huge'.*unallocated"):
            fn(path)
    assert "huge" in cli_fails("inspect", "--json", path)
    assert time.monotonic() - start < 30


# ----------------------------------------------------------------------------- item 4: reaching outside the file


@pytest.fixture
def secret(tmp_path):
    s = tmp_path / "secret.bin"
    s.write_bytes(np.arange(64, dtype=np.float64).tobytes())
    return s


def _readers(path, sh=False):
    out = [read_table, summarize, lambda p: preview(p, p.with_suffix(".png"), dataset="ext")]
    return out + ([SHTables.load] if sh else [])


def test_external_raw_storage_is_refused(tmp_path, secret, sh_file):
    path = lobes_table(tmp_path / "t.h5")[0]
    poke(path, lambda f: f.create_dataset("ext", shape=(64,), dtype="f8", external=[(str(secret), 0, 512)]))
    for fn in _readers(path):
        with pytest.raises(errors.ForeignReferenceError, match="'ext'.*external file.*secret.bin"):
            fn(path)
    assert not path.with_suffix(".png").exists()
    assert "external" in cli_fails("inspect", "--png", tmp_path / "p.png", "--dataset", "ext", path)
    assert not (tmp_path / "p.png").exists()
    sh = copy(sh_file, tmp_path / "sh.h5")

    def gaunt_external(f):
        g = f["gaunt"][()]
        raw = tmp_path / "g.bin"
        raw.write_bytes(g.astype("<f8").tobytes())
        del f["gaunt"]
        f.create_dataset("gaunt", shape=g.shape, dtype="<f8", external=[(str(raw), 0, g.size * 8)])

    poke(sh, gaunt_external)
    with pytest.raises(errors.ForeignReferenceError, match="gaunt"):
        SHTables.load(sh)


@pytest.mark.parametrize("link", ["external", "soft"])
def test_links_are_refused(tmp_path, link):
    other = lobes_table(tmp_path / "other.h5")[0]
    path = lobes_table(tmp_path / "t.h5")[0]

    def add(f):
        f["ext"] = h5py.ExternalLink(str(other), "/specular") if link == "external" else h5py.SoftLink("/specular")

    poke(path, add)
    for fn in _readers(path):
        with pytest.raises(errors.ForeignReferenceError, match=f"'/ext' is an? {link}"):
            fn(path)
    cli_fails("inspect", path)


def test_virtual_dataset_pointing_elsewhere_is_refused(tmp_path):
    other = lobes_table(tmp_path / "other.h5")[0]  # same recipe, but not one of the asset's parts
    path = virtual_over(lobes_table(tmp_path / "t.h5")[0], other)
    for fn in _readers(path):
        with pytest.raises(errors.ForeignReferenceError, match="'ext' is virtual.*parts folder"):
            fn(path)
    cli_fails("inspect", path)


def test_virtual_dataset_over_the_assets_own_parts_is_allowed(tmp_path):
    path = lobes_table(tmp_path / "t.h5")[0]
    parts = tmp_path / "t.h5.parts"
    parts.mkdir()
    part = declare_rows(lobes_table(parts / "part-0.h5")[0], 0, 2)
    with h5py.File(path, "r") as f:
        digest = f.attrs["recipe_hash"]
    assert allowed_virtual_sources(path, digest) == [part]
    virtual_over(path, "t.h5.parts/part-0.h5")
    t = read_table(path)
    np.testing.assert_array_equal(t["ext"], read_table(part)["specular"])
    assert summarize(path)["datasets"][-1]["name"] == "ext"

    foreign = lobes_table(parts / "part-1.h5", recipe={"other": 1})[0]  # another recipe hash
    assert allowed_virtual_sources(path, digest) == [part]
    poke(path, lambda f: f.__delitem__("ext"))
    virtual_over(path, "t.h5.parts/part-1.h5")
    with pytest.raises(errors.ForeignReferenceError, match="another recipe hash"):
        read_table(path)
    poke(path, lambda f: f.__delitem__("ext"))
    os.symlink(part, parts / "part-2.h5")
    virtual_over(path, "t.h5.parts/part-2.h5")
    with pytest.raises(errors.ForeignReferenceError, match="not a regular file"):
        read_table(path)
    assert foreign.exists()


# ----------------------------------------------------------------------------- item 5: contents disagree with the recipe


def _edit_recipe(path, **changes):
    with h5py.File(path, "r+") as f:
        recipe = json.loads(f.attrs["recipe"])
        for dotted, value in changes.items():
            node = recipe
            *head, last = dotted.split("__")
            for key in head:
                node = node[key]
            node[last] = value
        set_recipe(f, json.dumps(recipe, sort_keys=True, separators=(",", ":")))
    return path


@pytest.mark.parametrize(
    "changes, table",
    [
        ({"bands__light_specular": 9}, "gaunt"),
        ({"bands__transmittance": 4}, "gaunt"),
        ({"bands__light_diffuse": 5}, "gaunt"),
        ({"bands__light_specular": 200}, "bands.light_specular"),
        ({"kernel__p": -1.0}, "kernel.p"),
        ({"kernel__diffuse": "yes"}, "kernel.diffuse"),
        ({"bands": None}, "bands"),
    ],
)
def test_sh_tables_that_disagree_with_their_recipe(tmp_path, sh_file, changes, table):
    path = _edit_recipe(copy(sh_file, tmp_path / "sh.h5"), **changes)
    with pytest.raises(errors.CorruptAssetError) as info:
        SHTables.load(path)
    assert table in str(info.value) and str(path) in str(info.value)


def test_sh_tables_whose_table_is_too_short(tmp_path, sh_file):
    path = copy(sh_file, tmp_path / "sh.h5")

    def shorten(f):
        d = f["kernel/diffuse_k"][()]
        del f["kernel/diffuse_k"]
        f.create_dataset("kernel/diffuse_k", data=d[:1])

    poke(path, shorten)
    with pytest.raises(errors.CorruptAssetError, match="'kernel/diffuse_k' has shape"):
        SHTables.load(path)


@pytest.mark.parametrize(
    "changes, table",
    [
        ({"angles__views": 5}, "alpha"),
        ({"angles__lights": 7}, "reflectance"),
        ({"trace__pixels": 16}, "alpha"),
        ({"sectors__grid": [8, 9]}, "density"),
        ({"sectors__features": "moments"}, "feature_names"),
        ({"angles__views": 0}, "angles.views"),
    ],
)
def test_hrir_db_that_disagrees_with_its_recipe(tmp_path, hrir_file, changes, table):
    path = _edit_recipe(copy(hrir_file, tmp_path / "db.h5"), **changes)
    with pytest.raises(errors.CorruptAssetError) as info:
        load_hrir_db(path)
    assert table in str(info.value)


def test_hrir_db_with_nonpositive_feature_std(tmp_path, hrir_file):
    path = copy(hrir_file, tmp_path / "db.h5")

    def zero_std(f):
        d = f["features_std"][()]
        d[0] = 0.0
        f["features_std"][...] = d

    poke(path, zero_std)
    with pytest.raises(errors.CorruptAssetError, match="features_std"):
        load_hrir_db(path)
