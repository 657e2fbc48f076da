"""The host's share of a sharded HRIR bake, done once per block: bitwise the per-sector work it replaced.

A block's sectors are sampled by ``sample_each`` (each sector from its own generator, the arithmetic
between draws done once for the block) and their densities by ``sector_density(chunk=1)`` (one call per
splat width, the one-sector program mapped over the sectors).  The references are the per-sector paths:
``sample_sectors(1, ...)`` per seed, and one ``density_kernel`` call per sector at its own width.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from hairlut.errors import ValidationError
from hairlut.geometry import SectorSpace, sample_sectors
from hairlut.geometry.density import _columns, _width, density_kernel, sector_density
from hairlut.geometry.sampler import sample_each
from hairlut.hrir import resolve_recipe
from hairlut.hrir._bake import sample_block, sector_seed
from hairlut.hrir._recipe import sector_space

FIELDS = ("center", "sigma", "radius", "mask", "area_scale", "v_range")


def _per_sector(seeds, space):
    drawn = [sample_sectors(1, space, seed=s) for s in seeds]
    splats = {f: np.concatenate([getattr(d.splats, f) for d in drawn]) for f in FIELDS}
    params = {k: np.concatenate([d.params[k] for d in drawn]) for k in drawn[0].params}
    return splats, params


@pytest.mark.parametrize(
    "space",
    [SectorSpace(), SectorSpace(strands=(0, 6), clumps=(1, 3)), SectorSpace(profile_weights=(0.0, 0.0, 1.0))],
    ids=["default", "few", "clumped"],
)
def test_sample_each_is_per_sector_sampling_bit_for_bit(space):
    seeds = [sector_seed(5, i) for i in range(160)]
    splats, params = _per_sector(seeds, space)
    got = sample_each(seeds, space)
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(got.splats, f), splats[f], err_msg=f)
    assert set(got.params) == set(params)
    for k, v in params.items():
        assert got.params[k].dtype == v.dtype, k
        np.testing.assert_array_equal(got.params[k], v, err_msg=k)
    if space.strands[0] == 0:
        assert (params["strands"] == 0).any(), "the case should hold an empty sector"


def test_sample_each_validates():
    with pytest.raises(ValidationError, match="seeds"):
        sample_each([])
    with pytest.raises(ValidationError, match="seed"):
        sample_each([1, -2])
    with pytest.raises(ValidationError, match="space"):
        sample_each([1], space="default")


def _density_one_call_each(splats, grid, scale):
    """The per-sector reference: one ``density_kernel`` call per sector, padded to its own width."""
    out = []
    for i in range(len(splats.mask)):
        w = _width(int(splats.mask[i].sum()))
        args = [
            _columns(splats.center[i : i + 1], w, 0.0),
            _columns(splats.sigma[i : i + 1], w, 1.0),
            _columns(splats.radius[i : i + 1], w, 0.0),
            _columns(splats.mask[i : i + 1], w, False),
            splats.area_scale[i : i + 1],
            splats.v_range[i : i + 1],
        ]
        arrs = [jnp.asarray(x, dtype=np.float32 if x.dtype.kind == "f" else None) for x in args]
        out.append(np.asarray(density_kernel(*arrs, jnp.asarray(scale, np.float32), n_s=grid[0], n_r=grid[1])))
    return np.concatenate(out)


def test_block_density_is_one_call_per_sector_bit_for_bit():
    r = resolve_recipe({"sectors": {"count": 96, "grid": [12, 10]}})
    splats, _ = sample_block(r, 0, 96)
    widths = {_width(int(c)) for c in splats.mask.sum(axis=1)}
    assert len(widths) >= 3, "the block should span several splat widths"
    scale = r["sectors"]["density_scale"]
    ref = _density_one_call_each(splats, (12, 10), scale)
    got = sector_density(splats, (12, 10), density_scale=scale, chunk=1)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, ref)
    # the sectors' grouping (a sub-block, another order) does not move a sector's bits
    pick = np.arange(95, 20, -3)
    sub = type(splats)(*(getattr(splats, f)[pick] for f in FIELDS))
    np.testing.assert_array_equal(sector_density(sub, (12, 10), density_scale=scale, chunk=1), ref[pick])


def test_sample_block_draws_each_sector_from_its_own_seed():
    r = resolve_recipe({"sectors": {"count": 50, "seed": 9}})
    splats, params = sample_block(r, 17, 41)
    ref_splats, ref_params = _per_sector([sector_seed(9, i) for i in range(17, 41)], sector_space(r))
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(splats, f), ref_splats[f], err_msg=f)
    for k, v in params.items():
        np.testing.assert_array_equal(v, ref_params[k], err_msg=k)


def test_storage_error_in_float32_is_the_float64_one():
    """The float16 rounding error of float32 data, differenced in float32 (write_shard's host work), equals the
    float64 difference on every value: random, float16-subnormal, tiny, near and past float16's largest."""
    from hairlut.hrir._io import storage_errors

    rng = np.random.default_rng(4)
    f16 = np.finfo(np.float16)
    pools = [
        rng.random(5000),
        rng.random(5000) * 6e-5,
        rng.random(5000) * 1e-7,
        65504 - rng.random(5000) * 40,
        np.array([0.0, 1e-45, 2.0**-25, 2.0**-24 * 1.5, float(f16.max), float(f16.max) + 15.0, 65519.99]),
    ]
    recipe = {"storage": {"dtype": "float16"}}
    for pool in pools:
        x = (pool * rng.choice([-1.0, 1.0], pool.size)).astype(np.float32)
        for i in range(0, x.size, 997):
            part = x[i : i + 997]
            got = storage_errors(recipe, {"alpha": part, "reflectance": part[::-1].copy()})
            ref = float(np.max(np.abs(part.astype(np.float16).astype(np.float64) - part)))
            assert got["alpha"] == ref and got["reflectance"] == ref
    with np.errstate(over="ignore"):  # past float16's range: an infinite error either way
        assert storage_errors(recipe, {"alpha": np.float32([7e4]), "reflectance": np.float32([1.0])})["alpha"] == np.inf
