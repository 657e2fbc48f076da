"""compare: zero against itself, known RMSEs and bias for known perturbations; frames through EXR; the CLI."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.recipes import resolve
from hairlut.render import Frame, block_average, compare, read_frame, write_frame
from hairlut.scene import CAMERA, make_camera
from hairlut_cli.main import cli


def _frame(rng, h=64, w=48):
    a = rng.uniform(0.0, 1.0, (h, w, 1))
    rgb = rng.uniform(0.0, 1.0, (h, w, 3)) * a
    return np.concatenate([rgb, a], -1).astype(np.float32)


def test_self_is_zero(rng):
    a = _frame(rng)
    fig, heat = compare(a, a)
    assert all(fig[k] == 0 for k in ("rgb_rmse", "alpha_rmse", "alpha_bias", "rgb_rmse_8x8", "alpha_rmse_8x8", "flip_mean"))
    assert heat.shape == (64, 48, 3)


def test_known_perturbation(rng):
    a = _frame(rng).astype(np.float64)
    b = a.copy()
    b[..., :3] += 0.05
    b[::2, :, 3] += 0.1  # half the rows: α RMSE √(0.1²/2), bias 0.05
    fig, _ = compare(b, a, flip=False)
    assert np.isclose(fig["rgb_rmse"], 0.05, rtol=1e-5)
    assert np.isclose(fig["alpha_rmse"], 0.1 / np.sqrt(2), rtol=1e-5)
    assert np.isclose(fig["alpha_bias"], 0.05, rtol=1e-5)
    assert np.isclose(fig["rgb_rmse_8x8"], 0.05, rtol=1e-5)
    assert np.isclose(fig["alpha_rmse_8x8"], 0.05, rtol=1e-5)  # every 8-row block holds 4 bumped rows: +0.05 each
    assert fig["alpha_rmse_8x8"] < fig["alpha_rmse"]


def test_block_average_is_a_loop(rng):
    x = rng.normal(size=(17, 20, 2))
    got = block_average(x)
    want = np.array([[x[8 * i : 8 * i + 8, 8 * j : 8 * j + 8].mean((0, 1)) for j in range(2)] for i in range(2)])
    assert np.allclose(got, want)


def test_bad_frames():
    with pytest.raises(errors.ValidationError, match="b="):
        compare(np.zeros((16, 16, 4)), np.zeros((16, 8, 4)))
    with pytest.raises(errors.ValidationError, match="a="):
        compare(np.full((16, 16, 4), np.nan), np.zeros((16, 16, 4)))


def test_frame_round_trip_keeps_the_camera(tmp_path, rng):
    cam = make_camera(
        resolve(CAMERA, {"view": [1.0, 0.5, 0.2], "projection": "perspective", "resolution": [48, 64]}, "camera."),
        rng.normal(size=(20, 3)),
    )
    f = Frame(_frame(rng), rng.uniform(1, 2, (64, 48)).astype(np.float32), cam, {"method": "test"})
    write_frame(f, tmp_path / "f.exr", png=True)
    g = read_frame(tmp_path / "f.exr")
    assert np.array_equal(g.rgba, f.rgba) and np.array_equal(g.depth, f.depth)
    assert np.allclose(g.camera.matrix, cam.matrix) and g.camera.projection == "perspective"
    assert (tmp_path / "f.png").is_file()


def test_cli_compare(tmp_path, rng):
    cam = make_camera(resolve(CAMERA, {"view": [0.0, 0.0, 1.0], "resolution": [32, 32]}, "camera."), rng.normal(size=(9, 3)))
    a = _frame(rng, 32, 32)
    b = a.copy()
    b[..., :3] *= 0.5
    write_frame(Frame(a, np.ones((32, 32), np.float32), cam), tmp_path / "a.exr")
    write_frame(Frame(b, np.ones((32, 32), np.float32), cam), tmp_path / "b.exr")
    out = CliRunner().invoke(
        cli,
        ["compare", str(tmp_path / "b.exr"), str(tmp_path / "a.exr"), "--json", "--png", str(tmp_path / "d.png")],
        catch_exceptions=False,
    )
    assert out.exit_code == 0, out.output
    fig = json.loads(out.stdout)
    assert np.isclose(fig["rgb_rmse"], np.sqrt(np.mean((0.5 * a[..., :3].astype(np.float64)) ** 2)), rtol=1e-5)
    assert fig["flip_mean"] > 0 and (tmp_path / "d.png").is_file()
    bad = CliRunner().invoke(cli, ["compare", str(tmp_path / "a.exr"), str(tmp_path / "nope.exr")])
    assert bad.exit_code == 2 and "nope.exr" in bad.stderr and bad.stdout == ""


def _camera_record(**change):
    cam = make_camera(
        resolve(CAMERA, {"view": [0.0, 0.0, 1.0], "projection": "perspective", "resolution": [16, 16]}, "camera."),
        np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]),
    )
    return {**cam.to_json(), **change}


def _frame_with_camera(path, text, rng):
    """A checksum-valid 16 x 16 RGBA EXR whose ``hairlut:camera`` header is ``text``."""
    from hairlut.assets import write_exr

    write_exr(path, {c: v for c, v in zip("RGBA", np.moveaxis(_frame(rng, 16, 16), -1, 0))}, attributes={"hairlut:camera": text})
    return path


@pytest.mark.parametrize(
    "text, field, reason",
    [
        (json.dumps(_camera_record(resolution=[1e999, 1e999])), "hairlut:camera.resolution", "2 integers"),  # Infinity
        (json.dumps(_camera_record(resolution=[16.0, 16])), "hairlut:camera.resolution", "2 integers"),
        (json.dumps(_camera_record(resolution=[32, 32])), "hairlut:camera.resolution", "16 x 16 pixels"),
        (json.dumps(_camera_record(resolution=[10**30, 16])), "hairlut:camera.resolution", "at most"),
        (json.dumps(_camera_record(eye=[float("nan"), 0.0, 1.0])), "hairlut:camera.eye", "finite"),
        (json.dumps(_camera_record(view=[0.0, 0.0, 2.0])), "hairlut:camera.view", "unit"),
        (json.dumps(_camera_record(up=[1.0, 0.0, 0.0])), "hairlut:camera.right", "orthogonal"),
        (json.dumps(_camera_record(fov=1e999)), "hairlut:camera.fov", "finite"),
        (json.dumps(_camera_record(fov=180)), "hairlut:camera.fov", "(0, 180)"),
        (json.dumps(_camera_record(extent=-1.0)), "hairlut:camera.extent", "> 0"),
        (json.dumps(_camera_record(near="0.1")), "hairlut:camera.near", "finite number"),
        (json.dumps(_camera_record(near=0.0)), "hairlut:camera.near", "in front of the eye"),
        (json.dumps(_camera_record(far=-1.0)), "hairlut:camera.far", "beyond the near plane"),
        (json.dumps(_camera_record(projection="fisheye")), "hairlut:camera.projection", "'perspective'"),
        (json.dumps(_camera_record(world_to_clip=[[1.0] * 4] * 4)), "hairlut:camera.world_to_clip", "not the matrix"),
        (json.dumps(_camera_record(world_to_clip=[[1e999] * 4] * 4)), "hairlut:camera.world_to_clip", "finite"),
        (json.dumps({k: v for k, v in _camera_record().items() if k != "far"}), "hairlut:camera", "missing field(s) far"),
        (json.dumps([1, 2, 3]), "hairlut:camera", "not a JSON object"),  # m3: valid JSON, not "not JSON"
        ("{not json", "hairlut:camera", "is not JSON"),
    ],
)
def test_a_bad_camera_record_is_refused_naming_the_field(tmp_path, rng, text, field, reason):
    """Issue 29 N3 and m3: every field of the ``hairlut:camera`` record is checked (an infinite resolution raised
    OverflowError from ``compare``; a JSON list was called "not JSON"); the CLI gives one line naming the file,
    the attribute's field and the fault, exit status 2."""
    path = _frame_with_camera(tmp_path / "c.exr", text, rng)
    with pytest.raises(errors.CorruptAssetError) as exc:
        read_frame(path)
    assert str(path) in str(exc.value) and field in str(exc.value) and reason in str(exc.value), str(exc.value)
    r = CliRunner().invoke(cli, ["compare", str(path), str(path)])
    assert r.exit_code == 2 and r.stdout == "" and r.stderr.count("\n") == 1 and field in r.stderr, r.output


