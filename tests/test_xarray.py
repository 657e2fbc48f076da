"""Every table kind opens in xarray (h5netcdf): named dimensions, axes as coordinates, hairlut's own values.

netCDF-4 readers look for a variable's dimension scales in its group or an
ancestor; hairlut keeps them at the root (schema 2).  The files are the kinds'
own writers' output, from small recipes.
"""

import shutil
import subprocess

import h5netcdf  # noqa: F401  (the engine xarray uses below)
import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from hairlut.assets import read_table, write_exr
from hairlut.assets.h5 import disk_name
from hairlut.assets.kinds import SCHEMA
from hairlut.bake import registry
from hairlut.planner import scene_maps_recipe
from hairlut.scene import resolve_scene

from ._synth_fixtures import scene as base_scene

SMALL_HRIR = {"sectors": {"count": 4, "grid": [6, 6]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 6, "steps": 8}}


def _cli(*args):
    from hairlut_cli.main import cli

    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    from hairlut.demo import sky
    from hairlut.hrir import bake

    d = tmp_path_factory.mktemp("kinds")
    bake(SMALL_HRIR, d / "db.h5", block=4)
    bake({**SMALL_HRIR, "storage": {"dtype": "float16"}}, d / "db16.h5", block=4)
    bake(SMALL_HRIR, d / "shard.h5", block=2, shard="1/2")
    write_exr(d / "sky.exr", sky(16))
    _cli("sh", "project", d / "sky.exr", "--bands", "3", "--out", d / "light.h5")
    recipe = d / "sh.toml"
    recipe.write_text("[kernel]\np = 8.0\n[dense]\nt_resolution = 2\ntheta_v_steps = 3\n")
    _cli("bake", "sh", "--recipe", recipe, "--out", d / "sh.h5", "--set", "bands.transmittance=2", "--light", d / "sky.exr")
    _cli(
        "bake",
        "sh",
        "--recipe",
        recipe,
        "--out",
        d / "shp.h5",
        "--set",
        "bands.transmittance=2",
        "--light",
        d / "sky.exr",
        "--shard",
        "0/2",
        "--block",
        "8",
    )
    sc = resolve_scene(_tiny_scene())
    registry.bake("scene_maps", scene_maps_recipe(sc), d / "maps.h5", scene=sc)
    registry.bake("scene_maps", scene_maps_recipe(sc), d / "mapsp.h5", scene=sc, shard="1/2", options={"block": 16})
    bsdf = {"grid": {"resolution": [3, 3, 2]}, "coverage": {"resolution": [2, 3]}}
    registry.bake("hair_bsdf", bsdf, d / "bsdf.h5")
    registry.bake("hair_bsdf", bsdf, d / "bsdfp.h5", shard="1/2", options={"block": 1})
    return {
        "hrir_db": d / "db.h5",
        "hrir_db_float16": d / "db16.h5",
        "hrir_shard": d / "shard.h5",
        "sh_light": d / "light.h5",
        "sh_tables": d / "sh.h5",
        "sh_shard": d / "shp.h5",
        "scene_maps": d / "maps.h5",
        "scene_shard": d / "mapsp.h5",
        "hair_bsdf": d / "bsdf.h5",
        "hair_bsdf_shard": d / "bsdfp.h5",
    }


def _tiny_scene() -> dict:
    s = base_scene()
    s["strands"] = {**s["strands"], "count": 20}
    s["render"] = {**s["render"], "method": "scene", "views": 8, "terms": 1, "shading_pixels": 8}
    s["tables"] = {"hrir": {"sectors": {"grid": [8, 8]}, "trace": {"pixels": 8, "steps": 12}}}
    return s


KINDS = [
    "hrir_db",
    "hrir_db_float16",
    "hrir_shard",
    "sh_light",
    "sh_tables",
    "sh_shard",
    "scene_maps",
    "scene_shard",
    "hair_bsdf",
    "hair_bsdf_shard",
]


