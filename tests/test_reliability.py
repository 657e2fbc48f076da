"""Issue 14's remaining cases, each reproduced as the issue (or its audit) describes it.

* item 4: ``HDF5_VDS_PREFIX`` cannot redirect a virtual asset's own parts to other files;
* item 15: empty sectors and empty clusters render α = re = 0 (satf, direct); every bad
  scene and recipe key is named in its error, never a value derived from it (``kernel.p``
  rather than the band count it implies, the cluster keys that drive the sector count);
  huge coordinates and exponents give an error or a result, never an overflow warning;
* item 14: ``Contracted.radiance`` at more than 30 light bands against the brute-force
  quadrature of the kernel (independent of the Gaunt tables);
* item 12–13 on the shard path: ``bake sh_tables --shard`` and ``merge`` are finite or refused.
"""

import math
import warnings

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from cli.main import cli
from hairlut import errors
from hairlut.assets import allowed_virtual_sources, read_table, summarize

from ._synth_fixtures import scene, synthetic_db
from ._tables import declare_rows, lobes_table, virtual_over

# ----------------------------------------------------------------------------- item 4: HDF5_VDS_PREFIX


@pytest.fixture
def own_virtual(tmp_path):
    """An asset whose dataset 'ext' is virtual over its own part, and a decoy of that part elsewhere
    (same recipe, so the same recipe hash; other contents) at the same relative path."""
    asset = tmp_path / "asset"
    (asset / "t.h5.parts").mkdir(parents=True)
    path = lobes_table(asset / "t.h5")[0]
    part, want = lobes_table(asset / "t.h5.parts" / "part-0.h5", rng=np.random.default_rng(1))
    declare_rows(part, 0, 2)
    decoy = tmp_path / "decoy"
    (decoy / "t.h5.parts").mkdir(parents=True)
    lobes_table(decoy / "t.h5.parts" / "part-0.h5", rng=np.random.default_rng(2))
    virtual_over(path, "t.h5.parts/part-0.h5")
    with h5py.File(path, "r") as f:
        assert allowed_virtual_sources(path, f.attrs["recipe_hash"]) == [part]
    return path, want["specular"], decoy


def test_hdf5_vds_prefix_cannot_redirect_a_virtual_asset(own_virtual, monkeypatch):
    path, want, decoy = own_virtual
    np.testing.assert_array_equal(read_table(path)["ext"], want)
    monkeypatch.setenv("HDF5_VDS_PREFIX", str(decoy))
    with h5py.File(path, "r") as f:  # what HDF5 itself does: reads the decoy
        assert not np.array_equal(f["ext"][()], want)
    for fn in (read_table, summarize):
        with pytest.raises(errors.ForeignReferenceError, match=r"HDF5_VDS_PREFIX=.*redirects to .*decoy.*unset"):
            fn(path)
    res = CliRunner().invoke(cli, ["inspect", "--json", str(path)])
    assert res.exit_code == 2 and "HDF5_VDS_PREFIX" in res.output and len(res.output.strip().splitlines()) == 1
    monkeypatch.setenv("HDF5_VDS_PREFIX", f"{path.parent.parent / 'nothing-here'}:{decoy}")  # a search list
    with pytest.raises(errors.ForeignReferenceError, match="HDF5_VDS_PREFIX"):
        read_table(path)


@pytest.mark.parametrize("prefix", ["${ORIGIN}", "{tmp}/nothing-here", "."])
def test_hdf5_vds_prefix_that_leads_to_the_own_part_is_allowed(own_virtual, monkeypatch, prefix):
    path, want, _ = own_virtual
    monkeypatch.setenv("HDF5_VDS_PREFIX", prefix.replace("{tmp}", str(path.parent.parent)))
    np.testing.assert_array_equal(read_table(path)["ext"], want)


# ----------------------------------------------------------------------------- item 15: empty sectors and clusters


@pytest.fixture(scope="module")
def db():
    return synthetic_db()


@pytest.mark.parametrize("method", ["satf", "direct"])
def test_empty_clusters_render_transparent(db, method):
    """strands.count = 0: every sector is empty, so α, re and the final coverage are exactly 0."""
    from hairlut.synth import synthesize

    given = scene()
    given["strands"]["count"] = 0
    given["render"]["method"] = method
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no 'mean of empty slice' on the way
        res = synthesize(given, db if method == "satf" else None)
    for c in res.clusters:
        assert np.all(c.alpha == 0) and np.all(c.re == 0) and np.all(c.final[..., 3] == 0)


