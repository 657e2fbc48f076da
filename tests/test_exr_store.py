"""OpenEXR images: round trips (layered, multi-part, half), foreign files, bad files."""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from hairlut import errors
from hairlut.assets import ExrPart, read_exr, recipe_hash, write_exr


@pytest.fixture
def image(rng):
    h, w = 24, 40
    return {
        "R": rng.random((h, w)).astype(np.float32),
        "G": rng.random((h, w)).astype(np.float32),
        "B": rng.random((h, w)).astype(np.float32),
        "A": rng.random((h, w)).astype(np.float16),
        "layer0.re": rng.random((h, w)).astype(np.float32),
        "layer0.A": rng.random((h, w)).astype(np.float16),
    }


@pytest.mark.parametrize("compression", ["zip", "piz"])
def test_round_trip_layered(tmp_path, image, compression):
    recipe = {"exposure": 1.5, "layers": ["layer0"]}
    write_exr(tmp_path / "a.exr", image, recipe=recipe, kind="test_image", compression=compression)
    im = read_exr(tmp_path / "a.exr", kind="test_image")
    assert im.checksum == "verified"
    assert im.recipe == recipe and im.recipe_hash == recipe_hash(recipe)
    assert len(im.parts) == 1
    for name, arr in image.items():
        got = im.channel(name)
        assert got.dtype == arr.dtype, name
        np.testing.assert_array_equal(got, arr)
    assert compression.upper() in im.parts[0].header["compression"]


def test_float64_input_is_stored_as_float32_or_half(tmp_path, rng):
    y = rng.random((5, 7))
    write_exr(tmp_path / "f.exr", {"Y": y})
    np.testing.assert_array_equal(read_exr(tmp_path / "f.exr").channel("Y"), y.astype(np.float32))
    write_exr(tmp_path / "h.exr", {"Y": y}, pixel_type="half")
    got = read_exr(tmp_path / "h.exr").channel("Y")
    assert got.dtype == np.float16
    np.testing.assert_array_equal(got, y.astype(np.float16))


def test_multi_part_of_different_sizes(tmp_path, rng):
    big = {"R": rng.random((30, 20)), "G": rng.random((30, 20)), "B": rng.random((30, 20))}
    small = {"Y": rng.random((4, 9)).astype(np.float16)}
    write_exr(tmp_path / "m.exr", [ExrPart("beauty", big), ExrPart("mask", small)], recipe={"k": 1})
    im = read_exr(tmp_path / "m.exr")
    assert [p.name for p in im.parts] == ["beauty", "mask"]
    assert im.part("beauty").shape == (30, 20) and im.part("mask").shape == (4, 9)
    np.testing.assert_array_equal(im.channel("Y", part="mask"), small["Y"])
    np.testing.assert_array_equal(im.channel("G", part="beauty"), big["G"].astype(np.float32))
    assert im.checksum == "verified" and im.recipe == {"k": 1}
    with pytest.raises(errors.MissingDatasetError, match="no part named 'depth'"):
        im.part("depth")
    with pytest.raises(errors.MissingDatasetError, match="no channel 'Z'"):
        im.channel("Z", part="mask")


@pytest.mark.parametrize(
    "image, field",
    [
        ({"R": np.ones((2, 2)), "G": np.ones((3, 2))}, "channels['G'].shape"),
        ({"R": np.ones((2, 2), np.int32)}, "channels['R'].dtype"),
        ({"bad name": np.ones((2, 2))}, "channels['bad name']"),
        ({"layer..R": np.ones((2, 2))}, "channels['layer..R']"),
        ({"R": np.ones(4)}, "channels['R'].shape"),
        ({}, "parts[''].channels"),
    ],
)
def test_writer_rejects_bad_images_and_writes_nothing(tmp_path, image, field):
    with pytest.raises(errors.ValidationError) as info:
        write_exr(tmp_path / "x.exr", image)
    assert info.value.field == field
    assert list(tmp_path.iterdir()) == []


def test_writer_rejects_lossy_compression_and_bad_parts(tmp_path):
    with pytest.raises(errors.ValidationError, match="compression"):
        write_exr(tmp_path / "x.exr", {"Y": np.ones((2, 2))}, compression="dwaa")
    with pytest.raises(errors.ValidationError, match="parts.name"):
        write_exr(tmp_path / "x.exr", [ExrPart("a", {"Y": np.ones((2, 2))}), ExrPart("a", {"Y": np.ones((1, 2))})])


# ----------------------------------------------------------------------------- foreign files


def test_reads_a_file_written_with_the_raw_binding(tmp_path, rng):
    r = rng.random((8, 6)).astype(np.float32)
    z = rng.random((8, 6)).astype(np.float16)
    header = {"compression": OpenEXR.RLE_COMPRESSION, "type": OpenEXR.scanlineimage, "owner": "someone", "n": 3}
    OpenEXR.File(header, {"R": r, "G": r, "B": r, "depth.Z": z}).write(str(tmp_path / "raw.exr"))
    im = read_exr(tmp_path / "raw.exr")
    assert im.recipe is None and im.kind is None
    assert im.checksum.startswith("not written by hairlut")
    np.testing.assert_array_equal(im.channel("depth.Z"), z)
    assert im.parts[0].header["owner"] == "someone"