def test_every_kind_hairlut_bakes_is_covered():
    """A new table kind (or its shard kind) must join this file's cases."""
    written = set()
    for baker in (registry.get(k) for k in registry.kinds()):
        written |= {baker.kind} | ({baker.shard_kind} if baker.shard_kind else set())
    assert written <= {_kind(k) for k in KINDS}


def _kind(case: str) -> str:
    return case.removesuffix("_float16")


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype and a.shape == b.shape
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("kind", KINDS)
def test_open_dataset_names_dims_and_shows_axes_as_coordinates(assets, kind):
    t = read_table(assets[kind], kind=_kind(kind))
    assert t.schema == SCHEMA
    with xr.open_dataset(assets[kind], engine="h5netcdf") as ds:
        assert ds.attrs["kind"] == _kind(kind) and ds.attrs["recipe_hash"] == t.recipe_hash
        assert set(ds.coords) == set(t.axes)
        for name, ax in t.axes.items():
            c = ds.coords[name]
            assert c.dims == (name,) and name in ds.indexes
            _same(c.values, np.asarray(ax.values))
            assert c.attrs["units"] == ax.units and c.attrs["long_name"] == ax.long_name
            assert bool(c.attrs["periodic"]) == ax.periodic
            if ax.periodic:
                assert c.attrs["period"] == pytest.approx(ax.period)
        if kind.endswith("_float16"):
            assert ds["alpha"].dtype == np.float16 and ds["reflectance"].dtype == np.float16
        root = [n for n in t.variables if "/" not in n]
        assert t.variables and set(ds.data_vars) == set(root)  # a shard may hold its tables in groups only
        for name in root:
            var = t.variables[name]
            assert ds[name].dims == var.dims
            assert ds[name].attrs["units"] == var.units and ds[name].attrs["long_name"] == var.long_name
            _same(ds[name].values, var.data)
            for dim in var.dims:
                _same(ds[name].coords[dim].values, np.asarray(t.axes[dim].values))


@pytest.mark.parametrize("kind", KINDS)
def test_open_datatree_gives_every_table_its_dims_and_coordinates(assets, kind):
    t = read_table(assets[kind], kind=_kind(kind))
    with xr.open_datatree(assets[kind], engine="h5netcdf") as tree:
        seen = set()
        for name, var in t.variables.items():
            where = disk_name(name, t.axes)
            group, _, leaf = where.rpartition("/")
            node = tree[group] if group else tree
            da = node[leaf]
            assert da.dims == var.dims, name
            assert da.attrs["units"] == var.units, name
            _same(da.values, var.data)
            for dim in var.dims:  # inherited from the root, where the scales are
                assert dim in node.coords, (name, dim)
                _same(da.coords[dim].values, np.asarray(t.axes[dim].values))
            seen.add(where)
        stored = {f"{n.path.strip('/')}/{v}".lstrip("/") for n in tree.subtree for v in n.data_vars}
        assert stored == seen  # nothing else shows up as a table


@pytest.mark.parametrize("kind", ["hrir_db", "sh_tables"])
def test_groups_open_alone_with_named_dims(assets, kind):
    t = read_table(assets[kind], kind=_kind(kind))
    groups = {disk_name(n, t.axes).rpartition("/")[0] for n in t.variables if "/" in n}
    assert groups
    for group in groups:
        with xr.open_dataset(assets[kind], engine="h5netcdf", group=group) as ds:
            for leaf, da in ds.data_vars.items():
                name = next(n for n in t.variables if disk_name(n, t.axes) == f"{group}/{leaf}")
                assert da.dims == t.variables[name].dims
                _same(da.values, t[name])


@pytest.mark.skipif(shutil.which("h5dump") is None, reason="h5dump (Debian hdf5-tools) not installed")
@pytest.mark.parametrize("kind", KINDS)
def test_h5dump_reads_every_kind(assets, kind):
    run = subprocess.run(["h5dump", str(assets[kind])], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "error" not in run.stderr.lower() and "DIMENSION_SCALE" in run.stdout