def test_a_good_camera_record_reads_back_exactly(tmp_path, rng):
    rec = _camera_record()
    f = read_frame(_frame_with_camera(tmp_path / "c.exr", json.dumps(rec), rng))
    assert f.camera.to_json() == rec


def test_json_is_strict_when_the_reference_alpha_is_zero(tmp_path, rng):
    """Issue 29 m1: against a reference with α = 0 everywhere the relative α bias is undefined: None with its reason,
    never a bare NaN (not JSON); the other figures stay numbers (the bias is a's mean α)."""
    cam = make_camera(resolve(CAMERA, {"view": [0.0, 0.0, 1.0], "resolution": [16, 16]}, "camera."), rng.normal(size=(9, 3)))
    a = _frame(rng, 16, 16)
    write_frame(Frame(a, np.ones((16, 16), np.float32), cam), tmp_path / "a.exr")
    write_frame(Frame(np.zeros_like(a), np.ones((16, 16), np.float32), cam), tmp_path / "empty.exr")
    r = CliRunner().invoke(cli, ["compare", str(tmp_path / "a.exr"), str(tmp_path / "empty.exr"), "--json"])
    assert r.exit_code == 0, r.output

    def refuse(name):
        raise AssertionError(f"{name} is not JSON")

    fig = json.loads(r.stdout, parse_constant=refuse)
    assert fig["alpha_bias_relative"] is None and "zero everywhere" in fig["alpha_bias_relative_undefined"]
    assert fig["alpha_mean_b"] == 0.0 and np.isclose(fig["alpha_bias"], a[..., 3].astype(np.float64).mean(), rtol=1e-6)
    assert fig["colour_per_alpha"] is None and "no light" in fig["colour_per_alpha_undefined"]
    assert all(
        isinstance(v, (int, float)) for k, v in fig.items() if not k.startswith(("alpha_bias_relative", "colour_per_alpha"))
    )
    text = CliRunner().invoke(cli, ["compare", str(tmp_path / "a.exr"), str(tmp_path / "empty.exr")])
    assert text.exit_code == 0 and "alpha_bias_relative  n/a" in text.stdout


