"""A virtual hrir_db's feature index from the parts' own features (``hairlut.hrir._parts``).

Each process computes its parts' features as it indexes them, in the whole database's aligned
chunks, so the leader reads a few numbers per sector instead of every density grid.  The
reference is the whole database's features computed at once (``sector_features`` over every
sector, as a copied asset computes them) and the copied asset itself.
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from hairlut.geometry.density import sector_density
from hairlut.geometry.features import sector_features
from hairlut.hrir import bake, resolve_recipe
from hairlut.hrir._bake import sample_block
from hairlut.hrir._io import FEATURE_CHUNK, _row_areas
from hairlut.hrir._parts import part_features, part_index
from hairlut.march._geometry import sector_geometry


def _inputs(r, n):
    splats, params = sample_block(r, 0, n)
    density = sector_density(splats, tuple(r["sectors"]["grid"]), density_scale=r["sectors"]["density_scale"], chunk=1)
    geometry = sector_geometry(params, kappa=r["trace"]["extinction"], n_pix=r["trace"]["pixels"])
    return density, geometry


@pytest.mark.parametrize("features", ["basic", "moments"])
@pytest.mark.parametrize("total, cuts", [(20, [0, 3, 11, 20]), (600, [0, 7, 255, 256, 300, 512, 600])])
def test_part_features_are_the_whole_databases_bit_for_bit(features, total, cuts):
    r = resolve_recipe({"sectors": {"count": total, "grid": [8, 6], "features": features}})
    density, geometry = _inputs(r, total)
    n_s, n_r = r["sectors"]["grid"]
    whole = sector_features(density, _row_areas({"geometry": geometry}, n_s, n_r), features, chunk=FEATURE_CHUNK)
    for s, e in zip(cuts[:-1], cuts[1:]):
        got = part_features(r, density[s:e], geometry[s:e], s, total)
        np.testing.assert_array_equal(got, whole[s:e], err_msg=f"sectors {s}..{e}")


def test_virtual_feature_index_is_the_copied_assets(tmp_path):
    """Parts of 48 sectors straddle the 256-sector feature chunks; the leader reads only their features."""
    given = {"sectors": {"count": 300, "grid": [8, 8]}, "angles": {"views": 2, "lights": 2}, "trace": {"pixels": 4, "steps": 2}}
    copy = bake(given, tmp_path / "copy.h5", block=48)
    virtual = bake(given, tmp_path / "virtual.h5", block=48, distributed=True, merge="virtual")
    assert virtual["merge"] == "virtual" and copy["merge"] == "copy"
    part = sorted((tmp_path / "virtual.h5.parts").glob("part-*.h5"))[1]
    small = part_index(resolve_recipe(given), part)
    assert set(small) == {"features", "errors"} and small["features"].shape == (48, 3)
    with h5py.File(tmp_path / "copy.h5") as a, h5py.File(tmp_path / "virtual.h5") as b:
        for name in ("features", "features_mean", "features_std", "density", "alpha"):
            np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)
        assert b["density"].is_virtual and not b["features"].is_virtual
