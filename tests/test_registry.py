"""The kind registry: a new kind is one subpackage plus one registry line; every real kind keeps the protocol."""

import hashlib
import json
import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets import read_table, stale_temporaries
from hairlut.bake import registry
from hairlut.bake.protocol import Baker
from hairlut_cli.main import cli

# The whole of a toy table kind: a package whose _kind.py declares BAKER (and nothing else in hairlut changes).
TOY_INIT = "from ._kind import BAKER\n"
TOY_KIND = textwrap.dedent('''
    """A toy table kind: values[i] = scale * i, for i < n; shards hold slices of i."""
    import time
    from pathlib import Path

    import numpy as np

    from hairlut.assets import Axis, Variable, read_table, recipe_hash, write_table
    from hairlut.bake.protocol import Baker, Option, parse_shard
    from hairlut.recipes import Field, resolve

    SCHEMA = {"n": Field(4, (int,), lambda v: None if v >= 1 else "must be >= 1", "values"),
              "scale": Field(1.0, (float, int), None, "scale")}


    def resolve_recipe(given=None):
        r = resolve(SCHEMA, given)
        r["scale"] = float(r["scale"])
        return r


    def _write(out, kind, r, start, stop, attrs):
        i = np.arange(start, stop)
        return write_table(out, kind, r, [Axis("i", i, "1", "index")],
                           [Variable("values", r["scale"] * i.astype(np.float64), ("i",), "1", "scale * i")], attrs=attrs)


    def bake(recipe, out, *, progress=None, shard=None, note=None):
        r, t0 = resolve_recipe(recipe), time.perf_counter()
        start, stop, kind = 0, r["n"], "toy_table"
        if shard is not None:
            k, n = parse_shard(shard)
            start, stop, kind = k * r["n"] // n, (k + 1) * r["n"] // n, "toy_shard"
        path = _write(out, kind, r, start, stop, {"start": start, "total": r["n"], "note": str(note)})
        if progress:
            progress(stop - start, stop - start)
        return {"out": str(path), "kind": kind, "bytes": Path(path).stat().st_size, "seconds": time.perf_counter() - t0,
                "recipe_hash": recipe_hash(r), "values": stop - start}


    def merge(shards, out):
        tables = sorted((read_table(p, kind="toy_shard") for p in shards), key=lambda t: int(t.attrs["start"]))
        r = tables[0].recipe
        path = _write(out, "toy_table", r, 0, r["n"], {"start": 0, "total": r["n"], "note": "merged"})
        return {"out": str(path), "shards": len(tables), "values": r["n"], "bytes": Path(path).stat().st_size}


    BAKER = Baker(kind="toy_table", command="toy", description="a toy table for the registry test", required=("values",),
                  schema=SCHEMA, resolve_recipe=resolve_recipe, bake=bake,
                  load=lambda path: read_table(path, kind="toy_table")["values"],
                  estimate=lambda r: (8 * resolve_recipe(r)["n"], 0.01), unit="values",
                  options=(Option("note", str, None, "a kind-specific option"),),
                  shard_kind="toy_shard", shard_required=("values",), merge=merge)
''')


