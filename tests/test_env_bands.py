"""Environment bands from the radiance error (issue 12 item 4): hairlut.scene._envbands and the windows.

Independent reference: the radiance integral ∫ L(ω) k(ω) dω by brute-force lat-long quadrature of
the Kajiya–Kay lobes against the Funk–Hecke band sum; the windows' factors; the choice of bands as
the smallest meeting the tolerance; ringing measured (and damped by a window) on a sharp light.
"""

import numpy as np
import pytest

from hairlut import errors
from hairlut.envlight import latlong_samples
from hairlut.scene import window_coeffs, window_factors
from hairlut.scene._envbands import _fibonacci, band_radiance, choose_bands, radiance_error
from hairlut.sh import real_sh


def test_band_sum_equals_the_radiance_integral():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(25, 2)) * np.repeat(1.0 / (1 + np.arange(5)), 2 * np.arange(5) + 1)[:, None]
    a[0] += 3.0
    kd, ks, p = 0.4, 0.7, 9.0
    terms = band_radiance(a, kd, ks, p, tangents=16, theta_v=5)
    e = terms.sum(0)  # (t, θ′, C)
    dirs, omega = latlong_samples(400, 800)
    dirs, omega = dirs.reshape(-1, 3), omega.reshape(-1)
    L = np.asarray(real_sh(4, dirs), np.float64) @ a  # (n, C)
    t = _fibonacci(16)
    for i in (0, 5, 11):
        th = np.arccos(np.clip(dirs @ t[i], -1, 1))
        for j, tv in enumerate(np.linspace(0, np.pi, 5)):
            k = kd * np.sin(th) + ks * np.maximum(0.0, -np.cos(th + tv)) ** p
            ref = (omega * k) @ L
            np.testing.assert_allclose(e[i, j], ref, rtol=2e-3, atol=2e-3 * np.abs(ref).max())


def test_windows():
    for w in ("hanning", "lanczos"):
        s = window_factors(8, w)
        assert s[0] == 1.0 and np.all(np.diff(s) < 0) and np.all(s > 0)
    assert np.all(window_factors(8, "none") == 1.0)
    c = np.ones((16, 3))
    out = window_coeffs(c, "hanning")
    np.testing.assert_allclose(out[4:9, 0], window_factors(4, "hanning")[2])
    with pytest.raises(errors.ValidationError, match="environment.window"):
        window_factors(4, "kaiser")
    with pytest.raises(errors.ValidationError, match="coeffs"):
        window_coeffs(np.ones((10, 3)), "none")


def test_choose_bands_is_the_smallest_within_tolerance_and_windows_damp_ringing():
    from hairlut.envlight import sky_light

    terms = band_radiance(sky_light(19).coeffs, 0.0, 1.0, 49.0, tangents=512, theta_v=9)  # the sky's specular term
    errs = [radiance_error(terms, b)[0] for b in range(1, 21)]
    assert errs[-1] < 1e-12 and errs[2] > errs[10]
    for tol in (0.3, 0.1, 0.02):
        b, err, _ = choose_bands(terms, tol)
        assert err <= tol and err == errs[b - 1] and (b == 3 or errs[b - 2] > tol)
    for w in ("hanning", "lanczos"):
        _, clamped_none = radiance_error(terms, 5, "none")
        _, clamped_w = radiance_error(terms, 5, w)
        assert clamped_none > 0.01 and clamped_w < 0.5 * clamped_none  # truncation rings below 0; a window damps it