@pytest.mark.parametrize("thr", [1.0, math.inf])
def test_empty_sectors_give_zero_alpha_on_the_view_path_and_the_reference(db, thr):
    """A sparse groom (6 clumped strands per cluster): empty sectors hold no hair, so a texel whose
    HSV has two empty sectors has α = re = 0, an HSV with one empty end is never uniform (eq 7 fades
    to 0 towards it), and the per-view path equals the reference build_maps."""
    from hairlut.synth import prepare
    from hairlut.synth._maps import build_maps, sector_angles, texels
    from hairlut.synth._view import view_maps

    given = scene(k_threshold=thr)
    given["strands"].update(count=6, profile="clumped", spread=0.05)
    prep = prepare(given, db)
    occ = prep.frames.occupied
    assert occ.any() and not occ.all()
    sc = prep.scene
    sp = sector_angles(prep.frames, sc.view, sc.lights)
    n_u, n_t = sc.config["render"]["resolution"]
    tx = texels(prep.table, sp, prep.clusters[0].spec.n_layers, (n_u, n_t), db.alpha.shape[-1])
    ref = build_maps(db, prep.table, sp, tx, thr, sc.config["render"]["neighbours"])
    re, alpha, uniform = view_maps(prep.index, db, sc.view, sc.lights, thr)
    np.testing.assert_array_equal(uniform, ref.uniform)
    np.testing.assert_allclose(np.asarray(alpha), ref.alpha, atol=2e-6)
    np.testing.assert_allclose(np.asarray(re), ref.re, atol=2e-6)
    top, bot = prep.table.hsv_sectors[:, 0], prep.table.hsv_sectors[:, 1]
    half = occ[top] != occ[bot]
    assert half.any() and not ref.uniform[half].any()
    empty_texels = ~occ[top][tx.hsv] & ~occ[bot][tx.hsv]
    assert empty_texels.any()
    assert np.all(ref.alpha[empty_texels] == 0) and np.all(np.asarray(alpha)[empty_texels] == 0)
    assert np.all(np.moveaxis(np.asarray(re), 2, -1)[empty_texels] == 0)
    full = occ[top][tx.hsv] & occ[bot][tx.hsv]
    assert np.asarray(alpha)[full].max() > 0  # the occupied ones are drawn


# ----------------------------------------------------------------------------- items 12–13 on the SH shard path

SH_DENSE = {"kernel": {"p": 16.0}, "dense": {"t_resolution": 4, "theta_v_steps": 5}}  # 96 tangents


def _bright_sky(factor):
    """The built-in sky with its coefficients scaled (an EnvLight given to the library directly; maps
    above 1e30 are already refused when read)."""
    from dataclasses import replace

    from hairlut.envlight import sky_light

    sky = sky_light(4)
    return replace(sky, coeffs=sky.coeffs * factor)


@pytest.mark.parametrize("shard", [None, "0/2"])
def test_sh_bake_and_its_shards_refuse_products_that_overflow(tmp_path, shard):
    """Cd/Cs in float32 from a light whose coefficients are finite in float64 (3e38 × the sky): the whole
    bake and a shard of it refuse with NonFiniteError naming the light, and leave no file or part behind."""
    from hairlut.shtables import bake

    out = tmp_path / "sh.h5"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no 'overflow encountered in cast' on the way
        with pytest.raises(errors.NonFiniteError, match=r"light/c[ds] is not finite in float32.*coefficients reach"):
            bake(SH_DENSE, out, light=_bright_sky(3e38 / 1.0), block=40, shard=shard)
    assert not any(p.suffix == ".h5" for p in tmp_path.rglob("*")), list(tmp_path.rglob("*"))
    bake(SH_DENSE, out, light=_bright_sky(1e3), block=40, shard=shard)  # a bright but representable light bakes


def test_sh_merge_refuses_a_part_holding_nan(tmp_path):
    """``bake sh_tables --shard K/N`` then ``merge``: a shard whose Rs holds NaN is refused, naming the file."""
    from hairlut.bake import registry

    shards = [
        registry.bake("sh_tables", SH_DENSE, tmp_path / f"s{k}.h5", shard=f"{k}/2", options={"block": 40})["out"]
        for k in range(2)
    ]
    with h5py.File(shards[1], "r+") as f:
        rs = f["dense/rs"][()]
        rs[0, 0, 0, 0] = np.nan
        f["dense/rs"][...] = rs
    with pytest.raises(errors.CorruptAssetError, match=r"s1\.h5.*'dense/rs' holds non-finite values"):
        registry.merge(shards, tmp_path / "merged.h5")
    assert not (tmp_path / "merged.h5").exists()
    res = CliRunner().invoke(cli, ["merge", "--out", str(tmp_path / "cli.h5"), *map(str, shards)])
    assert res.exit_code == 2 and "non-finite" in res.output and len(res.output.strip().splitlines()) == 1, res.output


# ----------------------------------------------------------------------------- item 15: the key the user set is named

BAD_VALUES = [
    -1,
    0,
    1e300,
    -1e300,
    float("nan"),
    float("inf"),
    "zzz",
    [],
    [1e300, 1e300, 1e300],
    True,
    {},
    [0, 0, 0],
    [-1, -1],
    [10**9, 10**9],
    10**12,
]