def _multipart(path, parts):
    """A multi-part EXR written with OpenEXR's own binding (no hairlut metadata): ``parts`` (name, channels)."""
    import OpenEXR

    out = []
    display = (np.array([0, 0], np.int32), np.array([31, 31], np.int32))  # every part's, as EXR requires
    for name, ch in parts:
        h, w = next(iter(ch.values())).shape
        header = {
            "compression": OpenEXR.ZIP_COMPRESSION,
            "type": OpenEXR.scanlineimage,
            "displayWindow": display,
            "dataWindow": (np.array([0, 0], np.int32), np.array([w - 1, h - 1], np.int32)),
        }
        out.append(OpenEXR.Part(header, {k: np.ascontiguousarray(v, np.float32) for k, v in ch.items()}, name))
    OpenEXR.File(out).write(str(path))
    return path


def test_compare_reads_the_part_that_holds_the_frame(tmp_path, rng):
    """Issue 29 m4: in a multi-part EXR the frame is the part with R, G, B and A, wherever it stands (compare read
    the first part only); several such parts are refused as ambiguous, naming them; none, naming every part's
    channels."""
    a, b = _frame(rng, 16, 24), _frame(rng, 16, 24)
    rgba = lambda x: {c: x[..., i] for i, c in enumerate("RGBA")}  # noqa: E731
    mask = {"Y": rng.uniform(size=(8, 8))}
    pa = _multipart(tmp_path / "a.exr", [("mask", mask), ("beauty", {**rgba(a), "Z": np.full((16, 24), 2.0)})])
    pb = _multipart(tmp_path / "b.exr", [("mask", mask), ("beauty", rgba(b))])
    fa = read_frame(pa)
    assert np.array_equal(fa.rgba, a) and np.all(fa.depth == 2.0) and fa.camera is None
    r = CliRunner().invoke(cli, ["compare", str(pa), str(pb), "--json"])
    assert r.exit_code == 0, r.output
    want, _ = compare(a, b, flip=False)
    got = json.loads(r.stdout)
    assert all(np.isclose(got[k], v, rtol=1e-6) for k, v in want.items())
    two = _multipart(tmp_path / "two.exr", [("left", rgba(a)), ("right", rgba(b))])
    r = CliRunner().invoke(cli, ["compare", str(two), str(pb)])
    assert r.exit_code == 2 and "2 of its 2 parts" in r.stderr and "'left', 'right'" in r.stderr, r.output
    none = _multipart(tmp_path / "none.exr", [("mask", mask), ("rgb", {c: a[..., i] for i, c in enumerate("RGB")})])
    r = CliRunner().invoke(cli, ["compare", str(none), str(pb)])
    assert r.exit_code == 2 and "no part has channels R, G, B, A" in r.stderr and "'rgb': ['B', 'G', 'R']" in r.stderr, r.output
