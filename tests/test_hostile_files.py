"""Hostile and inconsistent HDF5 files (issue 14, items 1–5): typed errors naming file and fault.

Each case is crafted the way the issue describes it, on a real table written by hairlut,
and read through read_table, summarize (inspect), the CLI and the kind loaders.
"""

import json
import os
import select
import signal
import time
import traceback

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from cli.main import cli
from hairlut import errors
from hairlut.assets import allowed_virtual_sources, read_table, recipe_hash, summarize
from hairlut.assets.preview import preview
from hairlut.hrir import bake as bake_hrir
from hairlut.hrir import load_hrir_db
from hairlut.shtables import SHTables, bake_sh, write_sh_tables

from ._tables import lobes_table

SMALL_HRIR = {"sectors": {"count": 6, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3},
              "trace": {"pixels": 8, "steps": 12}}


@pytest.fixture(scope="module")
def sh_file(tmp_path_factory):
    res = bake_sh({"kernel": {"p": 9.0}, "bands": {"light_diffuse": 2, "transmittance": 2}})
    return write_sh_tables(tmp_path_factory.mktemp("sh") / "sh.h5", res["tables"], res["info"])


@pytest.fixture(scope="module")
def hrir_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("hrir") / "db.h5"
    bake_hrir(SMALL_HRIR, out, block=6)
    return out


def copy(src, dst):
    dst.write_bytes(open(src, "rb").read())
    return dst


def poke(path, fn):
    with h5py.File(path, "r+") as f:
        fn(f)
    return path


def set_recipe(f, recipe_text):
    """Replace the stored recipe and make its hash consistent (the checksum passes)."""
    f.attrs["recipe"] = recipe_text
    f.attrs["recipe_hash"] = recipe_hash(recipe_text)


def cli_fails(*args):
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("hairlut: error:"), res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    return lines[0]


# ----------------------------------------------------------------------------- item 1: flipped metadata bits


CHILD_SECONDS = 5  # per offset: a child that computes this long (CPU seconds) without a result is stuck in HDF5
CHILD_WALL_SECONDS = 60  # ... or that reports nothing for this long at all (a loaded machine slows every child)


def _cpu_seconds(pid):
    """CPU time a child has used (Linux /proc); None where that cannot be read."""
    try:
        fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


BATCH = 64  # offsets per forked child; a fork of the test process costs more than reading one small file


def _child(raw, probe_dir, offs, readers, w):  # pragma: no cover (runs in the forked child)
    """Read each flipped file in turn, writing one JSON line of outcomes per offset as soon as it is known."""
    import gc

    gc.freeze()  # the parent's heap is never collected here: no copy-on-write of it, no time spent on it
    for off in offs:
        b = bytearray(raw)
        b[off] ^= 0xFF
        probe = probe_dir / f"flipped-{off}.h5"  # a name of its own: no open handle of an earlier probe aliases it
        probe.write_bytes(bytes(b))
        res = []
        for fn in readers:
            try:
                fn(probe)
                res.append("ok")
            except errors.HairlutError:
                res.append("typed")
            except BaseException as exc:  # noqa: BLE001
                res.append("".join(traceback.format_exception_only(exc)).strip()[-300:])
        probe.unlink()
        os.write(w, (json.dumps([off, res]) + "\n").encode())
    os._exit(0)


def _stuck(pid, since, cpu_then):
    """No result for CHILD_SECONDS of the child's own CPU time (wall time where /proc is missing), or for
    CHILD_WALL_SECONDS of wall time: on a loaded machine a slow child is not taken for a hang."""
    waited = time.monotonic() - since
    cpu_now = _cpu_seconds(pid)
    if cpu_then is None or cpu_now is None:
        return waited > CHILD_SECONDS
    return cpu_now - cpu_then > CHILD_SECONDS or waited > CHILD_WALL_SECONDS


