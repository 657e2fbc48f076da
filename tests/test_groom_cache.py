"""The groom cache (hairlut/scene/_cache.py, issue 26 "Scale with the groom"): a groom's cluster fit, its sector
tables and scene_sectors' measures kept on disk beside the tables, keyed by the strands' content and the fit's
arguments; and the vectorised fit's pieces against the loops they replace."""

from __future__ import annotations

import dataclasses
import logging
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

import hairlut.geometry as geometry
from hairlut.bench._grooms import curly, write_groom, write_scene
from hairlut.scene import (
    _cache,
    _clusters,
    _sectors,
    cluster_count,
    load_scene,
    scene_clusters,
    scene_sector_tables,
    scene_sectors,
    texel_choice,
)

from ._readonly import read_only_dir  # noqa: F401  (a fixture)

SS_FIELDS = ("aspect", "v_range", "strands", "radius_rel", "theta_v", "theta_l")


@pytest.fixture(autouse=True)
def _fresh_memo(monkeypatch):
    monkeypatch.setattr(_clusters, "_MEMO", {})
    monkeypatch.setattr(_clusters, "_CAMERAS", {})
    monkeypatch.setattr(_clusters, "_TEXELS", {})
    monkeypatch.setattr(_clusters, "_ROOTS", {})
    monkeypatch.setattr(_sectors, "_KEYS", {})


@pytest.fixture(scope="module")
def groom_file(tmp_path_factory):
    """A small curly groom (.hair), written once for the module."""
    folder = tmp_path_factory.mktemp("groom")
    return write_groom(folder, "curly", curly(160, 16, seed=3), formats=("hair",))["hair"]


def _scene(folder: Path, groom: Path, extra: str = "") -> Path:
    """A scene in ``folder`` over a copy of ``groom`` (its own path, the same bytes); ``extra`` TOML appended to
    its [groom] table."""
    folder.mkdir(parents=True, exist_ok=True)
    copy = folder / groom.name
    shutil.copy(groom, copy)
    path = write_scene(folder / "scene.toml", copy)
    if extra:
        path.write_text(path.read_text().replace("[groom]\n", f"[groom]\n{extra}\n", 1))
    return path


def _entries(root: Path, entry: str) -> list[Path]:
    return sorted(root.glob(f"groom-{entry}-*.bin"))


def _forget():
    _clusters._MEMO.clear()
    _clusters._CAMERAS.clear()
    _clusters._TEXELS.clear()
    _clusters._ROOTS.clear()
    _sectors._KEYS.clear()


def _same_pairs(a, b) -> bool:
    if len(a) != len(b):
        return False
    for (sa, x), (sb, y) in zip(a, b):
        for name in _cache.SPLINES:
            pa, pb = getattr(sa, name), getattr(sb, name)
            if not (np.array_equal(pa.control, pb.control) and np.array_equal(pa.knots, pb.knots) and pa.degree == pb.degree):
                return False
        if not (np.array_equal(sa.layer_radii, sb.layer_radii) and sa.structure() == sb.structure()):
            return False
        if not (np.array_equal(sa.normal0, sb.normal0) and sa.core_radius == sb.core_radius):
            return False
        if not all(np.array_equal(getattr(x, f), getattr(y, f)) for f in ("points", "counts", "thickness")):
            return False
    return True


def _same_tables(a, b) -> bool:
    return len(a) == len(b) and all(
        ta.shape == tb.shape
        and ta.s_v == tb.s_v
        and all(
            np.array_equal(getattr(ta, f.name), getattr(tb, f.name), equal_nan=True)
            for f in dataclasses.fields(ta)
            if f.name not in ("shape", "s_v")
        )
        for ta, tb in zip(a, b)
    )


def _same_sectors(a, b) -> bool:
    return a.s_u == b.s_u and all(np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True) for f in SS_FIELDS)


