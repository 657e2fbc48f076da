"""Evaluating a per-row JAX function block by block (inside jit).

Large batched queries are split into fixed-size blocks with ``lax.map`` so that
each block's intermediates stay in cache and memory stays bounded; the last
block is padded by repeating the final row, and the padding is cut off again.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def map_blocks(fn, xs: tuple, block: int):
    """``fn(*blocks)`` over the leading axis of every array in ``xs``, ``block`` rows at a time.

    ``fn`` returns an array or a tuple of arrays with the block's rows leading; the
    result has the same structure with all N rows, in order.
    """
    n = xs[0].shape[0]
    nb = -(-n // block)
    pad = nb * block - n

    def split(x):
        x = jnp.pad(x, [(0, pad)] + [(0, 0)] * (x.ndim - 1), mode="edge")
        return x.reshape(nb, block, *x.shape[1:])

    out = jax.lax.map(lambda b: fn(*b), tuple(split(x) for x in xs))
    return jax.tree_util.tree_map(lambda o: o.reshape(nb * block, *o.shape[2:])[:n], out)
