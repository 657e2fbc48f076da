"""Exact SH convolution tables for Kajiya–Kay hair (xing §4, eqs 2–5) and their lookup.

For fixed θ′ the kernels are zonal around t, so with k_l their Legendre
coefficients (see ``_zonal``) and G the real Gaunt coefficients,

    R(i, j, t) = Σ_k k_{l(k)} Y_k(t) G[k, i, j],    l(k) ≤ l_i + l_j,

which is exact at every t.  Rd uses the constant diffuse k_l; Rs uses k_l(θ′),
evaluated anywhere from its per-half Chebyshev series.  A light change
contracts the light coefficients into G once (eqs 4–5):

    Cd(j, t) = Σ_k kd_l Y_k(t) Hd[k, j],   Hd[k, j] = Σ_i a_i G[k, i, j],

and similarly Cs, so that per vertex I = Σ_j b_j (Kd·Cd + Ks·Cs) costs
O((l_light + l_trans + 1)²·n) instead of O(m·n) table reads.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from .._blocks import map_blocks
from ..assets import read_table
from ..sh import check_dirs, real_sh_soa
from ..sh import real_sh_kernel as _real_sh_kernel
from ._kind import KIND
from ._zonal import cheb_coeffs, cheb_eval

Array = jax.Array


def _sh(dirs, lmax):
    return _real_sh_kernel(dirs, lmax=lmax)


@functools.partial(jax.jit, static_argnames=("lmax",))
def _rd_kernel(t, kd, gaunt, lmax):
    y = _sh(t, lmax) * kd  # (..., K): k_l already expanded per k
    return jnp.einsum("...k,kij->...ij", y, gaunt, precision=jax.lax.Precision.HIGHEST)


@functools.partial(jax.jit, static_argnames=("lmax",))
def _rs_kernel(t, theta_v, cheb, gaunt, lmax, l_of_k):
    k_l = cheb_eval(cheb, theta_v)  # (..., L+1)
    y = _sh(t, lmax) * jnp.take(k_l, l_of_k, axis=-1)
    return jnp.einsum("...k,kij->...ij", y, gaunt, precision=jax.lax.Precision.HIGHEST)


SOA_LMAX = 16  # hairlut.sh.real_sh_soa unrolls up to this lmax (compile time grows fast beyond)
BLOCK = 2048  # vertices per block: keeps the (block, (L+1)²) working set in cache


def _radiance_block(t, theta_v, b, kd, ks, kd_k, hd, cheb, hs, l_of_k_s, lmax_d, lmax_s):
    """I = Σ_k Y_k(t) Σ_j b_j (Kd·kd_l Hd[k,j] + Ks·ks_l(θ′) Hs[k,j]) for one block (xing eq. 2 via 4–5).

    Y is computed unrolled with the SH index leading up to lmax :data:`SOA_LMAX`, so
    the block's work stays in cache; above it (tables with many bands) by the general
    recurrence of ``real_sh_kernel``, the one ``rd``/``rs`` use.  Per vertex it costs
    (l_s + l_t + 1)²·n_trans·C multiply-adds.
    """
    lmax = max(lmax_d, lmax_s)
    if lmax <= SOA_LMAX:
        y = real_sh_soa(t[:, 0], t[:, 1], t[:, 2], lmax)  # (K, n)
    else:
        y = _real_sh_kernel(t, lmax).T  # (K, n): general path for every band count the baker accepts
    out = 0.0
    if hd is not None:
        w = y[: hd.shape[0]] * kd_k[:, None] * kd[None, :]
        out = out + jnp.einsum("kn,nj,kjc->nc", w, b[:, : hd.shape[1]], hd, precision=jax.lax.Precision.HIGHEST)
    if hs is not None:
        k_l = jnp.take(cheb_eval(cheb, theta_v), l_of_k_s, axis=-1)  # (n, K)
        w = y[: hs.shape[0]] * k_l.T * ks[None, :]
        out = out + jnp.einsum("kn,nj,kjc->nc", w, b[:, : hs.shape[1]], hs, precision=jax.lax.Precision.HIGHEST)
    return out


@functools.partial(jax.jit, static_argnames=("lmax_d", "lmax_s"))
def _radiance_kernel(t, theta_v, b, kd, ks, kd_k, hd, cheb, hs, l_of_k_s, lmax_d, lmax_s):
    """Radiance for flat (N,) vertices, evaluated block by block."""
    return map_blocks(
        lambda *blk: _radiance_block(*blk, kd_k, hd, cheb, hs, l_of_k_s, lmax_d, lmax_s), (t, theta_v, b, kd, ks), BLOCK
    )


def _l_of_k(lmax: int) -> np.ndarray:
    return np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)


def _check_theta_v(theta_v, field="theta_v") -> np.ndarray:
    tv = np.asarray(theta_v, dtype=np.float64)
    if not np.all(np.isfinite(tv)):
        raise errors.ValidationError(field, theta_v, "θ′ must be finite")
    if tv.size and (tv.min() < -1e-12 or tv.max() > np.pi + 1e-12):
        raise errors.ValidationError(field, (float(tv.min()), float(tv.max())), "θ′ = angle(t, v) lies in [0, π]")
    return np.clip(tv, 0.0, np.pi)


@dataclass(frozen=True)
class Bands:
    """Band counts (lmax + 1) of the light (diffuse, specular) and of the transmittance."""

    light_diffuse: int
    light_specular: int
    transmittance: int

    @property
    def n_light_diffuse(self) -> int:
        return self.light_diffuse**2

    @property
    def n_light_specular(self) -> int:
        return self.light_specular**2

    @property
    def n_trans(self) -> int:
        return self.transmittance**2


class SHTables:
    """The compact exact tables: kernel Legendre coefficients and a Gaunt tensor.

    ``rd(t)`` → (..., n_light_diffuse, n_trans); ``rs(t, θ′)`` → (..., n_light_specular,
    n_trans); ``contract(a)`` → :class:`Contracted` with ``cd``/``cs``; ``radiance``.
    Everything is float64, jit-compiled, and exact at any t and θ′.
    """

    def __init__(self, bands: Bands, p: float, kd_l, ks_cheb, gaunt, recipe: dict | None = None):
        self.bands, self.p, self.recipe = bands, p, recipe or {}
        self.lmax_d = bands.light_diffuse + bands.transmittance - 2 if kd_l is not None else -1
        self.lmax_s = bands.light_specular + bands.transmittance - 2 if ks_cheb is not None else -1
        self.kd_l = None if kd_l is None else np.asarray(kd_l, np.float64)
        self.ks_cheb = None if ks_cheb is None else np.asarray(ks_cheb, np.float64)
        self.gaunt = np.asarray(gaunt, np.float64)

    @classmethod
    def load(cls, path) -> SHTables:
        """Read a validated ``sh_tables`` asset (see :func:`load_sh_tables`)."""
        return load_sh_tables(path)

    @property
    def has_diffuse(self) -> bool:
        return self.kd_l is not None

    @property
    def has_specular(self) -> bool:
        return self.ks_cheb is not None

    # -- pieces of G for each table
    def _g(self, lmax, n_light):
        return self.gaunt[: (lmax + 1) ** 2, :n_light, : self.bands.n_trans]

    def _need(self, what: str):
        ok = self.has_diffuse if what == "diffuse" else self.has_specular
        if not ok:
            raise errors.ValidationError("tables", what, f"these tables were baked without the {what} term")

    def rd(self, t) -> Array:
        """Rd(i, j, t) = ∫ sin θ Y_i Y_j dω at unit tangents t (..., 3)."""
        self._need("diffuse")
        t = check_dirs(t, field="t").astype(np.float64)
        with jax.enable_x64(True):
            kd = jnp.asarray(self.kd_l[_l_of_k(self.lmax_d)])
            return _rd_kernel(jnp.asarray(t), kd, jnp.asarray(self._g(self.lmax_d, self.bands.n_light_diffuse)), self.lmax_d)

    def rs(self, t, theta_v) -> Array:
        """Rs(i, j, t, θ′) = ∫ max(0, cos(π − θ − θ′))^p Y_i Y_j dω, broadcast over t (..., 3) and θ′ (...)."""
        self._need("specular")
        t = check_dirs(t, field="t").astype(np.float64)
        tv = _check_theta_v(theta_v)
        with jax.enable_x64(True):
            return _rs_kernel(
                jnp.asarray(t),
                jnp.asarray(tv),
                jnp.asarray(self.ks_cheb),
                jnp.asarray(self._g(self.lmax_s, self.bands.n_light_specular)),
                self.lmax_s,
                jnp.asarray(_l_of_k(self.lmax_s)),
            )

    def specular_coeffs(self, theta_v) -> Array:
        """k_l(θ′) of the specular kernel (..., lmax_s + 1)."""
        self._need("specular")
        with jax.enable_x64(True):
            return cheb_eval(jnp.asarray(self.ks_cheb), jnp.asarray(_check_theta_v(theta_v)))

    def contract(self, a) -> Contracted:
        """Fold light coefficients a (n_light,) or (n_light, C) into the tables (eqs 4–5)."""
        a = np.asarray(a, dtype=np.float64)
        squeeze = a.ndim == 1
        a = a[:, None] if squeeze else a
        if a.ndim != 2 or not np.all(np.isfinite(a)):
            raise errors.ValidationError("a", a.shape, "light coefficients are a finite (n_light,) or (n_light, C) array")
        need = max(self.bands.n_light_diffuse if self.has_diffuse else 0, self.bands.n_light_specular if self.has_specular else 0)
        if a.shape[0] < need:
            raise errors.ValidationError("a", a.shape, f"need at least {need} light coefficients for these tables")
        with jax.enable_x64(True):
            hd = hs = None
            if self.has_diffuse:
                g = jnp.asarray(self._g(self.lmax_d, self.bands.n_light_diffuse))
                hd = jnp.einsum(
                    "kij,ic->kjc", g, jnp.asarray(a[: self.bands.n_light_diffuse]), precision=jax.lax.Precision.HIGHEST
                )
            if self.has_specular:
                g = jnp.asarray(self._g(self.lmax_s, self.bands.n_light_specular))
                hs = jnp.einsum(
                    "kij,ic->kjc", g, jnp.asarray(a[: self.bands.n_light_specular]), precision=jax.lax.Precision.HIGHEST
                )
        return Contracted(self, hd, hs, squeeze)

    def radiance(self, a, b, t, theta_v, kd=1.0, ks=1.0) -> Array:
        """I = Σ_i Σ_j a_i b_j (Kd·Rd + Ks·Rs) per vertex (xing eq. 2), as (..., C) or (...)."""
        return self.contract(a).radiance(b, t, theta_v, kd, ks)


class Contracted:
    """Tables with a light folded in: ``cd(t)`` (..., n_trans[, C]) and ``cs(t, θ′)``."""

    def __init__(self, tables: SHTables, hd, hs, squeeze: bool):
        self.tables, self.hd, self.hs, self._squeeze = tables, hd, hs, squeeze

    def _out(self, x):
        return x[..., 0] if self._squeeze else x

    def cd(self, t) -> Array:
        """Cd(j, t) = Σ_i a_i Rd(i, j, t) (eq. 4)."""
        tb = self.tables
        tb._need("diffuse")
        t = check_dirs(t, field="t").astype(np.float64)
        with jax.enable_x64(True):
            kd = jnp.asarray(tb.kd_l[_l_of_k(tb.lmax_d)])
            return self._out(_rd_kernel(jnp.asarray(t), kd, self.hd.transpose(0, 2, 1), tb.lmax_d).swapaxes(-1, -2))

    def cs(self, t, theta_v) -> Array:
        """Cs(j, t, θ′) = Σ_i a_i Rs(i, j, t, θ′) (eq. 5)."""
        tb = self.tables
        tb._need("specular")
        t = check_dirs(t, field="t").astype(np.float64)
        tv = _check_theta_v(theta_v)
        with jax.enable_x64(True):
            out = _rs_kernel(
                jnp.asarray(t),
                jnp.asarray(tv),
                jnp.asarray(tb.ks_cheb),
                self.hs.transpose(0, 2, 1),
                tb.lmax_s,
                jnp.asarray(_l_of_k(tb.lmax_s)),
            )
            return self._out(out.swapaxes(-1, -2))

    def radiance(self, b, t, theta_v, kd=1.0, ks=1.0, dtype="float64") -> Array:
        """I = Σ_j b_j (Kd·Cd + Ks·Cs) per vertex: b (..., ≥ n_trans), t (..., 3), θ′ (...).

        ``dtype="float32"`` trades exactness (relative error ~1e-6) for speed.
        """
        tb = self.tables
        if dtype not in ("float64", "float32"):
            raise errors.ValidationError("dtype", dtype, "use float64 or float32")
        t = check_dirs(t, field="t").astype(np.float64)
        tv = _check_theta_v(theta_v)
        b = np.asarray(b, dtype=np.float64)
        if b.ndim < 1 or b.shape[-1] < tb.bands.n_trans or not np.all(np.isfinite(b)):
            raise errors.ValidationError("b", b.shape, f"transmittance coefficients are finite (..., {tb.bands.n_trans})")
        for name, v in (("kd", kd), ("ks", ks)):
            if not np.all(np.isfinite(np.asarray(v, np.float64))):
                raise errors.ValidationError(name, v, "must be finite")
        shape = np.broadcast_shapes(t.shape[:-1], tv.shape, b.shape[:-1], np.shape(kd), np.shape(ks))

        def arr(x, tail=()):
            return None if x is None else jnp.asarray(np.broadcast_to(x, shape + tail).reshape(-1, *tail), dtype)

        def const(x):
            return None if x is None else jnp.asarray(x, dtype)

        with jax.enable_x64(True):
            out = _radiance_kernel(
                arr(t, (3,)),
                arr(tv),
                arr(b, b.shape[-1:]),
                arr(np.asarray(kd, np.float64)),
                arr(np.asarray(ks, np.float64)),
                None if self.hd is None else const(tb.kd_l[_l_of_k(tb.lmax_d)]),
                const(self.hd),
                None if self.hs is None else const(tb.ks_cheb),
                const(self.hs),
                None if self.hs is None else jnp.asarray(_l_of_k(tb.lmax_s)),
                max(tb.lmax_d, 0),
                max(tb.lmax_s, 0),
            ).reshape(*shape, -1)
            return self._out(out)


def _shape_fault(path, name: str, got: tuple, want: tuple, why: str):
    """CorruptAssetError unless ``got`` has ``want``'s rank and each dimension ≥ want (None: any)."""
    if len(got) != len(want) or any(w is not None and g < w for g, w in zip(got, want)):
        shown = tuple("any" if w is None else f"≥{w}" for w in want)
        raise errors.CorruptAssetError(path, f"table {name!r} has shape {got}, its recipe ({why}) needs {shown}")


