"""Light-oriented shadow map (bertails §2–3): analytic slab, front/monotonicity, resolution
independence, rotation equivariance, a brute-force ray march, input validation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut import errors
from hairlut.geometry import Strands
from hairlut.shadows import light_oriented_map, voxelize
from hairlut.shadows import ray_march as reference_ray_march


def tuft(seed=1, n=2000, v=8):
    """A dense hanging tuft: roots on a disc of radius 0.5, about 2 long, gently bent."""
    rng = np.random.default_rng(seed)
    r, phi = np.sqrt(rng.uniform(0, 1, n)) * 0.5, rng.uniform(0, 2 * np.pi, n)
    root = np.stack([r * np.cos(phi), np.zeros(n), r * np.sin(phi)], 1)
    t = np.linspace(0, 1, v)[None, :, None]
    pts = root[:, None] + t * np.array([0, -2.0, 0]) + rng.normal(0, 0.15, (n, 1, 3)) * t**2 + 0.3 * root[:, None] * t
    return Strands.from_padded(pts)


TUFT = tuft()
LIGHT = np.array([0.4, 0.7, -0.2]) / np.linalg.norm([0.4, 0.7, -0.2])
KAPPA = 0.5 / TUFT.n_strands  # about 1.5 optical depths through the thick end


def inside_points(strands, n=400, seed=0):
    lo, hi = strands.points.min(0), strands.points.max(0)
    return np.random.default_rng(seed).uniform(lo, hi, (n, 3))


def ray_march(points, light, kappa, vol, step=0.5):
    return reference_ray_march(points, light, kappa, volume=vol, step=step)


def test_frame_and_mass():
    m = light_oriented_map(TUFT, LIGHT, resolution=16, kappa=KAPPA)
    f = m.frame
    np.testing.assert_allclose(f @ f.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(f) == pytest.approx(1.0) and np.allclose(f[0], LIGHT)
    assert m.shape == (21, 21, 21) and np.allclose(m.light, LIGHT)
    assert m.density.sum() * m.spacing**3 == pytest.approx(TUFT.lengths().sum(), rel=1e-12)
    assert m.transmittance.min() >= 0 and m.transmittance.max() == 1.0


def test_uniform_slab_of_parallel_strands_is_beer_lambert():
    """15 × 15 strands on a lattice of pitch a = ds / 3 (commensurate with the cells), along the
    light, 1 long: ρ = 1 / a², and at depth d below the lit end Trans = exp(−κ ρ d).  Cell centres
    are exact (the half-cell rule) except in the half-filled end cells; between them the only error is the linear interpolation of
    the exponential, ≤ (κ ρ ds)² / 8."""
    ds, a = 0.05, 0.05 / 3
    off = (np.arange(15) - 7) * a
    x, y = np.meshgrid(off, off, indexing="ij")
    z = np.linspace(-1.0, 0.0, 41)  # 0.025-long segments: 2 density samples each, 4 per cell
    pts = np.stack(np.broadcast_arrays(x[..., None], y[..., None], z), -1).reshape(225, 41, 3)
    rho, kappa = 1 / a**2, 2.0 * a**2  # κρ = 2 per unit depth
    m = light_oriented_map(Strands.from_padded(pts), [0, 0, 1], resolution=(20, 10, 10), kappa=kappa)
    assert m.spacing == pytest.approx(ds)
    centre = m.density[:, m.shape[1] // 2, m.shape[2] // 2]
    np.testing.assert_allclose(centre[centre > 0][1:-1], rho, rtol=1e-9)  # full interior cells
    rng = np.random.default_rng(3)
    d = rng.uniform(ds, 1 - ds, 300)  # between the centres of full cells
    q = np.stack([rng.uniform(-2 * ds, 2 * ds, 300), rng.uniform(-2 * ds, 2 * ds, 300), -d], 1)
    tol = (kappa * rho * ds) ** 2 / 8 + 1e-12
    np.testing.assert_allclose(m.at(q), np.exp(-kappa * rho * d), atol=tol)


def test_front_is_lit_and_depth_is_monotone():
    m = light_oriented_map(TUFT, LIGHT, resolution=24, kappa=KAPPA)
    proj = TUFT.points @ LIGHT
    base = inside_points(TUFT, 50)
    # in front of all hair by more than the trilinear footprint (1.5 cells: the frontmost hair's cell centre
    # can lie half a cell ahead of it)
    ahead = base + (proj.max() + 1.5 * m.spacing + 1e-9 - base @ LIGHT)[:, None] * LIGHT
    np.testing.assert_array_equal(m.at(ahead), 1.0)
    far = base + np.array([10.0, 0, 0])  # beside the hair
    np.testing.assert_array_equal(m.at(far), 1.0)
    s = np.linspace(0, 6, 121)
    line = ahead[:, None, :] - s[None, :, None] * LIGHT  # walking away from the light
    T = m.at(line.reshape(-1, 3)).reshape(len(base), len(s))
    assert np.all(np.diff(T, axis=1) <= 1e-12) and T.min() >= 0
    assert T[:, -1].min() < 0.9  # some rays do cross hair


def test_resolution_independence():
    q = np.concatenate([TUFT.points[::7], inside_points(TUFT)])
    ref = light_oriented_map(TUFT, LIGHT, resolution=48, kappa=KAPPA).at(q)
    err = {r: light_oriented_map(TUFT, LIGHT, resolution=r, kappa=KAPPA).at(q) - ref for r in (12, 24)}
    rms = {r: np.sqrt(np.mean(e**2)) for r, e in err.items()}
    assert rms[24] < 0.02 and np.abs(err[24]).max() < 0.12  # max at the tuft's edge (trilinear blur)
    assert rms[24] < 0.7 * rms[12]
    # ρ is per unit volume: scaling the scene by c with κ / c leaves Trans unchanged
    big = Strands.from_padded(3.0 * TUFT.points.reshape(TUFT.n_strands, -1, 3))
    np.testing.assert_allclose(light_oriented_map(big, LIGHT, resolution=24, kappa=3 * KAPPA).at(3 * q), err[24] + ref, atol=1e-9)


def rotation(q):
    w, x, y, z = np.asarray(q) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


SMALL = tuft(seed=2, n=1500, v=6)


@settings(max_examples=8)
@given(st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1))
def test_rotation_equivariance(quat):
    """Rotating hair and light together rotates the map; only the grid's roll about L (fixed by L
    alone) changes, so Trans agrees to the discretisation error."""
    R = rotation(quat)
    q = np.concatenate([SMALL.points[::5], inside_points(SMALL, 200)])
    base = light_oriented_map(SMALL, LIGHT, resolution=32, kappa=KAPPA).at(q)
    turned = Strands.from_padded((SMALL.points @ R.T).reshape(SMALL.n_strands, -1, 3))
    rot = light_oriented_map(turned, R @ LIGHT, resolution=32, kappa=KAPPA).at(q @ R.T)
    assert np.sqrt(np.mean((rot - base) ** 2)) < 0.015 and np.abs(rot - base).max() < 0.08  # worst of 25: 0.007, 0.044


def test_agrees_with_brute_force_ray_march():
    q = np.concatenate([TUFT.points[::3], inside_points(TUFT)])
    for res in (16, 24):
        T = light_oriented_map(TUFT, LIGHT, resolution=res, kappa=KAPPA).at(q)
        ref = ray_march(q, LIGHT, KAPPA, voxelize(TUFT, res))
        assert np.sqrt(np.mean((T - ref) ** 2)) < 0.012 and np.abs(T - ref).max() < 0.06, res


def test_reference_march_shadows_points_outside_the_grid():
    """A point below the hair and outside the voxel grid, whose ray toward the light crosses the
    hair, is shadowed as much as a point on the same ray just inside the grid (no density between)."""
    vol = voxelize(TUFT, 16)
    centre = TUFT.points.mean(0)
    inside = centre - 1.2 * LIGHT  # behind the tuft's middle, still inside its bounds
    far = centre - 40.0 * LIGHT  # far outside the grid on the same ray
    t_in, t_far = ray_march(np.stack([inside, far]), LIGHT, KAPPA, vol)
    assert t_in < 0.9 and abs(t_far - t_in) < 0.02
    assert ray_march(np.stack([centre + 40.0 * LIGHT]), LIGHT, KAPPA, vol)[0] == 1.0  # ray leaves: lit


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"light": [0, 0, 0]}, "light"),
        ({"light": [np.nan, 0, 1]}, "light"),
        ({"light": [0, 1]}, "light"),
        ({"resolution": 0}, "resolution"),
        ({"resolution": (8, 8)}, "resolution"),
        ({"resolution": 8.0}, "resolution"),
        ({"resolution": True}, "resolution"),
        ({"resolution": (1024,) * 3}, "resolution"),
        ({"kappa": -1.0}, "kappa"),
        ({"kappa": np.inf}, "kappa"),
        ({"padding": -1}, "padding"),
        ({"strands": Strands(np.zeros((0, 3)), np.zeros(0, int))}, "strands"),
        ({"strands": np.zeros((4, 3))}, "strands"),
    ],
)
def test_bad_inputs(kwargs, field):
    args = {"strands": SMALL, "light": LIGHT, "resolution": 8, "kappa": 1.0, **kwargs}
    with pytest.raises(errors.ValidationError) as info:
        light_oriented_map(args.pop("strands"), args.pop("light"), **args)
    assert info.value.field == field


def test_bad_query_points():
    m = light_oriented_map(SMALL, LIGHT, resolution=8, kappa=1.0)
    for bad in (np.zeros(3), np.full((2, 3), np.nan)):
        with pytest.raises(errors.ValidationError) as info:
            m.at(bad)
        assert info.value.field == "points"
