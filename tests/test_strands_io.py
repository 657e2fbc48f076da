"""Hair strand I/O: the real .tfx grooms, .hair and USD round trips, handcrafted files, bad input, the CLI."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import struct
import sys
import tempfile
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hairlut import errors
from hairlut.atomic import stale_temporaries
from hairlut.geometry import Strands, read_strands, write_strands
from hairlut_cli.main import Group
from hairlut_cli.strands import strands_group

from .conftest import GROOMS as GROOM_DIR
from .conftest import groom_path as groom

needs_pxr = pytest.mark.skipif(
    importlib.util.find_spec("pxr") is None, reason="usd-core (pxr) is not installed; USD support is an optional extra"
)


# file: (strands, vertices per strand, bbox min, bbox max), as documented in tables/grooms/README.md
GROOMS = {
    "ratboy_mohawk.tfx": (2226, 32, (-9.5, 21.4, -33.6), (11.7, 111.0, 27.1)),
    "sintel_lite.tfx": (228, 32, (-10.6, 20.7, -13.0), (9.8, 47.7, 11.7)),
}


def random_strands(rng: np.random.Generator, n: int = 7, equal: int | None = None) -> Strands:
    counts = np.full(n, equal) if equal else rng.integers(2, 12, n)
    p = int(counts.sum())
    return Strands(
        rng.normal(size=(p, 3)).astype(np.float32),
        counts,
        thickness=rng.uniform(0, 2, p).astype(np.float32),
        transparency=rng.uniform(0, 1, p).astype(np.float32),
        color=rng.uniform(0, 1, (p, 3)).astype(np.float32),
    )


def assert_same(a: Strands, b: Strands, names=("thickness", "transparency", "color", "uv", "movable"), atol=0.0) -> None:
    np.testing.assert_array_equal(a.counts, b.counts)
    np.testing.assert_array_equal(a.points, b.points)
    for name in names:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_allclose(x, y, rtol=0, atol=atol, err_msg=name)


def test_strands_helpers_on_a_known_polyline():
    s = Strands.from_list([[[0, 0, 0], [3, 4, 0], [3, 4, 12]], [[1, 1, 1], [1, 1, 2]]])
    assert (s.n_strands, s.n_points) == (2, 5)
    np.testing.assert_array_equal(s.offsets, [0, 3, 5])
    np.testing.assert_array_equal(s.segments, [[0, 1], [1, 2], [3, 4]])
    np.testing.assert_allclose(s.lengths(), [5 + 12, 1])
    np.testing.assert_array_equal(s.bbox(), [[0, 0, 0], [3, 4, 12]])
    np.testing.assert_array_equal(s.strand(-1), [[1, 1, 1], [1, 1, 2]])
    with pytest.raises(errors.ValidationError, match="as_padded"):
        s.as_padded()
    padded = np.arange(24, dtype=np.float32).reshape(2, 4, 3)
    np.testing.assert_array_equal(Strands.from_padded(padded).as_padded(), padded)
    assert Strands.from_padded(padded).points.dtype == np.float32


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(points=np.zeros((4, 3)), counts=[2, 3]), "counts"),
        (dict(points=np.zeros((4, 3)), counts=[1, 3]), "counts"),
        (dict(points=np.zeros((4, 2)), counts=[4]), "points"),
        (dict(points=np.array([[0, 0, 0], [0, np.nan, 0]]), counts=[2]), "points"),
        (dict(points=np.zeros((2, 3)), counts=[2], thickness=[1.0, -0.5]), "thickness"),
        (dict(points=np.zeros((2, 3)), counts=[2], transparency=[0.0, 1.5]), "transparency"),
        (dict(points=np.zeros((2, 3)), counts=[2], color=np.zeros((3, 3))), "color"),
        (dict(points=np.zeros((2, 3)), counts=[2], uv=np.zeros((2, 2))), "uv"),
        (dict(points=np.zeros((2, 3)), counts=[2.0]), "counts"),
    ],
)
def test_strands_validation_names_the_field(kwargs, field):
    with pytest.raises(errors.ValidationError) as info:
        Strands(**kwargs)
    assert info.value.field == field


@pytest.mark.parametrize("name", sorted(GROOMS))
def test_tfx_grooms_match_their_documentation(name):
    n_strands, per, lo, hi = GROOMS[name]
    s = read_strands(groom(name))
    assert (s.n_strands, s.n_points) == (n_strands, n_strands * per)
    assert s.as_padded().shape == (n_strands, per, 3)
    np.testing.assert_allclose(s.bbox(), [lo, hi], atol=0.1)
    assert not s.movable[s.offsets[:-1]].any(), "TressFX pins every root vertex (w = 0)"
    assert s.lengths().min() > 0


def test_vendored_grooms_are_the_documented_files_with_their_licences():
    """tables/grooms/ keeps each groom unchanged (the SHA-256 its README lists), beside its licence
    and attribution: a clone that lost a file, or a checkout that rewrote its bytes, fails here."""
    readme = (GROOM_DIR / "README.md").read_text(encoding="utf-8")
    assert sorted(p.name for p in GROOM_DIR.glob("*.tfx")) == sorted(GROOMS)
    for name in GROOMS:
        row = next(line for line in readme.splitlines() if line.startswith(f"| `{name}` |"))
        digest = row.rstrip(" |").rsplit("`", 2)[-2]
        assert hashlib.sha256(groom(name).read_bytes()).hexdigest() == digest, name
    sintel = (GROOM_DIR / "LICENSE-sintel.txt").read_text(encoding="utf-8")
    assert "Blender Foundation" in sintel and "durian.blender.org" in sintel
    assert "creativecommons.org/licenses/by/3.0" in sintel
    ratboy = (GROOM_DIR / "LICENSE-ratboy.txt").read_text(encoding="utf-8")
    assert "Advanced Micro Devices" in ratboy and "Permission is hereby granted, free of charge" in ratboy
    for licence in ("LICENSE-sintel.txt", "LICENSE-ratboy.txt"):
        assert f"({licence})" in readme, f"README.md does not point at {licence}"


def test_tfx_round_trip_is_byte_identical(tmp_path):
    for name in GROOMS:
        src = groom(name)
        s = read_strands(src)
        write_strands(tmp_path / name, s)
        assert (tmp_path / name).read_bytes() == src.read_bytes(), name
        assert_same(read_strands(tmp_path / name), s)
    assert stale_temporaries(tmp_path) == []


def test_tfx_per_strand_uvs():
    s = read_strands(groom("ratboy_mohawk.tfx"))
    assert s.uv.shape == (2226, 2) and 0 <= s.uv.min() and s.uv.max() <= 1
    assert read_strands(groom("sintel_lite.tfx")).uv is None


def test_tfx_writer_refuses_what_tressfx_cannot_hold(tmp_path):
    rng = np.random.default_rng(1)
    with pytest.raises(errors.ValidationError, match="same number"):
        write_strands(tmp_path / "x.tfx", random_strands(rng))
    with pytest.raises(errors.ValidationError, match="power of two"):
        write_strands(tmp_path / "x.tfx", random_strands(rng, equal=5))
    assert list(tmp_path.iterdir()) == []


def test_hair_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    s = random_strands(rng, n=50)
    write_strands(tmp_path / "a.hair", s)
    assert_same(read_strands(tmp_path / "a.hair"), s)
    bare = Strands(s.points, s.counts)
    write_strands(tmp_path / "b.hair", bare)
    back = read_strands(tmp_path / "b.hair")
    assert_same(back, bare, names=("uv", "movable"))
    assert (back.thickness == 1).all() and (back.transparency == 0).all() and (back.color == 1).all()


def _hair_header(n_strands, n_points, flags, d_seg, d_thick, d_transp, d_color, text=b"handmade"):
    head = b"HAIR" + struct.pack("<IIII", n_strands, n_points, flags, d_seg)
    head += struct.pack("<fffff", d_thick, d_transp, *d_color) + text.ljust(88, b"\0")
    assert len(head) == 128
    return head


def test_handcrafted_hair_with_every_array(tmp_path):
    segments = [1, 3]
    pts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 2, 0), (0, 3, 0.5), (0, 4, 1.5)]
    thick = [0.5, 0.25, 1.0, 0.75, 0.5, 0.125]
    transp = [0.0, 0.5, 0.25, 0.0, 1.0, 0.5]
    colour = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (0.5, 0.5, 0.5), (0.25, 0, 1), (1, 1, 1)]
    body = struct.pack("<2H", *segments)
    body += b"".join(struct.pack("<3f", *p) for p in pts)
    body += struct.pack("<6f", *thick) + struct.pack("<6f", *transp)
    body += b"".join(struct.pack("<3f", *c) for c in colour)
    path = tmp_path / "hand.hair"
    path.write_bytes(_hair_header(2, 6, 1 | 2 | 4 | 8 | 16, 9, 9.0, 0.9, (0.9, 0.9, 0.9)) + body)
    s = read_strands(path)
    np.testing.assert_array_equal(s.counts, [2, 4])
    np.testing.assert_array_equal(s.points, np.array(pts, dtype=np.float32))
    np.testing.assert_array_equal(s.thickness, np.array(thick, dtype=np.float32))
    np.testing.assert_array_equal(s.transparency, np.array(transp, dtype=np.float32))
    np.testing.assert_array_equal(s.color, np.array(colour, dtype=np.float32))
    np.testing.assert_allclose(s.lengths(), [1, 1 + math.hypot(1, 0.5) + math.hypot(1, 1)], rtol=1e-6)


def test_hair_without_segments_uses_header_defaults(tmp_path):
    pts = np.arange(3 * 4 * 3, dtype="<f4").reshape(12, 3)
    path = tmp_path / "defaults.hair"
    path.write_bytes(_hair_header(3, 12, 2, 3, 0.5, 0.25, (0.1, 0.2, 0.3)) + pts.tobytes())
    s = read_strands(path)
    np.testing.assert_array_equal(s.counts, [4, 4, 4])
    np.testing.assert_array_equal(s.points, pts)
    assert (s.thickness == np.float32(0.5)).all() and (s.transparency == np.float32(0.25)).all()
    np.testing.assert_array_equal(s.color, np.tile(np.array([0.1, 0.2, 0.3], dtype=np.float32), (12, 1)))


@needs_pxr
@pytest.mark.parametrize("suffix", [".usda", ".usdc", ".usd"])
def test_usd_round_trip(tmp_path, suffix):
    rng = np.random.default_rng(3)
    s = random_strands(rng, n=20)
    s = Strands(
        s.points,
        s.counts,
        thickness=s.thickness,
        transparency=s.transparency,
        color=s.color,
        uv=rng.uniform(0, 1, (20, 2)).astype(np.float32),
        movable=rng.integers(0, 2, s.n_points).astype(bool),
    )
    write_strands(tmp_path / f"a{suffix}", s)
    assert_same(read_strands(tmp_path / f"a{suffix}"), s, atol=1e-6)
    assert [p.name for p in tmp_path.iterdir()] == [f"a{suffix}"]


@needs_pxr
def test_usd_reader_applies_transforms_and_refuses_cubic(tmp_path):
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(tmp_path / "moved.usda"))
    xf = UsdGeom.Xform.Define(stage, "/root")
    xf.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    curves = UsdGeom.BasisCurves.Define(stage, "/root/c")
    curves.CreateTypeAttr("linear")
    curves.CreatePointsAttr([(0, 0, 0), (0, 1, 0), (0, 2, 0)])
    curves.CreateCurveVertexCountsAttr([3])
    stage.Save()
    np.testing.assert_allclose(read_strands(tmp_path / "moved.usda").points, [[10, 0, 0], [10, 1, 0], [10, 2, 0]])
    curves.CreateTypeAttr("cubic")
    stage.Save()
    with pytest.raises(errors.FormatError, match="only linear"):
        read_strands(tmp_path / "moved.usda")


@needs_pxr
def test_tfx_to_hair_to_usda_keeps_points(tmp_path):
    runner = CliRunner()
    src = groom("sintel_lite.tfx")
    for a, b in ((src, tmp_path / "s.hair"), (tmp_path / "s.hair", tmp_path / "s.usda")):
        result = runner.invoke(strands_group, ["convert", str(a), str(b)])
        assert result.exit_code == 0, result.output
    original, final = read_strands(src), read_strands(tmp_path / "s.usda")
    assert_same(final, original, names=())
    assert final.thickness is not None  # .hair filled the default thickness, USD kept it as widths


def test_missing_pxr_is_a_clear_hairlut_error(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pxr", None)
    with pytest.raises(errors.MissingDependencyError, match="pip install usd-core"):
        write_strands(tmp_path / "x.usda", random_strands(np.random.default_rng(0)))
    assert list(tmp_path.iterdir()) == []


def test_missing_file_and_unknown_extension(tmp_path):
    with pytest.raises(errors.AssetNotFoundError):
        read_strands(tmp_path / "absent.tfx")
    with pytest.raises(errors.AssetNotFoundError):
        read_strands(tmp_path / "absent.hair")
    (tmp_path / "x.obj").write_text("v 0 0 0\n")
    with pytest.raises(errors.FormatError, match="extension"):
        read_strands(tmp_path / "x.obj")
    with pytest.raises(errors.ValidationError):
        write_strands(tmp_path / "y.obj", random_strands(np.random.default_rng(0)))


def test_wrong_magic(tmp_path):
    (tmp_path / "png.hair").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(200))
    with pytest.raises(errors.FormatError, match="HAIR"):
        read_strands(tmp_path / "png.hair")
    write_strands(tmp_path / "real.hair", random_strands(np.random.default_rng(0)))
    (tmp_path / "fake.tfx").write_bytes((tmp_path / "real.hair").read_bytes())
    with pytest.raises(errors.FormatError, match="version"):
        read_strands(tmp_path / "fake.tfx")


@pytest.mark.parametrize("keep", [0, 3, 100, 159, 160, 1000, 600_000, 1_139_872, 1_157_679])
def test_truncated_tfx(tmp_path, keep):
    data = groom("ratboy_mohawk.tfx").read_bytes()
    (tmp_path / "cut.tfx").write_bytes(data[:keep])
    with pytest.raises(errors.TruncatedAssetError) as info:
        read_strands(tmp_path / "cut.tfx")
    assert f"file has {keep} bytes" in str(info.value)


def test_truncated_tfx_message_names_the_arithmetic(tmp_path):
    data = groom("ratboy_mohawk.tfx").read_bytes()
    (tmp_path / "cut.tfx").write_bytes(data[:1000])
    with pytest.raises(errors.TruncatedAssetError, match="2226 strands × 32 vertices × 16 bytes at offset 160 = 1139712 bytes"):
        read_strands(tmp_path / "cut.tfx")


def test_truncated_hair(tmp_path):
    write_strands(tmp_path / "full.hair", random_strands(np.random.default_rng(5), n=9))
    data = (tmp_path / "full.hair").read_bytes()
    for keep in (0, 2, 64, 127, 128, 129, len(data) // 2, len(data) - 1):
        (tmp_path / "cut.hair").write_bytes(data[:keep])
        with pytest.raises(errors.TruncatedAssetError, match=f"file has {keep} bytes"):
            read_strands(tmp_path / "cut.hair")


def test_nan_coordinates_are_corrupt(tmp_path):
    data = bytearray(groom("sintel_lite.tfx").read_bytes())
    struct.pack_into("<f", data, 160 + 16 * 40 + 4, float("nan"))  # strand 1, vertex 8, y
    (tmp_path / "nan.tfx").write_bytes(bytes(data))
    with pytest.raises(errors.CorruptAssetError, match=r"strand 1, vertex 8"):
        read_strands(tmp_path / "nan.tfx")
    pts = np.zeros((4, 3), dtype="<f4")
    pts[2, 0] = np.inf
    (tmp_path / "inf.hair").write_bytes(_hair_header(2, 4, 2, 1, 1, 0, (1, 1, 1)) + pts.tobytes())
    with pytest.raises(errors.CorruptAssetError, match="non-finite"):
        read_strands(tmp_path / "inf.hair")


def test_inconsistent_counts_are_corrupt(tmp_path):
    pts = np.zeros((6, 3), dtype="<f4").tobytes()
    (tmp_path / "seg.hair").write_bytes(_hair_header(2, 6, 1 | 2, 0, 1, 0, (1, 1, 1)) + struct.pack("<2H", 1, 1) + pts)
    with pytest.raises(errors.CorruptAssetError, match="implies 4 points, header says 6"):
        read_strands(tmp_path / "seg.hair")
    (tmp_path / "dflt.hair").write_bytes(_hair_header(4, 6, 2, 1, 1, 0, (1, 1, 1)) + pts)
    with pytest.raises(errors.CorruptAssetError, match="8 points, but 6 points"):
        read_strands(tmp_path / "dflt.hair")
    data = bytearray(groom("sintel_lite.tfx").read_bytes())
    struct.pack_into("<I", data, 8, 1)  # one vertex per strand
    (tmp_path / "one.tfx").write_bytes(bytes(data))
    with pytest.raises(errors.CorruptAssetError, match="at least 2"):
        read_strands(tmp_path / "one.tfx")


def test_absurd_counts_fail_before_allocating(tmp_path):
    (tmp_path / "huge.hair").write_bytes(_hair_header(0xFFFFFFFF, 0, 2, 0xFFFFFFFF, 1, 0, (1, 1, 1)))
    with pytest.raises(errors.CorruptAssetError):
        read_strands(tmp_path / "huge.hair")
    data = bytearray(groom("sintel_lite.tfx").read_bytes())
    struct.pack_into("<II", data, 4, 0xFFFFFFFF, 0xFFFFFFFF)
    (tmp_path / "huge.tfx").write_bytes(bytes(data))
    with pytest.raises(errors.TruncatedAssetError):
        read_strands(tmp_path / "huge.tfx")


def test_negative_thickness_is_corrupt(tmp_path):
    pts = np.zeros((2, 3), dtype="<f4").tobytes()
    (tmp_path / "neg.hair").write_bytes(_hair_header(1, 2, 2 | 4, 1, 1, 0, (1, 1, 1)) + pts + struct.pack("<2f", 1, -1))
    with pytest.raises(errors.CorruptAssetError, match="negative thickness at point 1"):
        read_strands(tmp_path / "neg.hair")
    (tmp_path / "negdefault.hair").write_bytes(_hair_header(1, 2, 2, 1, -2, 0, (1, 1, 1)) + pts)
    with pytest.raises(errors.CorruptAssetError, match="negative thickness"):
        read_strands(tmp_path / "negdefault.hair")


def test_failed_write_keeps_the_old_file(tmp_path):
    target = tmp_path / "keep.tfx"
    target.write_bytes(b"old")
    with pytest.raises(errors.ValidationError):
        write_strands(target, random_strands(np.random.default_rng(2)))
    assert target.read_bytes() == b"old" and stale_temporaries(tmp_path) == []


# -- property: random strands survive a write and a read -----------------------------------------------------------
unit = st.floats(0, 1, width=32)


@st.composite
def strand_sets(draw, equal_pow2: bool = False):
    if equal_pow2:
        counts = [draw(st.sampled_from([4, 8, 16]))] * draw(st.integers(1, 6))
    else:
        counts = draw(st.lists(st.integers(2, 9), max_size=8))
    p, s = sum(counts), len(counts)

    def rows(n, *elements):
        return np.array(draw(st.lists(st.tuples(*elements), min_size=n, max_size=n)), np.float32).reshape(n, len(elements))

    coord = st.floats(-1e4, 1e4, width=32)
    opt = {
        name: rows(p, *[elem] * k)[:, 0 if k == 1 else slice(None)]
        for name, elem, k in (("thickness", st.floats(0, 10, width=32), 1), ("transparency", unit, 1), ("color", unit, 3))
        if draw(st.booleans())
    }
    if equal_pow2 and draw(st.booleans()):
        opt["uv"] = rows(s, unit, unit)
    return Strands(rows(p, coord, coord, coord), np.array(counts, dtype=np.int64), **opt)


@pytest.mark.parametrize("suffix", [".hair", ".tfx", pytest.param(".usdc", marks=needs_pxr)])
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_property_round_trip(suffix, data):
    s = data.draw(strand_sets(equal_pow2=suffix == ".tfx"))
    with tempfile.TemporaryDirectory() as folder:
        write_strands(Path(folder) / f"p{suffix}", s)
        back = read_strands(Path(folder) / f"p{suffix}")
    if suffix == ".hair":  # .hair fills absent attributes from the header defaults
        assert_same(back, s, names=[n for n in ("thickness", "transparency", "color") if getattr(s, n) is not None])
    elif suffix == ".tfx":  # .tfx keeps uv and pins the roots when no movable flag was given
        assert_same(back, s, names=("uv",))
        assert not back.movable[back.offsets[:-1]].any() and back.movable.sum() == s.n_points - s.n_strands
    else:
        assert_same(back, s, atol=1e-6)


def _cli() -> click.Group:
    @click.group(cls=Group)
    def top():
        pass

    top.add_command(strands_group)
    return top


def test_cli_info_json_and_text():
    path = groom("ratboy_mohawk.tfx")
    result = CliRunner().invoke(_cli(), ["strands", "info", str(path), "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    assert (info["format"], info["strands"], info["points"]) == ("tfx", 2226, 71232)
    assert info["arrays"] == {"thickness": False, "transparency": False, "color": False, "uv": True, "movable": True}
    assert info["length"]["min"] <= info["length"]["mean"] <= info["length"]["max"]
    np.testing.assert_allclose([info["bbox"]["min"], info["bbox"]["max"]], GROOMS[path.name][2:], atol=0.1)
    text = CliRunner().invoke(_cli(), ["strands", "info", str(path)]).output
    assert "2226" in text and "32 per strand" in text and "absent: thickness" in text


def test_cli_errors_are_one_line_and_exit_2(tmp_path):
    (tmp_path / "bad.hair").write_bytes(b"NOPE" + bytes(200))
    result = CliRunner().invoke(_cli(), ["strands", "info", str(tmp_path / "bad.hair")])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and "bad.hair" in result.output
    write_strands(tmp_path / "ragged.hair", random_strands(np.random.default_rng(4)))
    result = CliRunner().invoke(_cli(), ["strands", "convert", str(tmp_path / "ragged.hair"), str(tmp_path / "r.tfx")])
    assert result.exit_code == 2 and "same number of vertices" in result.output
    assert not (tmp_path / "r.tfx").exists()