def load_sh_tables(path: str | os.PathLike) -> SHTables:
    """Read a ``sh_tables`` asset (validated) into exact lookup tables.

    Besides the store's checks (checksums, no foreign references, finite values), the
    stored recipe must be a valid resolved recipe and every table must have the shape
    that recipe implies; a file whose checksums pass but whose contents disagree with
    its recipe raises :class:`~hairlut.errors.CorruptAssetError` naming the table.
    """
    from ._recipe import resolve_recipe

    t = read_table(path, kind=KIND)
    try:
        r = resolve_recipe(t.recipe, budget=False)
    except errors.ValidationError as exc:
        raise errors.CorruptAssetError(path, f"stored recipe is not valid: {exc}") from None
    bands = Bands(r["bands"]["light_diffuse"], r["bands"]["light_specular"], r["bands"]["transmittance"])
    kern = r["kernel"]
    for name in (["kernel/diffuse_k"] if kern["diffuse"] else []) + (["kernel/specular_k"] if kern["specular"] else []):
        if name not in t.variables:
            raise errors.MissingDatasetError(path, f"required dataset {name!r} is missing")
    T = bands.transmittance
    lmax_d = bands.light_diffuse + T - 2 if kern["diffuse"] else -1
    lmax_s = bands.light_specular + T - 2 if kern["specular"] else -1
    n_light = max(bands.n_light_diffuse if kern["diffuse"] else 0, bands.n_light_specular if kern["specular"] else 0)
    why = f"bands {bands.light_diffuse}/{bands.light_specular}/{T}"
    _shape_fault(path, "gaunt", t["gaunt"].shape, ((max(lmax_d, lmax_s) + 1) ** 2, n_light, bands.n_trans), why)
    kd = ks = None
    if kern["diffuse"]:
        kd = t["kernel/diffuse_k"]
        _shape_fault(path, "kernel/diffuse_k", kd.shape, (lmax_d + 1,), why)
    if kern["specular"]:
        values = t["kernel/specular_k"]
        _shape_fault(path, "kernel/specular_k", values.shape, (4, lmax_s + 1), why)
        if values.shape[0] % 2:
            raise errors.CorruptAssetError(
                path, f"table 'kernel/specular_k' has {values.shape[0]} rows; it holds two equal θ′ halves (an even count)"
            )
        ks = cheb_coeffs(values.reshape(2, values.shape[0] // 2, values.shape[1]))
    if "light/a" in t.variables:
        _shape_fault(path, "light/a", t["light/a"].shape, (n_light, 1), why)
    dense = {
        "dense/t_dirs": (None, 3),
        "dense/rd": (None, bands.n_light_diffuse, bands.n_trans),
        "dense/rs": (None, None, bands.n_light_specular, bands.n_trans),
    }
    for name, want in dense.items():
        if name in t.variables:
            _shape_fault(path, name, t[name].shape, want, why)
    tables = SHTables(bands, float(kern["p"]), kd, ks, t["gaunt"], r)
    tables.source = t
    return tables