def _run_child(raw, probe_dir, offs, readers):
    """Fork one child for ``offs``; return ({offset: outcomes} it reported, the offset it died or hung at, how)."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover (child)
        os.close(r)
        _child(raw, probe_dir, offs, readers, w)
    os.close(w)
    got, buf, fail = {}, b"", None
    last, last_cpu = time.monotonic(), _cpu_seconds(pid)
    while True:
        ready, _, _ = select.select([r], [], [], 0.05)
        if ready:
            chunk = os.read(r, 65536)
            if not chunk:
                break  # the child exited, or died
            buf += chunk
            *lines, buf = buf.split(b"\n")
            for line in lines:
                off, res = json.loads(line)
                got[off] = res
            last, last_cpu = time.monotonic(), _cpu_seconds(pid)
        elif _stuck(pid, last, last_cpu):
            os.kill(pid, signal.SIGKILL)
            fail = "hang"
            break
    os.close(r)
    os.waitpid(pid, 0)
    if len(got) < len(offs) and fail is None:
        fail = "native crash"
    return got, (offs[len(got)] if fail else None), fail


def _outcomes_of_flips(path, readers, step, offsets=None):
    """Flip one byte at every ``step``-th offset and read the file with each reader, in forked children (HDF5
    itself may crash or loop). Each outcome is the one a child of its own per offset gives: a child reads
    BATCH flipped files in turn, and where it crashes or hangs, that offset is read again alone in a fresh
    child (so a crash is never blamed on the wrong offset) and the rest of the batch goes on in another."""
    raw = bytes(path.read_bytes())
    probe_dir = path.parent
    todo = list(range(0, len(raw), step) if offsets is None else offsets)
    outcomes = {}
    while todo:
        batch, todo = todo[:BATCH], todo[BATCH:]
        got, bad, how = _run_child(raw, probe_dir, batch, readers)
        outcomes.update({int(k): v for k, v in got.items()})
        if bad is not None:
            alone, _, how_alone = _run_child(raw, probe_dir, [bad], readers) if len(got) else (got, None, how)
            outcomes[bad] = alone[bad] if bad in alone else [how_alone] * len(readers)
            todo = batch[len(got) + 1:] + todo
    return {off: outcomes[off] for off in sorted(outcomes)}


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
@pytest.mark.parametrize("which, step", [
    ("table", 211), ("sh", 97), ("hrir", 397),
    # denser sweeps, in CI: every 5th, 3rd and 3rd offset of the full sweeps (steps 11, 13, 41) once measured
    # offline with 0 untyped outcomes; the full sweeps take ~20 minutes on 2 cores
    pytest.param("table", 55, marks=pytest.mark.slow), pytest.param("sh", 39, marks=pytest.mark.slow),
    pytest.param("hrir", 123, marks=pytest.mark.slow),
])
def test_flipped_metadata_bits_give_typed_errors(tmp_path, which, step, sh_file, hrir_file):
    """Every flip that HDF5 survives gives ok or a hairlut error: no KeyError, OSError, ValueError ... tracebacks.

    A few flips make the HDF5 C library itself crash (double free) or loop while it
    reads a variable-length attribute; no Python code can catch those (see
    hairlut.assets.trust), so they are only counted and kept rare here."""
    if which == "table":
        path, readers = lobes_table(tmp_path / "t.h5")[0], (read_table, summarize)
    elif which == "sh":
        path, readers = copy(sh_file, tmp_path / "sh.h5"), (SHTables.load, summarize)
    else:
        path, readers = copy(hrir_file, tmp_path / "db.h5"), (load_hrir_db,)
    outcomes = _outcomes_of_flips(path, readers, step)
    native = ("native crash", "hang")
    untyped = {off: r for off, res in outcomes.items() for r in res if r not in ("ok", "typed", *native)}
    assert not untyped, untyped
    typed = sum(r == "typed" for res in outcomes.values() for r in res)
    lost = sum(res[0] in native for res in outcomes.values())
    assert typed > len(outcomes) // 10  # the sweep does reach metadata
    assert lost <= max(2, len(outcomes) // 50)  # HDF5's own crashes and loops stay rare


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_metadata_fault_is_one_line_at_the_cli(tmp_path):
    path = lobes_table(tmp_path / "t.h5")[0]
    raw = bytearray(path.read_bytes())
    near = raw.find(b"specular")  # the root group's link names the object; flips around it break metadata
    assert near > 0
    outcomes = _outcomes_of_flips(path, (summarize,), 1, range(max(0, near - 48), near + 48))
    typed = [off for off, res in outcomes.items() if res == ["typed"]]
    assert typed, outcomes
    for off in typed[:3]:
        b = bytearray(raw)
        b[off] ^= 0xFF
        bad = tmp_path / f"flip{off}.h5"
        bad.write_bytes(bytes(b))
        assert str(bad) in cli_fails("inspect", "--json", bad)


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


@pytest.mark.parametrize("text", ["{not json", "[1, 2]", "\"a string\"", "NaN"])
def test_recipe_that_is_not_a_json_object(tmp_path, text, sh_file):
    path = poke(lobes_table(tmp_path / "t.h5")[0], lambda f: set_recipe(f, text))
    for fn in (read_table, summarize):
        with pytest.raises(errors.CorruptAssetError, match="'recipe'"):
            fn(path)
    assert "recipe" in cli_fails("inspect", "--json", path)
    sh = poke(copy(sh_file, tmp_path / "sh.h5"), lambda f: set_recipe(f, text))
    with pytest.raises(errors.CorruptAssetError, match="'recipe'"):
        SHTables.load(sh)


@pytest.mark.parametrize("names", ["rho_st, rho_s", "[1, 2, 3]", "[\"a\", \"b\", \"c\"]"])
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


def _virtual(path, source, dset="specular", shape=(2, 33, 17)):
    def add(f):
        lay = h5py.VirtualLayout(shape=shape, dtype="f4")
        lay[...] = h5py.VirtualSource(str(source), dset, shape=shape)
        f.create_virtual_dataset("ext", lay, fillvalue=0)
    return poke(path, add)


def test_virtual_dataset_pointing_elsewhere_is_refused(tmp_path):
    other = lobes_table(tmp_path / "other.h5")[0]  # same recipe, but not one of the asset's parts
    path = _virtual(lobes_table(tmp_path / "t.h5")[0], other)
    for fn in _readers(path):
        with pytest.raises(errors.ForeignReferenceError, match="'ext' is virtual.*parts folder"):
            fn(path)
    cli_fails("inspect", path)


def test_virtual_dataset_over_the_assets_own_parts_is_allowed(tmp_path):
    path = lobes_table(tmp_path / "t.h5")[0]
    parts = tmp_path / "t.h5.parts"
    parts.mkdir()
    part = lobes_table(parts / "part-0.h5")[0]
    with h5py.File(path, "r") as f:
        digest = f.attrs["recipe_hash"]
    assert allowed_virtual_sources(path, digest) == [part]
    _virtual(path, "t.h5.parts/part-0.h5")
    t = read_table(path)
    np.testing.assert_array_equal(t["ext"], read_table(part)["specular"])
    assert summarize(path)["datasets"][-1]["name"] == "ext"

    foreign = lobes_table(parts / "part-1.h5", recipe={"other": 1})[0]  # another recipe hash
    assert allowed_virtual_sources(path, digest) == [part]
    poke(path, lambda f: f.__delitem__("ext"))
    _virtual(path, "t.h5.parts/part-1.h5")
    with pytest.raises(errors.ForeignReferenceError, match="another recipe hash"):
        read_table(path)
    poke(path, lambda f: f.__delitem__("ext"))
    os.symlink(part, parts / "part-2.h5")
    _virtual(path, "t.h5.parts/part-2.h5")
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


@pytest.mark.parametrize("changes, table", [
    ({"bands__light_specular": 9}, "gaunt"),
    ({"bands__transmittance": 4}, "gaunt"),
    ({"bands__light_diffuse": 5}, "gaunt"),
    ({"bands__light_specular": 200}, "bands.light_specular"),
    ({"kernel__p": -1.0}, "kernel.p"),
    ({"kernel__diffuse": "yes"}, "kernel.diffuse"),
    ({"bands": None}, "bands"),
])
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


@pytest.mark.parametrize("changes, table", [
    ({"angles__views": 5}, "alpha"),
    ({"angles__lights": 7}, "reflectance"),
    ({"trace__pixels": 16}, "alpha"),
    ({"sectors__grid": [8, 9]}, "density"),
    ({"sectors__features": "moments"}, "feature_names"),
    ({"angles__views": 0}, "angles.views"),
])
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
