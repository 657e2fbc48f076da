"""Issue 29's asset-integrity defects, each reproduced as the issue gives it (m8 is in test_virtual_read.py, m10 in
test_cache.py):

* N7: parts of a virtual asset swapped by renaming are refused by every reader, naming the part and both ranges
  (the range the part declares, the slot the asset maps it to), for every table kind;
* N8: readers open only regular files: a FIFO standing for the asset, a part, a groom, a scene or a recipe is
  refused before anything opens it (no hang), as are folders and devices;
* m2: an output path that is one of the inputs (``compare --png``, ``merge --out``) is refused, the input intact.
"""

import contextlib
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets import h5 as store
from hairlut.assets import open_table, read_exr, read_table, summarize
from hairlut.assets.layout import layout
from hairlut.assets.parts import parts_dir
from hairlut.assets.virtual_write import check_virtual
from hairlut.bake import registry
from hairlut.files import not_an_input, regular_file
from hairlut.hrir import bake, load_hrir_db
from hairlut_cli.main import cli

from ._tables import lobes_table
from .test_distributed_bake import split_cases

SMALL = {"sectors": {"count": 12, "grid": [8, 8]}, "angles": {"views": 3, "lights": 2}, "trace": {"pixels": 4, "steps": 4}}


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def one_line_error(res, *words):
    """The CLI's refusal: exit status 2, one line, naming each of ``words``."""
    assert res.exit_code == 2, res.output
    assert len(res.output.strip().splitlines()) == 1 and res.output.startswith("hairlut: error:"), res.output
    for w in words:
        assert str(w) in res.output, (w, res.output)


@pytest.fixture(scope="module")
def virtual_db(tmp_path_factory):
    out = tmp_path_factory.mktemp("vdb") / "V.h5"
    bake(SMALL, out, block=5, merge="virtual")  # parts of sectors [0, 5), [5, 10) and a last one [10, 12)
    return out


def _copy_asset(src: Path, where: Path) -> Path:
    """The virtual asset ``src`` and its parts folder copied under the same name into ``where``."""
    where.mkdir()
    (where / src.name).write_bytes(src.read_bytes())
    parts = parts_dir(where / src.name)
    parts.mkdir()
    for p in parts_dir(src).iterdir():
        (parts / p.name).write_bytes(p.read_bytes())
    return where / src.name


def _swap(a: Path, b: Path) -> None:
    tmp = a.with_name("swap.tmp")
    a.rename(tmp)
    b.rename(a)
    tmp.rename(b)


# ----------------------------------------------------------------------------- N7: parts checked against their slot


def test_swapped_parts_are_refused_by_every_reader_naming_the_part_and_both_ranges(virtual_db, tmp_path):
    out = _copy_asset(virtual_db, tmp_path / "swapped")
    first, second = (parts_dir(out) / f"part-12x5-{b}.h5" for b in (0, 1))
    good = load_hrir_db(out).reflectance
    _swap(first, second)  # the reproduction: the rows now belong to other sectors
    said = ("sector [5, 10)", "sector [0, 5)")  # what the part at block 0 declares, and its slot

    for reader in (check_virtual, load_hrir_db, read_table, summarize):
        with pytest.raises(errors.CorruptAssetError) as exc:
            reader(out)
        assert exc.value.path == str(first) and all(s in str(exc.value) for s in said), (reader, exc.value)
    one_line_error(invoke("inspect", out), first, *said)
    with pytest.raises(errors.CorruptAssetError, match=r"sector \[5, 10\).*sector \[0, 5\)"):
        with open_table(out):  # every reader's validation, HDF5's own virtual read included
            pass
    with h5py.File(out, "r") as f:  # and read_virtual, were it called without that validation
        with pytest.raises(errors.CorruptAssetError, match=r"sector \[5, 10\)"):
            store.read_virtual(out, f, layout(f)[1])

    _swap(first, second)  # each part back under its own name: read, the same rows as before
    assert load_hrir_db(out).reflectance.tobytes() == good.tobytes()