def _uncached(scene):
    """What the scene's clusters, sector tables and sector measures are without any cache."""
    from hairlut.geometry import ClusterGeometry, build_sectors, fit_clusters, read_strands

    g = scene.config["groom"]
    strands = read_strands(scene.groom_path)
    if strands.thickness is None:
        strands = geometry.Strands(
            strands.points, strands.counts, thickness=np.full(strands.n_points, 2 * g["radius"], np.float32)
        )
    batch, labels = fit_clusters(
        strands,
        cluster_count(strands, g["clusters"]).value,
        layer_radii=g["layer_radii"],
        core_radius=g["core_radius"],
        s_t=g["s_t"],
        s_u=g["s_u"],
        seed=g["seed"],
    )
    off = strands.offsets
    pairs = []
    for c, spec in enumerate(batch.specs):  # the split as _build made it before the cache: strand by strand
        idx = np.flatnonzero(labels == c)
        pts = np.concatenate([strands.points[off[i] : off[i + 1]] for i in idx])
        thick = np.concatenate([strands.thickness[off[i] : off[i + 1]] for i in idx])
        pairs.append((spec, geometry.Strands(pts, strands.counts[idx], thickness=thick)))
    tables = [build_sectors(ClusterGeometry(s), st, np.zeros(st.n_strands, np.int64)) for s, st in pairs]
    return pairs, tables


def test_cached_results_are_the_uncached_ones(tmp_path, groom_file):
    """Cold (computed and stored) and warm (read back) clusters, sector tables and sector measures are the very
    arrays the uncached fit and cut give."""
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    root = tmp_path / "cache"
    pairs, tables = _uncached(scene)
    cold = (scene_clusters(scene, root), scene_sector_tables(scene, root), scene_sectors(scene, root))
    for entry in ("fit", "sectors", "tables"):
        assert len(_entries(root, entry)) == 1, entry
    _forget()
    warm = (scene_clusters(scene, root), scene_sector_tables(scene, root), scene_sectors(scene, root))
    for got in (cold, warm):
        assert _same_pairs(got[0], pairs)
        assert _same_tables(got[1], tables)
    assert _same_sectors(cold[2], warm[2])


def test_the_same_groom_bytes_at_another_path_hit(tmp_path, groom_file, monkeypatch):
    root = tmp_path / "cache"
    first = load_scene(_scene(tmp_path / "a", groom_file))
    ref = (scene_clusters(first, root), scene_sector_tables(first, root), scene_sectors(first, root))
    choice = _clusters.cluster_choice(first)
    files = {p: p.stat().st_mtime_ns for p in root.iterdir()}
    _forget()

    def refuse(*a, **k):
        raise AssertionError("computed again: the cache missed")

    monkeypatch.setattr(geometry, "fit_clusters", refuse)
    monkeypatch.setattr(geometry, "build_sectors", refuse)
    monkeypatch.setattr(_clusters, "cluster_count", refuse)  # the count chosen from the strands: kept too
    second = load_scene(_scene(tmp_path / "elsewhere" / "b", groom_file))
    assert second.groom_path != first.groom_path
    got = (scene_clusters(second, root), scene_sector_tables(second, root), scene_sectors(second, root))
    assert _same_pairs(got[0], ref[0]) and _same_tables(got[1], ref[1]) and _same_sectors(got[2], ref[2])
    assert {p: p.stat().st_mtime_ns for p in root.iterdir()} == files  # nothing written
    assert _clusters.cluster_choice(second) == choice


def test_changed_bytes_or_fit_arguments_miss(tmp_path, groom_file):
    root = tmp_path / "cache"
    scene_sectors(load_scene(_scene(tmp_path / "a", groom_file)), root)
    assert len(_entries(root, "fit")) == 1
    # one coordinate of one strand moved
    moved = tmp_path / "moved"
    moved.mkdir()
    strands = geometry.read_strands(groom_file)
    pts = strands.points.copy()
    pts[5, 1] += 0.25
    path = write_groom(moved, "curly", geometry.Strands(pts, strands.counts, thickness=strands.thickness), formats=("hair",))
    _forget()
    scene_sectors(load_scene(write_scene(moved / "scene.toml", path["hair"])), root)
    assert len(_entries(root, "fit")) == 2 and len(_entries(root, "sectors")) == 2
    # a fit argument changed (the seed, then the cluster count): another fit
    for n, extra in enumerate(("seed = 1", "clusters = 3"), start=3):
        _forget()
        scene_clusters(load_scene(_scene(tmp_path / f"s{n}", groom_file, extra)), root)
        assert len(_entries(root, "fit")) == n
    # the strand radius (no thickness in .tfx: [groom] radius) changes the sectors, not the fit
    tfx = write_groom(tmp_path / "tfx", "curly", strands, formats=("tfx",))["tfx"]
    _forget()
    scene_sectors(load_scene(write_scene(tmp_path / "tfx" / "scene.toml", tfx)), root)
    before = len(_entries(root, "sectors"))
    _forget()
    scene_sectors(load_scene(_scene(tmp_path / "tfx2", tfx, "radius = 0.05")), root)
    assert len(_entries(root, "fit")) == 4 and len(_entries(root, "sectors")) == before + 1


