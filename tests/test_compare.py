"""compare: zero against itself, known RMSEs and bias for known perturbations; frames through EXR; the CLI."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.render import Frame, block_average, compare, read_frame, write_frame
from hairlut.scene import CAMERA, make_camera
from hairlut.recipes import resolve
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
    want = np.array([[x[8 * i:8 * i + 8, 8 * j:8 * j + 8].mean((0, 1)) for j in range(2)] for i in range(2)])
    assert np.allclose(got, want)


def test_bad_frames():
    with pytest.raises(errors.ValidationError, match="b="):
        compare(np.zeros((16, 16, 4)), np.zeros((16, 8, 4)))
    with pytest.raises(errors.ValidationError, match="a="):
        compare(np.full((16, 16, 4), np.nan), np.zeros((16, 16, 4)))


def test_frame_round_trip_keeps_the_camera(tmp_path, rng):
    cam = make_camera(resolve(CAMERA, {"view": [1.0, 0.5, 0.2], "projection": "perspective", "resolution": [48, 64]},
                              "camera."), rng.normal(size=(20, 3)))
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
    out = CliRunner().invoke(cli, ["compare", str(tmp_path / "b.exr"), str(tmp_path / "a.exr"), "--json",
                                   "--png", str(tmp_path / "d.png")], catch_exceptions=False)
    assert out.exit_code == 0, out.output
    fig = json.loads(out.stdout)
    assert np.isclose(fig["rgb_rmse"], np.sqrt(np.mean((0.5 * a[..., :3].astype(np.float64)) ** 2)), rtol=1e-5)
    assert fig["flip_mean"] > 0 and (tmp_path / "d.png").is_file()
    bad = CliRunner().invoke(cli, ["compare", str(tmp_path / "a.exr"), str(tmp_path / "nope.exr")])
    assert bad.exit_code == 2 and "nope.exr" in bad.stderr and bad.stdout == ""