def test_a_part_that_declares_no_range_is_refused(virtual_db, tmp_path):
    out = _copy_asset(virtual_db, tmp_path / "bare")
    part = parts_dir(out) / "part-12x5-1.h5"
    with h5py.File(part, "r+") as f:
        del f.attrs["sector_start"]
    with pytest.raises(errors.CorruptAssetError, match="declares no sector range") as exc:
        load_hrir_db(out)
    assert exc.value.path == str(part) and "[5, 10)" in str(exc.value)


@pytest.mark.parametrize("kind", ["hair_bsdf", "hrir_db", "scene_maps", "sh_tables"])
def test_every_kind_refuses_its_parts_swapped(kind, tmp_path):
    """Every kind's parts declare their range along the axis the tables split (``<axis>_start``, ``_stop``)."""
    assert sorted(registry.kinds()) == ["hair_bsdf", "hrir_db", "scene_maps", "sh_tables"]
    recipe, options, _ = split_cases()[kind]
    out = tmp_path / "v.h5"
    registry.bake(kind, recipe, out, options=options, merge="virtual")
    parts = sorted(parts_dir(out).glob("part-*.h5"))
    assert len(parts) >= 3
    load = registry.get(kind).load
    load(out)
    _swap(parts[0], parts[1])  # two whole blocks: the same shapes
    with pytest.raises(errors.CorruptAssetError, match="maps it to") as exc:
        load(out)
    assert exc.value.path == str(parts[0])
    one_line_error(invoke("inspect", out), parts[0], "maps it to")
    _swap(parts[0], parts[1])
    load(out)


# ----------------------------------------------------------------------------- N8: regular files only


#: Opens each FIFO of argv for writing whenever a reader holds it open (a reader blocked in its open, or in HDF5's,
#: which holds the GIL, goes on and sees end of file) and prints it: a separate process, so no reader can starve it.
_WATCH = """
import os, sys, time
while True:
    for path in sys.argv[1:]:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)  # succeeds only while a reader holds the FIFO open
        except OSError:
            continue
        print(path, flush=True)
        os.close(fd)
    time.sleep(0.002)
"""


@contextlib.contextmanager
def fifo_never_opened(*paths):
    """Make FIFOs at ``paths`` and watch them from another process: a reader that opens one (and would block
    there) is let through at once and the open recorded, so that a defect fails the test rather than hanging it.
    Yields the list of FIFOs opened, filled when the block ends."""
    for path in paths:
        os.mkfifo(path)
    opened: list = []
    watcher = subprocess.Popen([sys.executable, "-c", _WATCH, *map(str, paths)], stdout=subprocess.PIPE, text=True)
    try:
        yield opened
    finally:
        watcher.terminate()
        opened += watcher.communicate(timeout=60)[0].split()


def _refuses(fn, path, error=errors.FormatError):
    with pytest.raises(error, match="not a regular file") as exc:
        fn(path)
    assert exc.value.path == str(path)


def test_a_fifo_as_the_asset_is_refused_before_it_is_opened(tmp_path):
    table, image = tmp_path / "f.h5", tmp_path / "f.exr"
    with fifo_never_opened(table, image) as opened:
        for fn in (read_table, summarize, check_virtual, load_hrir_db, lambda p: open_table(p).__enter__()):
            _refuses(fn, table)
        _refuses(read_exr, image)
        one_line_error(invoke("inspect", table), table, "not a regular file (a FIFO)")
        one_line_error(invoke("inspect", image), image, "not a regular file")
        one_line_error(invoke("compare", image, image), image, "not a regular file")
    assert not opened


def test_a_fifo_standing_for_a_part_is_refused(virtual_db, tmp_path):
    out = _copy_asset(virtual_db, tmp_path / "fifo")
    part = parts_dir(out) / "part-12x5-1.h5"
    part.unlink()
    with fifo_never_opened(part) as opened:
        with pytest.raises(errors.CorruptAssetError, match="not a regular file") as exc:
            load_hrir_db(out)
        assert exc.value.path == str(part)
        one_line_error(invoke("inspect", out), part, "not a regular file (a FIFO)")
        with pytest.raises(errors.ForeignReferenceError, match="not a regular file"):
            read_table(out)
    assert not opened


