"""Environment maps → SH light coefficients: exact solid angles, layouts, band error, bad maps."""

import numpy as np
import pytest

from hairlut import errors
from hairlut.assets import ExrPart, write_exr
from hairlut.envlight import (
    FACES,
    cube_dirs,
    cube_face_samples,
    latlong_samples,
    load_env_light,
    load_light,
    read_light,
    write_light,
)
from hairlut.sh import real_sh

COEFFS = np.zeros((9, 3))
COEFFS[0] = [2.0, 1.0, 0.5]
COEFFS[3] = [0.8, -0.3, 0.1]  # x
COEFFS[6] = [0.4, 0.2, -0.6]  # 3z² − 1
COEFFS[4] = [0.3, 0.0, 0.2]  # xy


def radiance(dirs):
    return np.asarray(real_sh(2, dirs.reshape(-1, 3))) @ COEFFS


def test_solid_angles_are_exact():
    _, w = latlong_samples(17, 34)
    assert w.sum() == pytest.approx(4 * np.pi, rel=1e-14)
    d, w = cube_dirs(9)
    assert w.sum() == pytest.approx(4 * np.pi, rel=1e-13)
    assert np.allclose(np.linalg.norm(d, axis=1), 1)
    # one face's corner texel against brute-force integration of the face's area element
    _, wf = cube_face_samples("+z", 4)
    u = np.linspace(0.5, 1.0, 801)
    uu, vv = np.meshgrid(0.5 * (u[1:] + u[:-1]), 0.5 * (u[1:] + u[:-1]))
    brute = np.sum((1 + uu**2 + vv**2) ** -1.5) * (u[1] - u[0]) ** 2
    assert wf[-1, -1] == pytest.approx(brute, rel=1e-6)


def test_cube_faces_cover_the_sphere_once():
    d, _ = cube_dirs(6)
    major = np.argmax(np.abs(d), axis=1) * 2 + (np.take_along_axis(d, np.argmax(np.abs(d), axis=1)[:, None], 1)[:, 0] < 0)
    np.testing.assert_array_equal(major, np.repeat(np.arange(6), 36))  # face k ↔ +x −x +y −y +z −z


def _latlong_file(path, h=128):
    d, _ = latlong_samples(h, 2 * h)
    img = radiance(d).reshape(h, 2 * h, 3)
    write_exr(path, {c: img[..., k] for k, c in enumerate("RGB")})


def _faces(n):
    return {f: radiance(cube_face_samples(f, n)[0]).reshape(n, n, 3) for f in FACES}


def test_latlong_projection_recovers_band_limited_light(tmp_path):
    _latlong_file(tmp_path / "ll.exr")
    light = load_env_light(tmp_path / "ll.exr", lmax=4)
    assert light.layout == "latlong" and light.channels == ("R", "G", "B")
    expect = np.zeros((25, 3))
    expect[:9] = COEFFS
    np.testing.assert_allclose(light.coeffs, expect, atol=2e-3)
    assert np.all(light.band_error < 2e-3)
    assert len(light.source_sha256) == 64


@pytest.mark.parametrize("layout", ["parts", "stacked", "hcross", "vcross"])
def test_cube_layouts_agree(tmp_path, layout):
    n = 48
    faces = _faces(n)
    path = tmp_path / f"{layout}.exr"
    chans = lambda img: {c: img[..., k].astype(np.float32) for k, c in enumerate("RGB")}  # noqa: E731
    if layout == "parts":
        write_exr(path, [ExrPart(f, chans(faces[f])) for f in FACES])
    elif layout == "stacked":
        write_exr(path, chans(np.concatenate([faces[f] for f in FACES], axis=0)))
    else:
        vertical = layout == "vcross"
        img = np.zeros((4 * n, 3 * n, 3) if vertical else (3 * n, 4 * n, 3))
        cells = {"+y": (0, 1), "-x": (1, 0), "+z": (1, 1), "+x": (1, 2), "-y": (2, 1), "-z": (3, 1) if vertical else (1, 3)}
        for f, (r, c) in cells.items():
            img[r * n : (r + 1) * n, c * n : (c + 1) * n] = faces[f][::-1, ::-1] if (vertical and f == "-z") else faces[f]
        write_exr(path, chans(img))
    light = load_env_light(path, lmax=2)
    assert light.layout == "cube"
    np.testing.assert_allclose(light.coeffs, COEFFS, atol=2e-3)


def test_y_up_rotates_the_light(tmp_path):
    _latlong_file(tmp_path / "ll.exr")
    z_up = load_env_light(tmp_path / "ll.exr", lmax=1).coeffs
    y_up = load_env_light(tmp_path / "ll.exr", lmax=1, up="y").coeffs
    # the map's z ("up") becomes world y, x becomes z, y becomes x: Y1,-1 ∝ y, Y1,0 ∝ z, Y1,1 ∝ x
    np.testing.assert_allclose(y_up[1], z_up[2], atol=1e-12)  # world y ← map z
    np.testing.assert_allclose(y_up[2], z_up[3], atol=1e-12)  # world z ← map x
    np.testing.assert_allclose(y_up[3], z_up[1], atol=1e-12)  # world x ← map y


def test_band_error_of_a_sharp_light_is_large(tmp_path):
    img = np.zeros((64, 128), np.float32)
    img[10, 20] = 1000.0
    write_exr(tmp_path / "sun.exr", {"Y": img})
    light = load_env_light(tmp_path / "sun.exr", lmax=2)
    assert light.channels == ("Y",) and light.band_error[0] > 0.9


def test_light_table_round_trip(tmp_path):
    _latlong_file(tmp_path / "ll.exr", h=32)
    light = load_env_light(tmp_path / "ll.exr", lmax=3)
    write_light(tmp_path / "l.h5", light, {"lmax": 3})
    back = read_light(tmp_path / "l.h5")
    np.testing.assert_array_equal(back.coeffs, light.coeffs)
    assert back.channels == light.channels
    with pytest.raises(errors.ValidationError, match="l=5 needed"):
        load_light(tmp_path / "l.h5", lmax=5)


def test_bad_maps(tmp_path):
    img = np.ones((10, 20), np.float32)
    img[3, 4] = np.nan
    write_exr(tmp_path / "nan.exr", {"Y": img})
    with pytest.raises(errors.ValidationError, match="1 texels are NaN"):
        load_env_light(tmp_path / "nan.exr", 2)
    write_exr(tmp_path / "odd.exr", {"Y": np.ones((10, 13), np.float32)})
    with pytest.raises(errors.ValidationError, match="envmap.shape"):
        load_env_light(tmp_path / "odd.exr", 2)
    write_exr(tmp_path / "ll.exr", {"Y": np.ones((10, 20), np.float32)})
    with pytest.raises(errors.ValidationError, match="layout"):
        load_env_light(tmp_path / "ll.exr", 2, layout="cube")
    write_exr(tmp_path / "nochan.exr", {"Z": np.ones((10, 20), np.float32)})
    with pytest.raises(errors.MissingDatasetError, match="R,G,B or Y"):
        load_env_light(tmp_path / "nochan.exr", 2)
