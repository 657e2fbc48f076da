"""Real Gaunt coefficients G[i, j, k] = ∫ Y_i Y_j Y_k dω (xing §4).

They are the triple-product integrals behind the paper's R_ij = ∫ f Y_i Y_j dω once f is
itself expanded in SH (R_ij = Σ_k f_k G[i, j, k]), and they give products of expansions:
Y_i Y_j = Σ_k G[i, j, k] Y_k exactly whenever l_i + l_j ≤ lmax3.

Computed exactly (to rounding): Y_i Y_j Y_k is a spherical polynomial of degree
l_i + l_j + l_k, so the Gauss–Legendre × uniform rule of order L = ⌈(lmax1+lmax2+lmax3)/2⌉
integrates it without error.  Entries that the selection rules force to zero are then set to
exactly 0 (the quadrature leaves ~1e-17 there):

* l_i + l_j + l_k even, and |l_i − l_j| ≤ l_k ≤ l_i + l_j (triangle);
* |m_k| = |m_i| + |m_j| or |m_k| = ||m_i| − |m_j|| (azimuthal frequencies cancel);
* an even number of negative m (sin factors), else the integrand is odd in φ.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..errors import ValidationError
from ._basis import check_lmax, lm_arrays, real_sh
from ._quadrature import sphere_grid

# Largest dense tensor we build: 2**27 float64 entries = 1 GiB.
MAX_ENTRIES = 2**27


def selection_mask(lmax1: int, lmax2: int, lmax3: int) -> np.ndarray:
    """Boolean (n1, n2, n3): True where the selection rules allow a nonzero real Gaunt."""
    named = ((lmax1, "lmax1"), (lmax2, "lmax2"), (lmax3, "lmax3"))
    (l1, m1), (l2, m2), (l3, m3) = (lm_arrays(check_lmax(v, f)) for v, f in named)
    l1, m1 = l1[:, None, None], m1[:, None, None]
    l2, m2 = l2[None, :, None], m2[None, :, None]
    l3, m3 = l3[None, None, :], m3[None, None, :]
    parity = (l1 + l2 + l3) % 2 == 0
    triangle = (np.abs(l1 - l2) <= l3) & (l3 <= l1 + l2)
    a1, a2, a3 = np.abs(m1), np.abs(m2), np.abs(m3)
    freq = (a3 == a1 + a2) | (a3 == np.abs(a1 - a2))
    sines = ((m1 < 0).astype(np.int8) + (m2 < 0) + (m3 < 0)) % 2 == 0
    return parity & triangle & freq & sines


def gaunt_quadrature(lmax1: int, lmax2: int, lmax3: int) -> np.ndarray:
    """Unmasked G by the product rule of order ⌈(lmax1+lmax2+lmax3)/2⌉ (float64), uncached.

    :func:`gaunt` is this plus the selection rules and a cache; the uncached form is what a
    bake pays (the SH-table benchmark times it)."""
    grid = sphere_grid(-(-(lmax1 + lmax2 + lmax3) // 2))
    lbig = max(lmax1, lmax2, lmax3)
    y = np.asarray(real_sh(lbig, grid.dirs))
    n1, n2, n3 = ((v + 1) ** 2 for v in (lmax1, lmax2, lmax3))
    y1 = y[:, :n1] * grid.weights[:, None]
    y2, y3 = y[:, :n2], y[:, :n3]
    out = np.empty((n1, n2, n3))
    # Chunk over i so the (N, chunk·n2) product stays ~32 MiB.
    chunk = max(1, (2**22) // max(1, grid.size * n2))
    for s in range(0, n1, chunk):
        e = min(n1, s + chunk)
        p = (y1[:, s:e, None] * y2[:, None, :]).reshape(grid.size, -1)
        out[s:e] = (p.T @ y3).reshape(e - s, n2, n3)
    return out


def _check_all(lmax1, lmax2, lmax3) -> tuple[int, int, int]:
    ls = tuple(check_lmax(v, f) for v, f in ((lmax1, "lmax1"), (lmax2, "lmax2"), (lmax3, "lmax3")))
    entries = math.prod((v + 1) ** 2 for v in ls)
    if entries > MAX_ENTRIES:
        raise ValidationError("lmax", ls, f"the dense Gaunt tensor would have {entries} entries (limit {MAX_ENTRIES})")
    return ls


@functools.lru_cache(maxsize=8)
def _gaunt_cached(lmax1: int, lmax2: int, lmax3: int) -> np.ndarray:
    g = gaunt_quadrature(lmax1, lmax2, lmax3)
    g[~selection_mask(lmax1, lmax2, lmax3)] = 0.0
    g.setflags(write=False)
    return g


def gaunt(lmax1: int, lmax2: int | None = None, lmax3: int | None = None) -> np.ndarray:
    """Dense real Gaunt tensor G[i, j, k] = ∫ Y_i Y_j Y_k dω, shape (n1, n2, n3), float64.

    ``lmax2`` and ``lmax3`` default to ``lmax1``.  Results are cached and returned
    read-only (copy before modifying).  G[0, j, k] = δ_jk / (2√π); G is symmetric under
    permutations of axes with equal band limits.
    """
    lmax2 = lmax1 if lmax2 is None else lmax2
    lmax3 = lmax1 if lmax3 is None else lmax3
    return _gaunt_cached(*_check_all(lmax1, lmax2, lmax3))


def gaunt_sparse(lmax1: int, lmax2: int | None = None, lmax3: int | None = None, *, tol: float = 1e-14):
    """Nonzero real Gaunt coefficients as (indices (K, 3) int64, values (K,) float64).

    Keeps |G| > ``tol``; the default also drops the "nontrivial zeros" of the Wigner 3j
    symbols, which the quadrature returns as ~1e-17 instead of 0.  Rows are sorted by
    (i, j, k).
    """
    g = gaunt(lmax1, lmax2, lmax3)
    tol = float(tol)
    if not (math.isfinite(tol) and tol >= 0):
        raise ValidationError("tol", tol, "must be finite and ≥ 0")
    idx = np.argwhere(np.abs(g) > tol)
    return idx, g[tuple(idx.T)].copy()
