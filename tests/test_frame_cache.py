"""The strand render frames in the table cache (``hairlut.render.cached_frame``, issue 29 Deliver 6): a frame comes
back bitwise what the strand render renders, only for the same scene, camera, levels and code; a damaged or foreign
entry is neither trusted nor removed; a cache that cannot be written costs the cache, not the frame."""

import logging
import os
import tomllib

import numpy as np
import pytest

from hairlut.render import render_strands, scene_camera, strands_frame
from hairlut.scene import resolve_scene
from tests.test_render_layered import TINY


def _scene(old: str = "", new: str = ""):
    text = TINY.replace("radius = 0.006", "radius = 0.025").replace(old, new)
    cfg = tomllib.loads(text)
    cfg["shadows"] = {"method": "none"}
    return resolve_scene(cfg, None)


def _entries(root):
    return sorted(p.name for p in root.iterdir() if p.name.startswith("strands-"))


def test_a_cached_frame_is_the_rendered_one(tmp_path):
    sc = _scene()
    cam = scene_camera(sc)
    fresh = render_strands(sc, cam, levels=[0])
    first = strands_frame(sc, cam, levels=[0], root=tmp_path)
    again = strands_frame(sc, cam, levels=[0], root=tmp_path)
    assert first.info["cache"]["status"] == "rendered" and again.info["cache"]["status"] == "reused"
    assert first.info["cache"]["key"] == again.info["cache"]["key"] and len(_entries(tmp_path)) == 1
    for f in (first, again):
        np.testing.assert_array_equal(f.rgba, fresh.rgba)
        np.testing.assert_array_equal(f.depth, fresh.depth)
        assert f.camera.to_json() == cam.to_json()
    assert again.info["seconds"] == first.info["seconds"]  # the time of the run that rendered it, not a cache read's
    assert again.info["levels"][0]["samples_per_pixel"] == 1 and "cache_key" not in again.info


def test_the_key_is_the_scene_the_camera_the_levels_and_the_code(tmp_path, monkeypatch):
    import hairlut.render._frame_cache as fc

    sc = _scene()
    cam = scene_camera(sc)
    keys = {fc.frame_key(sc, {"camera": cam.to_json(), "levels": [0]})}
    keys.add(fc.frame_key(sc, {"camera": cam.to_json(), "levels": [1]}))
    small = scene_camera(_scene("resolution = [48, 40]", "resolution = [24, 20]"))
    keys.add(fc.frame_key(sc, {"camera": small.to_json(), "levels": [0]}))
    keys.add(fc.frame_key(_scene("[lights]", "[material]\nkd = 0.2\n[lights]"), {"camera": cam.to_json(), "levels": [0]}))
    keys.add(fc.frame_key(_scene("half_axis_b = 0.045", "half_axis_b = 0.05"), {"camera": cam.to_json(), "levels": [0]}))
    assert len(keys) == 5
    assert fc.frame_key(_scene(), {"camera": cam.to_json(), "levels": [0]}) in keys  # the same scene again: the same key
    monkeypatch.setattr(fc, "code_record", lambda: {"sources": "another version"})
    assert fc.frame_key(sc, {"camera": cam.to_json(), "levels": [0]}) not in keys


def test_a_damaged_or_foreign_entry_is_neither_trusted_nor_removed(tmp_path, caplog):
    sc = _scene()
    cam = scene_camera(sc)
    good = strands_frame(sc, cam, levels=[0], root=tmp_path)
    path = tmp_path / _entries(tmp_path)[0]
    data = bytearray(path.read_bytes())
    data[-100] ^= 0xFF  # a flipped bit in the pixels: the checksum fails
    path.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING, logger="hairlut"):
        again = strands_frame(sc, cam, levels=[0], root=tmp_path)
    assert again.info["cache"]["status"] == "rendered" and again.info["cache"]["path"] is None
    np.testing.assert_array_equal(again.rgba, good.rgba)
    assert path.read_bytes() == bytes(data) and str(path) in caplog.text  # left as it was, and named
    path.unlink()
    os.mkfifo(path)  # a FIFO in its place: not opened (no hang), not replaced
    assert strands_frame(sc, cam, levels=[0], root=tmp_path).info["cache"]["status"] == "rendered"
    assert path.is_fifo()


def test_a_cache_that_cannot_be_written_costs_only_the_cache(tmp_path):
    sc = _scene()
    cam = scene_camera(sc)
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    f = strands_frame(sc, cam, levels=[0], root=blocked / "cache")
    assert f.info["cache"] == {"status": "rendered", "path": None, "key": f.info["cache"]["key"]}
    assert f.rgba.shape == (40, 48, 4)


def test_the_demo_probe_is_kept_with_its_figures(tmp_path):
    from hairlut.demo import strands_probe

    sc = _scene()
    plain = strands_probe(sc, level=0, size=24)
    first = strands_probe(sc, level=0, size=24, cache=tmp_path)
    second = strands_probe(sc, level=0, size=24, cache=tmp_path)
    assert plain["cache"] is None and first["cache"] == "rendered" and second["cache"] == "reused"
    assert first["change_to_next"] == second["change_to_next"] == pytest.approx(plain["change_to_next"], rel=1e-6)
    assert second["cpu_seconds"] == first["cpu_seconds"] > 0
