"""hairlut.scene.scene_clusters remembers the last few scenes' clusters (a warm demo fitted each groom five times,
issue 29): a second call gives the same clusters as fresh arrays, and a change to what decides them is seen."""

import dataclasses
from pathlib import Path

import numpy as np

from hairlut.scene import _clusters, load_scene, scene_clusters

ROOT = Path(__file__).resolve().parents[1]


def _same(a, b):
    return len(a) == len(b) and all(
        sa == sb and np.array_equal(x.points, y.points) and np.array_equal(x.counts, y.counts) for (sa, x), (sb, y) in zip(a, b)
    )


def test_remembered_clusters_are_the_built_ones_and_independent(monkeypatch):
    monkeypatch.setattr(_clusters, "_MEMO", {})
    scene = load_scene(ROOT / "tables/scenes/sky-clusters.toml")
    first = scene_clusters(scene)
    assert _same(first, _clusters._build(scene)[0])
    first[0][1].points[:] = 7.0  # a caller that writes into its arrays changes nobody else's
    again = scene_clusters(scene)
    assert _same(again, _clusters._build(scene)[0]) and not np.array_equal(again[0][1].points, first[0][1].points)


def test_what_decides_the_clusters_is_in_the_key(monkeypatch, tmp_path):
    monkeypatch.setattr(_clusters, "_MEMO", {})
    scene = load_scene(ROOT / "tables/scenes/sky-clusters.toml")
    other = dataclasses.replace(scene, cluster_seeds=tuple(int(s) + 1 for s in scene.cluster_seeds))
    a, b = scene_clusters(scene), scene_clusters(other)
    assert not _same(a, b) and _same(b, _clusters._build(other)[0])
    for i in range(2 * _clusters._MEMO_SIZE):  # bounded
        scene_clusters(dataclasses.replace(scene, cluster_seeds=tuple(int(s) + 10 + i for s in scene.cluster_seeds)))
    assert len(_clusters._MEMO) <= _clusters._MEMO_SIZE


def test_a_changed_groom_file_is_fitted_again(tmp_path):
    """The key holds the groom file's identity: rewriting it (a new modification time or size) is a new key."""
    import os
    import shutil

    (tmp_path / "grooms").mkdir()
    (tmp_path / "scenes").mkdir()
    shutil.copy(ROOT / "tables/grooms/sintel_lite.tfx", tmp_path / "grooms")
    shutil.copy(ROOT / "tables/scenes/sintel-groom.toml", tmp_path / "scenes")
    scene = load_scene(tmp_path / "scenes/sintel-groom.toml")
    before = _clusters._key(scene)
    assert _clusters._key(load_scene(tmp_path / "scenes/sintel-groom.toml")) == before
    st = os.stat(scene.groom_path)
    os.utime(scene.groom_path, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
    assert _clusters._key(scene) != before