def test_a_fifo_groom_scene_or_recipe_is_refused(tmp_path):
    from hairlut.geometry import read_strands
    from hairlut.recipes import load_toml
    from hairlut.scene import load_scene

    grooms = [tmp_path / f"g.{ext}" for ext in ("hair", "tfx", "usda")]
    scene_file, recipe_file = tmp_path / "s.toml", tmp_path / "r.toml"
    with fifo_never_opened(*grooms, scene_file, recipe_file) as opened:
        for groom in grooms:
            _refuses(read_strands, groom)
        _refuses(load_scene, scene_file)
        _refuses(load_toml, recipe_file)
        one_line_error(invoke("bake", "hrir", "--recipe", recipe_file, "--out", tmp_path / "x.h5"), recipe_file)
        one_line_error(invoke("strands", "info", grooms[0]), grooms[0], "not a regular file")
        on_disk = tmp_path / "scene.toml"  # the Sintel scene, its groom a FIFO
        text = (Path(__file__).parents[1] / "tables" / "scenes" / "sintel-groom.toml").read_text()
        on_disk.write_text(text.replace('path = "../grooms/sintel_lite.tfx"', f'path = "{grooms[1].name}"'))
        with pytest.raises(errors.FormatError, match="not a regular file") as exc:
            load_scene(on_disk)
        assert exc.value.path == str(grooms[1])
    assert not opened


@pytest.mark.parametrize("what", ["folder", "device"])
def test_folders_and_devices_are_refused(tmp_path, what):
    path = tmp_path if what == "folder" else Path("/dev/null")
    for fn in (read_table, summarize, read_exr, load_hrir_db, regular_file):
        with pytest.raises(
            errors.FormatError, match=f"not a regular file \\(a {'folder' if what == 'folder' else 'character device'}\\)"
        ):
            fn(path)
    res = invoke("inspect", path)
    assert res.exit_code == 2 and str(path) in res.output  # a folder: click's own usage error


# ----------------------------------------------------------------------------- m2: an output is never an input


def test_compare_refuses_to_write_its_png_over_an_input(tmp_path):
    from hairlut.recipes import resolve
    from hairlut.render import Frame, write_frame
    from hairlut.scene import CAMERA, make_camera

    rng = np.random.default_rng(3)
    cam = make_camera(resolve(CAMERA, {"view": [0.0, 0.0, 1.0], "resolution": [16, 16]}, "camera."), rng.normal(size=(9, 3)))
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    for path, scale in ((a, 1.0), (b, 0.5)):
        rgba = np.concatenate([rng.uniform(0, scale, (16, 16, 3)), np.ones((16, 16, 1))], -1).astype(np.float32)
        write_frame(Frame(rgba, np.ones((16, 16), np.float32), cam), path)
    before = a.read_bytes(), b.read_bytes()
    os.link(a, tmp_path / "also-a.exr")
    for target in (a, b, tmp_path / "also-a.exr", tmp_path / "." / "a.exr"):
        one_line_error(invoke("compare", a, b, "--png", target), "png=", "is the input")
    one_line_error(invoke("inspect", a, "--png", a), "png=", "is the input")  # the same fault in inspect
    assert (a.read_bytes(), b.read_bytes()) == before
    assert invoke("compare", a, b, "--png", tmp_path / "d.png").exit_code == 0


def test_merge_refuses_to_write_over_a_shard(tmp_path):
    shards = [tmp_path / f"s{k}.h5" for k in range(2)]
    for k, s in enumerate(shards):
        bake(SMALL, s, shard=f"{k}/2", block=5)
    before = [s.read_bytes() for s in shards]
    for out in shards:
        one_line_error(invoke("merge", *shards, "--out", out), "out=", str(out), "is the input")
    with pytest.raises(errors.ValidationError, match="is the input"):
        registry.merge(shards, shards[1])
    assert [s.read_bytes() for s in shards] == before
    assert invoke("merge", *shards, "--out", tmp_path / "m.h5").exit_code == 0


def test_not_an_input_compares_files_not_spellings(tmp_path):
    a = lobes_table(tmp_path / "a.h5")[0]
    os.symlink(a, tmp_path / "link.h5")
    for same in (a, tmp_path / "link.h5", f"{tmp_path}/./a.h5"):
        with pytest.raises(errors.ValidationError):
            not_an_input(same, [a])
    not_an_input(tmp_path / "b.h5", [a])  # another file, not there yet
    not_an_input(None, [a])