def test_reads_a_file_written_by_openimageio(tmp_path, rng):
    oiio = pytest.importorskip("OpenImageIO", reason="OpenImageIO (test extra) not installed")
    pixels = rng.random((12, 16, 4)).astype(np.float16)
    spec = oiio.ImageSpec(16, 12, 4, "half")
    spec.attribute("compression", "piz")
    out = oiio.ImageOutput.create(str(tmp_path / "o.exr"))
    assert out.open(str(tmp_path / "o.exr"), spec)
    out.write_image(pixels)
    out.close()
    im = read_exr(tmp_path / "o.exr")
    for c, name in enumerate("RGBA"):
        np.testing.assert_array_equal(im.channel(name), pixels[:, :, c])
    assert "PIZ" in im.parts[0].header["compression"]


OIIOTOOL = shutil.which("oiiotool", path=str(Path(sys.executable).parent)) or shutil.which("oiiotool")


@pytest.mark.skipif(OIIOTOOL is None, reason="oiiotool (OpenImageIO test extra) not installed")
def test_reads_an_oiiotool_pattern(tmp_path):
    path = tmp_path / "ramp.exr"
    cmd = [
        OIIOTOOL,
        "--pattern",
        "fill:topleft=0,0,0:topright=1,0,0:bottomleft=0,1,0:bottomright=1,1,0",
        "33x17",
        "3",
        "-d",
        "float",
        "-o",
        str(path),
    ]
    subprocess.run(cmd, check=True, capture_output=True, timeout=60)
    im = read_exr(path)
    r = im.channel("R")
    assert r.shape == (17, 33)
    assert r.min() == pytest.approx(0.0, abs=0.02) and r.max() == pytest.approx(1.0, abs=0.02)
    assert np.all(np.diff(r[0]) > 0), "R ramps left to right"
    np.testing.assert_allclose(im.channel("B"), 0.0)


# ----------------------------------------------------------------------------- bad files


def test_missing_and_not_exr(tmp_path):
    with pytest.raises(errors.AssetNotFoundError, match="no such file"):
        read_exr(tmp_path / "none.exr")
    (tmp_path / "x.exr").write_bytes(b"\x89HDF\r\n\x1a\n....")
    with pytest.raises(errors.FormatError, match="not an OpenEXR file"):
        read_exr(tmp_path / "x.exr")


@pytest.mark.parametrize("fraction", [0.01, 0.2, 0.5, 0.8, 0.99])
def test_truncated(tmp_path, image, fraction):
    write_exr(tmp_path / "a.exr", image)
    raw = (tmp_path / "a.exr").read_bytes()
    (tmp_path / "a.exr").write_bytes(raw[: max(5, int(len(raw) * fraction))])
    with pytest.raises(errors.CorruptAssetError) as info:
        read_exr(tmp_path / "a.exr")
    assert "a.exr" in str(info.value)


@pytest.mark.parametrize("compression", ["zip", "piz"])
@pytest.mark.parametrize("back", [20, 200, 2000])
def test_flipped_byte_in_pixel_data(tmp_path, image, compression, back):
    write_exr(tmp_path / "a.exr", image, compression=compression)
    raw = bytearray((tmp_path / "a.exr").read_bytes())
    raw[len(raw) - back] ^= 0x10
    (tmp_path / "a.exr").write_bytes(bytes(raw))
    with pytest.raises(errors.CorruptAssetError):
        read_exr(tmp_path / "a.exr")


def test_tampered_recipe_and_kind(tmp_path, image):
    write_exr(tmp_path / "a.exr", image, recipe={"a": 1}, kind="test_image")
    with pytest.raises(errors.KindError, match="expected 'sh_textures'"):
        read_exr(tmp_path / "a.exr", kind="sh_textures")
    raw = (tmp_path / "a.exr").read_bytes().replace(b'{"a":1}', b'{"a":2}')
    (tmp_path / "a.exr").write_bytes(raw)
    with pytest.raises(errors.ChecksumError, match="recipe_hash"):
        read_exr(tmp_path / "a.exr")


def test_library_noise_does_not_leak(tmp_path, image, capfd):
    write_exr(tmp_path / "a.exr", image)
    raw = bytearray((tmp_path / "a.exr").read_bytes())
    raw[-100] ^= 0xFF
    (tmp_path / "a.exr").write_bytes(bytes(raw))
    with pytest.raises(errors.CorruptAssetError):
        read_exr(tmp_path / "a.exr")
    out, err = capfd.readouterr()
    assert out == "" and err == ""