def _named(fn, key):
    """'ok' or 'named' when ``fn()`` passes or raises a hairlut error naming ``key``, else what it did."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # an overflow on the way is a fault too
            fn()
        return "ok"
    except errors.ValidationError as exc:
        return "named" if exc.field == key or exc.field.startswith((key + "[", key + ".")) else f"names {exc.field}: {exc}"
    except errors.AssetNotFoundError as exc:  # environment.map = 'zzz': the file it resolves to is named
        return "named" if "zzz" in str(exc) else repr(exc)
    except Exception as exc:
        return f"{type(exc).__name__}: {exc}"


def test_every_bad_scene_key_is_named():
    from hairlut.scene import resolve_scene
    from hairlut.scene._camera import CAMERA
    from hairlut.scene._schema import CLUSTER, SCHEMA

    faults = {}
    for section, fields in {**SCHEMA, "camera": CAMERA}.items():
        for key in fields:
            for value in BAD_VALUES + [[1e308, 1e308, 1e308]]:
                s = scene()
                s[section] = {**s.get(section, {}), key: value}
                if section == "shadows" and key != "method":
                    s[section]["method"] = "opacity_maps" if key == "slices" else "light_oriented"
                if section == "camera" and key in ("position", "look_at"):
                    s[section]["look_at" if key == "position" else "position"] = [-1e308, -1e308, -1e308]
                res = _named(lambda s=s: resolve_scene(s), f"{section}.{key}")
                if res not in ("ok", "named") and not res.startswith("names camera.position"):  # the pair's rule
                    faults[f"{section}.{key}={value!r}"] = res
    for key in CLUSTER:
        for value in BAD_VALUES:
            s = scene()
            for c in s["clusters"]:  # every cluster, so that the structure check across clusters is not what fails
                c[key] = value
            res = _named(lambda s=s: resolve_scene(s), f"clusters[0].{key}")
            if res not in ("ok", "named"):
                faults[f"clusters[*].{key}={value!r}"] = res
    assert not faults, faults


def _dotted(schema, prefix=""):
    for key, value in schema.items():
        yield from _dotted(value, f"{prefix}{key}.") if isinstance(value, dict) else [prefix + key]


def _nest(dotted, value):
    out = node = {}
    *head, last = dotted.split(".")
    for key in head:
        node[key] = node = {}
    node[last] = value
    return out


@pytest.mark.parametrize("kind", ["hrir", "shtables", "scenemaps"])
def test_every_bad_recipe_key_is_named(kind):
    """Each recipe key with each bad value: accepted, or an error naming that key (kernel.p = 1e300 used to
    name bands.light_specular, the band count the auto rule derives from it)."""
    import importlib

    mod = importlib.import_module(f"hairlut.{kind}")
    faults = {}
    for key in _dotted(mod.SCHEMA):
        for value in BAD_VALUES + [[1e-300, 1e-300], 1e-300]:
            res = _named(lambda: mod.resolve_recipe(_nest(key, value)), key)
            if res not in ("ok", "named"):
                faults[f"{key}={value!r}"] = res
    assert not faults, faults


def test_sh_exponent_beyond_the_band_rule_names_kernel_p():
    from hairlut.shtables import resolve_recipe

    with pytest.raises(errors.ValidationError, match=r"kernel\.p=1e\+300.*p ≤ 4096") as info:
        resolve_recipe({"kernel": {"p": 1e300}})
    assert info.value.field == "kernel.p"
    assert resolve_recipe({"kernel": {"p": 4096.0}})["bands"]["light_specular"] == 65
    assert resolve_recipe({"kernel": {"p": 1e6}, "bands": {"light_specular": 8}})["bands"]["light_specular"] == 8


def test_cluster_sector_counts_are_budgeted_naming_the_key():
    from hairlut.scene import resolve_scene

    s = scene()
    for c in s["clusters"]:
        c["s_u"] = 10**9
    with pytest.raises(errors.BudgetError, match=r"clusters\[0\]\.s_u=1000000000.*TiB.*sectors") as info:
        resolve_scene(s)
    assert info.value.field == "clusters[0].s_u"


# ----------------------------------------------------------------------------- item 15: p_I = 1e300


def test_huge_exponent_is_one_line_at_the_cli_without_an_overflow_warning(tmp_path):
    from hairlut.scene import resolve_scene

    from .test_plan import _write_toml

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(errors.ValidationError, match=r"material\.p_I=1e\+300: at most 1e\+06"):
            resolve_scene(scene(p_I=1e300))
    path = _write_toml(tmp_path / "scene.toml", scene(p_I=1e300))
    for args in (["plan", str(path), "--cache", str(tmp_path / "c")], ["synth", str(path), "--out", str(tmp_path / "o")]):
        res = CliRunner().invoke(cli, args)
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert res.exit_code == 2 and len(lines) == 1 and "material.p_I=1e+300" in lines[0], res.output
        assert "Warning" not in res.output


def test_the_largest_exponent_renders_finite_without_warnings(db):
    from hairlut.synth import synthesize

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = synthesize(scene(p_I=1e6, p_II=1e6), db)
    for c in res.clusters:
        assert np.isfinite(c.final).all() and np.isfinite(c.lighting).all()


# ----------------------------------------------------------------------------- items 8 and 10 at the command line

TINY_HRIR = [
    "--set",
    "sectors.count=12",
    "--set",
    "sectors.grid=[8, 8]",
    "--set",
    "angles.views=4",
    "--set",
    "angles.lights=3",
    "--set",
    "trace.pixels=8",
    "--set",
    "trace.steps=12",
    "--block",
    "2",
]


def _limit_file_size(nbytes):
    import resource

    def apply():
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))

    return apply


@pytest.mark.slow
@pytest.mark.parametrize("kind, args", [("hrir", TINY_HRIR), ("sh", ["--p", "9", "--set", "dense.t_resolution=8"])])
def test_full_disk_during_a_cli_bake_is_one_line_and_exit_2(tmp_path, hairlut_exe, kind, args):
    """`hairlut bake hrir` / `bake sh` with a file-size limit (EFBIG, what a full disk's ENOSPC gives): one line,
    exit 2, no segfault, nothing under the final name."""
    import signal
    import subprocess

    out = tmp_path / "X.h5"
    res = subprocess.run(
        [hairlut_exe, "bake", kind, *args, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=_limit_file_size(24_000),
    )
    assert res.returncode == 2 and res.returncode != -signal.SIGSEGV, res.stderr[-3000:]
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("hairlut: error:")]
    assert len(lines) == 1 and "Traceback" not in res.stderr and "cannot write" in lines[0], res.stderr[-3000:]
    assert not out.exists() and not list(tmp_path.glob("*.tmp"))


@pytest.mark.slow
def test_two_cli_bakes_of_one_output_started_1_5_s_apart(tmp_path, hairlut_exe):
    """Item 10 as filed: the second `bake hrir --out X` starts 1.5 s after the first; both succeed (the second
    waits on the output's lock, then reuses or resumes) and the file is the one-shot bake's."""
    import subprocess
    import time

    out = tmp_path / "X.h5"
    cmd = [hairlut_exe, "bake", "hrir", *TINY_HRIR, "--out", str(out), "--json"]
    first = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.5)
    second = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    outs = [p.communicate(timeout=600) for p in (first, second)]
    assert [p.returncode for p in (first, second)] == [0, 0], [o[1][-2000:] for o in outs]
    assert all("no such file" not in o[1].lower() for o in outs)
    one = tmp_path / "one.h5"
    assert subprocess.run([hairlut_exe, "bake", "hrir", *TINY_HRIR, "--out", str(one)], capture_output=True).returncode == 0
    a, b = read_table(out), read_table(one)
    for name in ("alpha", "reflectance", "density"):
        np.testing.assert_array_equal(a[name], b[name])
    assert not (tmp_path / "X.h5.parts").exists()


def test_sh_exponent_whose_quadrature_would_not_fit_is_budgeted():
    from hairlut.shtables import resolve_recipe

    with pytest.raises(errors.BudgetError, match=r"kernel\.p=1000000000000\.0.*TiB.*quadrature") as info:
        resolve_recipe({"kernel": {"p": 1e12}, "bands": {"light_specular": 8}})
    assert info.value.field == "kernel.p"


def test_sh_compact_tables_that_are_not_finite_are_refused(tmp_path, monkeypatch):
    """The compact tables (the unsharded bake and every shard start from them) are checked before anything is
    written: a NaN in the Gaunt tensor (injected) is refused naming kernel.p and the band counts."""
    import hairlut.shtables._bake as sh_bake
    from hairlut.shtables import SHTables, bake

    real = sh_bake.bake_compact

    def poisoned(recipe):
        tables, info = real(recipe)
        gaunt = np.array(tables.gaunt)
        gaunt[0, 0, 0] = np.nan
        return SHTables(tables.bands, tables.p, tables.kd_l, tables.ks_cheb, gaunt, tables.recipe), info

    monkeypatch.setattr(sh_bake, "bake_compact", poisoned)
    sh_bake._compact.cache_clear()
    try:
        with pytest.raises(errors.NonFiniteError, match=r"gaunt is not finite for kernel\.p=5\.0, bands\.light_specular=4"):
            bake({"kernel": {"p": 5.0}}, tmp_path / "sh.h5")
    finally:
        sh_bake._compact.cache_clear()
    assert not list(tmp_path.iterdir())