def test_the_key_holds_every_fit_argument_given(groom_file, tmp_path, monkeypatch):
    """cached_fit keys the arguments it is given (whatever chose them): two calls that differ in one argument
    never share an entry; the same call does."""
    strands = geometry.read_strands(groom_file)
    keys = []

    def record(entry, key, compute, *a, **k):
        keys.append(key)
        return compute()

    monkeypatch.setattr(_cache, "cached", record)
    for kw in ({}, {"seed": 2}, {"coverage": 0.9}, {"n_fit": 12}, {}):
        _cache.cached_fit(strands, 2, root=tmp_path, **kw)
    _cache.cached_fit(strands, 3, root=tmp_path)
    assert keys[0] == keys[4] and len(set(keys)) == 5


@pytest.mark.parametrize("entry", ["fit", "tables", "sectors"])
@pytest.mark.parametrize("damage", ["flip", "truncate", "stale"])
def test_a_damaged_entry_is_rebuilt(tmp_path, groom_file, entry, damage, caplog):
    root = tmp_path / "cache"
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    ref = (scene_clusters(scene, root), scene_sector_tables(scene, root), scene_sectors(scene, root))
    (path,) = _entries(root, entry)
    data = bytearray(path.read_bytes())
    if damage == "flip":
        data[-7] ^= 0x10
    elif damage == "truncate":
        data = data[: len(data) // 2]
    else:  # hairlut's file, another key (e.g. a stale entry under a colliding name)
        data = data.replace(b'"key": "', b'"key": "0', 1)
    path.write_bytes(bytes(data))
    _forget()
    with caplog.at_level(logging.WARNING, logger="hairlut.scene._cache"):
        got = (scene_clusters(scene, root), scene_sector_tables(scene, root), scene_sectors(scene, root))
    assert _same_pairs(got[0], ref[0]) and _same_tables(got[1], ref[1]) and _same_sectors(got[2], ref[2])
    assert "rebuilding" in caplog.text and path.name in caplog.text
    arrays, _ = _cache.decode(path.read_bytes(), entry, _cache.decode_key(path.read_bytes()))  # valid again
    assert arrays


def test_an_entry_whose_arrays_do_not_rebuild_is_rebuilt(tmp_path, groom_file):
    """A well-formed entry (checksum and key right) whose arrays are not a valid fit: labels out of range."""
    root = tmp_path / "cache"
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    ref = scene_clusters(scene, root)
    (path,) = _entries(root, "fit")
    raw = path.read_bytes()
    key = _cache.decode_key(raw)
    arrays, meta = _cache.decode(raw, "fit", key)
    arrays["labels"][0] = 99
    path.write_bytes(_cache.encode("fit", key, arrays, meta))
    _forget()
    assert _same_pairs(scene_clusters(scene, root), ref)
    assert _cache.decode(path.read_bytes(), "fit", key)[0]["labels"][0] != 99


@pytest.mark.parametrize("what", ["foreign file", "folder", "symlink"])
def test_what_hairlut_did_not_write_is_left_alone(tmp_path, groom_file, what, caplog):
    root = tmp_path / "cache"
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    ref = scene_clusters(scene, root)
    (path,) = _entries(root, "fit")
    path.unlink()
    target = tmp_path / "precious.txt"
    target.write_text("not hairlut's")
    if what == "foreign file":
        path.write_bytes(b"someone else's file")
    elif what == "folder":
        path.mkdir()
        (path / "inside").write_text("x")
    else:
        path.symlink_to(target)
    _forget()
    with caplog.at_level(logging.WARNING, logger="hairlut.scene._cache"):
        assert _same_pairs(scene_clusters(scene, root), ref)
    assert "not using or replacing" in caplog.text
    if what == "foreign file":
        assert path.read_bytes() == b"someone else's file"
    elif what == "folder":
        assert path.is_dir() and (path / "inside").read_text() == "x"
    else:
        assert path.is_symlink() and target.read_text() == "not hairlut's"


def test_a_cache_folder_that_cannot_be_written_costs_the_cache_only(read_only_dir, groom_file, tmp_path, caplog):
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    with caplog.at_level(logging.WARNING, logger="hairlut.scene._cache"):
        ss = scene_sectors(scene, read_only_dir)
    assert len(ss.aspect) and not list(read_only_dir.iterdir())
    assert "cannot keep" in caplog.text


def test_the_folder_is_the_table_caches(monkeypatch, tmp_path):
    from hairlut.bake.cache import cache_dir

    monkeypatch.delenv("HAIRLUT_CACHE", raising=False)
    assert _cache.cache_folder() == cache_dir() == Path("tables")
    monkeypatch.setenv("HAIRLUT_CACHE", str(tmp_path))
    assert _cache.cache_folder() == cache_dir() == tmp_path
    assert _cache.cache_folder(tmp_path / "x") == cache_dir(tmp_path / "x")


def test_the_plan_keeps_the_groom_in_its_cache_folder_and_later_calls_find_it(tmp_path, groom_file, monkeypatch):
    """``plan(scene, cache_root)`` fills that folder; a later ``scene_sector_tables(scene)`` in the process (as
    ``synth.prepare`` calls it, without a folder) reads it there, not from the default folder."""
    from hairlut.planner import plan

    monkeypatch.chdir(tmp_path)  # the default folder would be ./tables
    monkeypatch.delenv("HAIRLUT_CACHE", raising=False)
    root = tmp_path / "mine"
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    plan(scene, root)
    assert _entries(root, "fit") and _entries(root, "sectors") and _entries(root, "tables")
    for p in _entries(root, "tables"):
        p.unlink()
    scene_sector_tables(scene)
    assert _entries(root, "tables") and not (tmp_path / "tables").exists()


def test_generated_clusters_keep_nothing_on_disk(tmp_path, monkeypatch):
    monkeypatch.setenv("HAIRLUT_CACHE", str(tmp_path))
    scene = load_scene(Path(__file__).resolve().parents[1] / "tables/scenes/two-clusters.toml")
    assert len(scene_sectors(scene).aspect) and len(scene_sector_tables(scene))
    assert not list(tmp_path.iterdir())


# ----------------------------------------------------------------------------- the vectorised fit


def test_group_means_are_the_masked_means_bit_for_bit():
    from hairlut.geometry.fit import _group_means, _groups

    rng = np.random.default_rng(0)
    x = rng.normal(size=(5000, 48)) * rng.uniform(0.1, 100, 48)
    labels = rng.integers(0, 7, len(x))
    labels[labels == 4] = 5  # an empty group keeps its row
    c = rng.normal(size=(7, 48))
    got = _group_means(x, labels, c)
    for j in range(7):
        want = x[labels == j].mean(axis=0) if (labels == j).any() else c[j]
        assert np.array_equal(got[j], want)
    groups = _groups(np.where(labels == 2, -1, labels), 7)
    for j in range(7):
        assert np.array_equal(groups[j], np.flatnonzero(np.where(labels == 2, -1, labels) == j))


def test_extend_finds_the_brute_force_nearest_samples(monkeypatch):
    """_extend's k-d tree gives the nearest of the 257 samples and its distance exactly as the brute force did: the
    fitted trajectory and the reach are the same bits."""
    from hairlut.geometry import fit

    rng = np.random.default_rng(1)
    t = np.linspace(0, 1, 16)[:, None]
    mean = np.hstack([np.cos(2 * t), np.sin(2 * t), 3 * t]) * 5
    points = mean[rng.integers(0, 16, 3000)] + rng.normal(scale=0.6, size=(3000, 3))
    points[:40] = mean[0] - (mean[1] - mean[0]) * rng.uniform(1, 3, (40, 1))  # overhang the start
    traj, reach = fit._extend(mean, points, 6)

    class Brute:
        def __init__(self, pos):
            self.pos = pos

        def query(self, pts):
            d = np.linalg.norm(pts[:, None] - self.pos[None], axis=-1)
            near = np.argmin(d, axis=1)
            return d[np.arange(len(d)), near], near

    import scipy.spatial

    monkeypatch.setattr(scipy.spatial, "cKDTree", Brute)
    traj_b, reach_b = fit._extend(mean, points, 6)
    assert reach == reach_b and np.array_equal(traj.control, traj_b.control)


def test_mean_density_is_the_grids_rho_st(groom_file):
    from hairlut.geometry import ClusterGeometry, build_sectors, sector_density, sector_features, sector_mean_density

    strands = geometry.read_strands(groom_file)
    batch, labels = geometry.fit_clusters(strands, 2)
    geom = ClusterGeometry(batch.specs[0])
    table = build_sectors(geom, strands, np.where(labels == 0, 0, -1))
    splats = table.splats()
    for scale in (1.0, 2.5):
        want = np.asarray(sector_features(sector_density(splats, (32, 32), density_scale=scale), splats, ("rho_st",)))[:, 0]
        got = sector_mean_density(table, density_scale=scale)
        assert got.dtype == np.float32 and np.allclose(got, want, rtol=2e-6, atol=1e-7 * np.abs(want).max())


def test_lengths_from_differences_are_the_segment_lengths():
    rng = np.random.default_rng(2)
    counts = rng.integers(2, 9, 200)
    s = geometry.Strands(rng.normal(size=(int(counts.sum()), 3)).astype(np.float32), counts)
    seg = s.segments
    pts = s.points.astype(np.float64)
    want = np.add.reduceat(np.linalg.norm(pts[seg[:, 1]] - pts[seg[:, 0]], axis=1), s.offsets[:-1] - np.arange(s.n_strands))
    assert np.array_equal(s.lengths(), want)


def test_the_split_keeps_each_clusters_strands_in_order(groom_file):
    strands = geometry.read_strands(groom_file)
    labels = np.random.default_rng(3).integers(-1, 3, strands.n_strands)
    pairs = _clusters._split(strands, ["a", "b", "c"], labels)
    off = strands.offsets
    for c, (name, st) in enumerate(pairs):
        idx = np.flatnonzero(labels == c)
        assert name == "abc"[c]
        assert np.array_equal(st.points, np.concatenate([strands.points[off[i] : off[i + 1]] for i in idx]))
        assert np.array_equal(st.counts, strands.counts[idx])
        assert np.array_equal(st.thickness, np.concatenate([strands.thickness[off[i] : off[i + 1]] for i in idx]))


if os.name != "posix":  # pragma: no cover
    pytest.skip("symlinks and read-only folders", allow_module_level=True)


def test_prune_removes_the_groom_entries_and_nothing_foreign(tmp_path, groom_file):
    from hairlut.bake.cache import prune

    root = tmp_path / "cache"
    scene_sectors(load_scene(_scene(tmp_path / "a", groom_file)), root)
    ours = sorted(root.glob("groom-*-*.bin"))
    assert {p.name.split("-")[1] for p in ours} == {"choice", "fit", "sectors", "tables"}
    foreign = root / "groom-fit-0123456789abcdef.bin"
    foreign.write_bytes(b"not hairlut's")
    assert prune(root) == [] and prune(root, kinds=["sh_tables"]) == []  # neither all, nor by age: kept
    assert sorted(prune(root, older_than_days=1)) == []
    assert sorted(prune(root, everything=True, dry_run=True)) == sorted(ours)
    assert all(p.exists() for p in ours)
    assert sorted(prune(root, everything=True)) == sorted(ours)
    assert not any(p.exists() for p in ours) and foreign.read_bytes() == b"not hairlut's"


def test_a_grooms_light_space_shadows_are_kept(tmp_path, groom_file, monkeypatch):
    """The light-oriented map's transmittance at the texels (seconds on a production groom) is kept for a groom
    scene: prepared again, the same T without building a map; another light builds one."""
    import hairlut.shadows as shadows
    from hairlut.bench import with_config
    from hairlut.synth import prepare

    monkeypatch.setenv("HAIRLUT_CACHE", str(tmp_path / "cache"))
    base = load_scene(_scene(tmp_path / "a", groom_file))
    scene = with_config(base, shadows={"method": "light_oriented"}, render={"method": "direct"})
    first = np.asarray(prepare(scene).shadows.transmittance)
    assert len(_entries(tmp_path / "cache", "shadows")) == 1
    _forget()
    calls = []
    real = shadows.light_transmittance
    monkeypatch.setattr(shadows, "light_transmittance", lambda *a, **k: calls.append(1) or real(*a, **k))
    again = np.asarray(prepare(scene).shadows.transmittance)
    assert np.array_equal(first, again) and not calls
    lit = with_config(scene, lights={"directions": [[-0.3, 0.9, 0.2]]})
    other = prepare(lit).shadows
    assert calls and len(_entries(tmp_path / "cache", "shadows")) == 2
    assert not np.array_equal(np.asarray(other.transmittance), first)


def test_a_grooms_fitted_camera_is_kept(tmp_path, groom_file, monkeypatch):
    """The camera fitted to a groom's strands (a pass over every point: 0.9 s at 100,000 strands) is kept: fitted
    again in a fresh process, the same camera without a fit; another view fits another."""
    from hairlut.bench import with_config
    from hairlut.scene import make_camera, scene_camera, thinnest_radius

    monkeypatch.setenv("HAIRLUT_CACHE", str(tmp_path / "cache"))
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    first = scene_camera(scene)
    strands = [s for _, s in scene_clusters(scene)]
    fresh = make_camera(scene.config["camera"], np.concatenate([s.points for s in strands]), thinnest_radius(strands))
    fields = ("projection", "eye", "right", "up", "back", "width", "height", "extent", "fov", "near", "far")
    assert all(np.array_equal(getattr(first, f), getattr(fresh, f)) for f in fields)
    assert len(_entries(tmp_path / "cache", "camera")) == 1
    _forget()
    calls = []
    import hairlut.scene._camera as camera_module  # the fit runs through it

    monkeypatch.setattr(camera_module, "make_camera", lambda *a, **k: calls.append(1) or make_camera(*a, **k))
    again = scene_camera(scene)
    assert not calls and all(np.array_equal(getattr(again, f), getattr(first, f)) for f in fields)
    side = scene_camera(with_config(scene, camera={"view": [1.0, 0.0, 0.0]}))
    assert calls and len(_entries(tmp_path / "cache", "camera")) == 2
    assert not np.array_equal(side.back, first.back)


def test_a_grooms_chosen_texels_are_kept(tmp_path, groom_file, monkeypatch):
    """The clusters' projected sizes the texel choice reads (their sweeps: 0.6 s at 48 clusters) are kept: the same
    choice again in a fresh process without sweeping a cluster."""
    monkeypatch.setenv("HAIRLUT_CACHE", str(tmp_path / "cache"))
    scene = load_scene(_scene(tmp_path / "a", groom_file))
    first = texel_choice(scene)
    assert len(_entries(tmp_path / "cache", "texels")) == 1 and not first.given
    _forget()
    monkeypatch.setattr(_clusters, "_projected_sizes", lambda *a: pytest.fail("swept the clusters again"))
    again = texel_choice(scene)
    assert (again.value, again.reason) == (first.value, first.reason)


def test_prepare_in_groups_of_clusters_is_each_cluster_alone(tmp_path, groom_file):
    """synth.prepare sweeps texels and sections 4 clusters to a geometry: every cluster's frames and texels are the
    same bits as with a geometry of its own."""
    from hairlut.bench import with_config
    from hairlut.synth import _synth

    scene = with_config(load_scene(_scene(tmp_path / "a", groom_file, "clusters = 6")), render={"method": "direct"})
    pairs, tables = scene_clusters(scene, tmp_path), scene_sector_tables(scene, tmp_path)
    db = _synth._geometry_db(scene)
    specs = [s for s, _ in pairs]
    groups, memo = _synth.geometry_groups(specs), {}
    texels = _synth.texel_points(specs, texel_choice(scene).value, groups)
    for (spec, st), tb, tx, (g, c) in zip(pairs, tables, texels, groups):
        alone = _synth.prepare_cluster(scene, db, spec, st, tb)
        grouped = _synth.prepare_cluster(scene, db, spec, st, tb, tx, _synth._OneCluster(g, c, memo))
        for f in dataclasses.fields(alone.frames):
            assert np.array_equal(getattr(alone.frames, f.name), getattr(grouped.frames, f.name)), f.name
        for name in ("tangent", "normal", "position"):
            assert np.array_equal(getattr(alone, name), getattr(grouped, name)), name