@pytest.fixture
def toy(tmp_path, monkeypatch):
    """Register the toy subpackage with one registry line."""
    pkg = tmp_path / "pkgs" / "toykind"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text(TOY_INIT)
    (pkg / "_kind.py").write_text(TOY_KIND)
    monkeypatch.syspath_prepend(str(tmp_path / "pkgs"))
    monkeypatch.setitem(registry.BAKERS, "toy_table", "toykind")  # the one line
    return registry.get("toy")


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_a_new_kind_is_one_subpackage_and_one_line(toy, tmp_path):
    assert isinstance(toy, Baker) and "toy_table" in registry.kinds() and registry.get("toy_table") is toy
    assert "toy" in run("bake", "--help").output
    # hairlut bake KIND --out, with --set and the kind's own option
    res = run("bake", "toy", "--out", tmp_path / "t.h5", "--set", "n=6", "--set", "scale=2", "--note", "hi", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["kind"] == "toy_table" and doc["status"] == "baked" and doc["values"] == 6
    np.testing.assert_array_equal(toy.load(tmp_path / "t.h5"), 2.0 * np.arange(6))
    assert read_table(tmp_path / "t.h5").attrs["note"] == "hi"
    # inspect names it and its description
    res = run("inspect", tmp_path / "t.h5")
    assert res.exit_code == 0 and "toy_table  (a toy table for the registry test)" in res.output
    # the cache: without --out, baked once, then reused; the library's ensure finds the same file
    cache = tmp_path / "cache"
    first = run("bake", "--cache", cache, "toy", "--set", "n=5", "--json")
    again = run("bake", "--cache", cache, "toy", "--set", "n=5", "--json")
    assert first.exit_code == again.exit_code == 0, first.output + again.output
    a, b = json.loads(first.stdout), json.loads(again.stdout)
    assert (a["status"], b["status"]) == ("baked", "reused") and a["out"] == b["out"]
    assert registry.ensure("toy_table", {"n": 5}, cache) == (Path(a["out"]), "reused")
    ls = json.loads(run("cache", "ls", "--cache", cache, "--json").output)
    assert [e["kind"] for e in ls] == ["toy_table"]
    # shards and merge dispatch to the toy's merge without naming it
    for k in range(3):
        assert run("bake", "toy", "--set", "n=7", "--out", tmp_path / f"s{k}.h5", "--shard", f"{k}/3").exit_code == 0
    res = run("merge", *[tmp_path / f"s{k}.h5" for k in (2, 0, 1)], "--out", tmp_path / "m.h5")
    assert res.exit_code == 0, res.output
    assert res.output.strip() == f"wrote {tmp_path / 'm.h5'} (7 values from 3 shards, 0.0 MiB)"
    np.testing.assert_array_equal(toy.load(tmp_path / "m.h5"), np.arange(7.0))
    # a shard is not cached; a bad recipe key is one line naming the key
    assert "give --out" in run("bake", "toy", "--shard", "0/2").output
    bad = run("bake", "toy", "--out", tmp_path / "x.h5", "--set", "n=0")
    assert bad.exit_code == 2 and "n=0: must be >= 1" in bad.output and len(bad.output.strip().splitlines()) == 1


def test_the_scene_maps_command_is_its_kind_name():
    """`hairlut bake scene_maps` bakes one kind; `hairlut bake --scene FILE` bakes what a scene plans: the kind's
    command is no longer the bare word `scene`."""
    assert registry.get("scene_maps").command == "scene_maps"
    listed = run("bake", "--help").output
    assert "scene_maps" in listed and "per-groom sector projections" in listed
    assert run("bake", "scene_maps", "--help").exit_code == 0
    res = run("bake", "scene", "--help")
    assert res.exit_code == 2 and "No such command" in res.output


def test_unknown_kinds_and_kinds_that_cannot_shard(tmp_path):
    res = run("bake", "nonsense")
    assert res.exit_code == 2 and "No such command" in res.output
    with pytest.raises(errors.ValidationError) as exc:
        registry.get("nonsense")
    assert exc.value.field == "kind" and "sh (sh_tables)" in str(exc.value)
    res = run("bake", "sh", "--out", tmp_path / "x.h5", "--shard", "0/2")  # SH tables split over their dense tangents
    assert res.exit_code == 2 and "shard='0/2'" in res.output and "dense.t_resolution > 0" in res.output
    assert len(res.output.strip().splitlines()) == 1 and not (tmp_path / "x.h5").exists()
    with pytest.raises(errors.ValidationError):
        registry.merge([], tmp_path / "m.h5")


def test_every_registered_kind_declares_the_protocol():
    from hairlut.assets.kinds import KINDS

    for kind in registry.kinds():
        b = registry.get(kind)
        r = b.resolve_recipe({})
        assert b.resolve_recipe(r) == r  # idempotent: a resolved recipe (with its method) resolves to itself
        assert KINDS[kind].required == b.required and b.description
        if b.can_shard:
            assert KINDS[b.shard_kind].required == b.shard_required and (callable(b.merge) or b.units is not None)
        nbytes, seconds = b.estimate(r)
        assert nbytes > 0 and seconds > 0
    from hairlut.envlight import LAYOUTS

    assert next(o for o in registry.get("sh").options if o.name == "layout").type == LAYOUTS


SMALL = {
    "sh_tables": {"kernel": {"p": 16.0}},
    "hair_bsdf": {"grid": {"resolution": [3, 3, 2]}, "coverage": {"resolution": [2, 3]}},
    "hrir_db": {
        "sectors": {"count": 16, "grid": [8, 8]},
        "angles": {"views": 16, "lights": 16},
        "trace": {"pixels": 32, "steps": 16},
    },
}


@pytest.mark.parametrize("kind", sorted(SMALL))
def test_estimate_bake_atomically_and_load(kind, tmp_path):
    b = registry.get(kind)
    out = tmp_path / "t.h5"
    out.write_bytes(b"an older file")

    class Stop(Exception):
        pass

    def die(done, total):
        if done >= 1:
            raise Stop

    with pytest.raises(Stop):  # a bake that dies leaves the old file, no partial one
        registry.bake(kind, SMALL[kind], out, progress=die)
    assert out.read_bytes() == b"an older file"
    rep = registry.bake(kind, SMALL[kind], out)
    assert rep["out"] == str(out) and rep["kind"] == kind and rep["bytes"] == out.stat().st_size
    assert stale_temporaries(tmp_path) == []
    nbytes, seconds = b.estimate(SMALL[kind])
    assert 0.5 < nbytes / rep["bytes"] < 2 and seconds > 0
    loaded = b.load(out)
    assert loaded.recipe == read_table(out, kind=kind).recipe == b.resolve_recipe(SMALL[kind])


def test_sh_light_is_a_keyed_input(tmp_path):
    from hairlut.envlight import sky_light
    from hairlut.shtables import full_recipe

    b = registry.get("sh_tables")
    given = {"kernel": {"p": 4.0}, "bands": {"transmittance": 2}}
    light = sky_light(2)
    r = b.resolve_recipe(given, light=light)
    assert r == full_recipe(given, light) and r["light"]["lmax"] == 2 and b.resolve_recipe(r) == r
    path, status = registry.ensure("sh_tables", given, tmp_path, light=light)
    assert status == "baked" and read_table(path).recipe == r and "light/a" in read_table(path).variables
    assert registry.ensure("sh_tables", given, tmp_path, light=light) == (path, "reused")
    plain, _ = registry.ensure("sh_tables", given, tmp_path)
    assert plain != path  # the light is part of the cache key
    with pytest.raises(errors.ValidationError) as exc:  # a recipe naming a light needs it
        registry.bake("sh_tables", r, tmp_path / "x.h5")
    assert exc.value.field == "light"
    with pytest.raises(errors.ValidationError):  # and not another one
        b.resolve_recipe(r, light=sky_light(3))
    res = run(
        "bake",
        "sh",
        "--out",
        tmp_path / "s.h5",
        "--set",
        "kernel.p=4",
        "--set",
        "bands.transmittance=2",
        "--light",
        "sky",
        "--json",
    )
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["recipe"]["light"]["source_sha256"] == light.source_sha256


def test_hrir_through_the_registry_is_the_same_bake(tmp_path):
    """`hairlut bake hrir` (the generic command) and hairlut.hrir.bake write the same bytes."""
    from hairlut.hrir import bake

    small = {"sectors": {"count": 3, "grid": [8, 8]}, "angles": {"views": 4, "lights": 2}, "trace": {"pixels": 8, "steps": 8}}
    bake(small, tmp_path / "a.h5", block=2)
    rec = tmp_path / "r.toml"
    rec.write_text("[sectors]\ncount = 3\ngrid = [8, 8]\n[angles]\nviews = 4\nlights = 2\n[trace]\npixels = 8\nsteps = 8\n")
    res = run("bake", "hrir", "--recipe", rec, "--out", tmp_path / "b.h5", "--block", "3", "--no-progress")
    assert res.exit_code == 0, res.output
    assert res.output.startswith(f"wrote {tmp_path / 'b.h5'} (hrir_db, sectors 0..2 of 3,")

    def sha(p):
        return hashlib.sha256(p.read_bytes()).hexdigest()

    assert sha(tmp_path / "a.h5") == sha(tmp_path / "b.h5")
