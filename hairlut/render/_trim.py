"""Layers that stay on the hair: each cluster's layer fragments kept only where its own strands are, seen from the camera.

A cluster's layer surfaces (satf §3, eq 1: an ellipse swept along the trajectory) are bigger than its strands where
the strands do not fill them, and its in-plane maps (§5–6) put α on a layer texel from the strands that texel's
*in-plane* ray crosses, at the two cross-sections around it (eq 7).  Both hold while the strands run along the
trajectory.  Where they do not, the α lands where the cluster has no hair: a fitted cluster's lengthened start
(``hairlut.geometry.fit``: roots spread over the scalp make its first cross-sections wide, and its strands cross
them at a slant), a fat ellipse seen at a slant (the in-plane ray and the camera ray part by the chord times
cot ψ), and eq 7's interpolation between a full cross-section and an empty one.  On the Sintel groom (128², direct
maps) 6.7 % of the frame's α lay outside the strands' silhouette dilated by 3 pixels, most of it near the start of
three clusters: translucent sheets past the hair (benchmarks/records.md, 2026-12-04).

Trimming the surfaces where a cluster's strands are *not* can be view-independent only in part: a layer texel
carries the α of strands anywhere along its ray (the front surface of a flat curtain seen face-on holds all of the
curtain's α, far from every strand in 3-D).  Cutting texels whose own sector is empty misses the sheets (their
sections hold strands; and with track reads a texel reads the sectors along its ray, not its own), clipping the
meshes to the strands' span in t removes nothing (the fit lengthens each cluster only just past its strands), and
a per-texel trim leaks a texel's width through the bilinear texture.  So the trim is made per camera, in
the camera pass, where the silhouette is known: :func:`strand_footprints` draws each cluster's footprint, the
pixels within its strands' projected radius plus a margin (:func:`texel_margins`: two texels) of their centre lines, and
``_fragments.plan_fragments(keep=)`` drops the cluster's fragments outside it.  Inside the footprint nothing
changes (α and colour are the maps'), so the trim removes only α that lies off the cluster's own strands; the margin
keeps it from cutting the layers into single strands finer than the texture resolves.
"""

from __future__ import annotations

import math

import numpy as np

from .. import errors

#: The least margin, pixels, the footprint reaches past each strand's projected radius (:func:`texel_margins`).
MIN_MARGIN = 1.0
#: The margin in texels: a layer's α is its strands' blurred over about a texel each way (the maps' splats and the
#: bilinear texture), and a one-texel margin cut those tails: mean α 4.1 % (Sintel) and 2.3 % (curly groom) below the
#: strand render, against 2.2 % and 1.9 % with two texels, while α outside the strands' silhouette stays 0.38 % and
#: 0.05 % of the frame's (0.63 % and 0.09 % untrimmed); FLIP 0.132 → 0.136 and 0.139 → 0.140 (128², defaults).
MARGIN_TEXELS = 2.0
#: Centre-line samples per pixel of projected segment length.
SAMPLES_PER_PIXEL = 2.0


#: Centre-line samples held at once (bounds the memory of a big cluster's footprint).
CHUNK = 1 << 22
#: The most samples one segment takes (half-pixel spacing across a 16k-pixel frame and more).
PER_SEGMENT = 1 << 16


def _segments(cam, strands) -> tuple[np.ndarray, ...]:
    """Pixel x, y and projected radius (pixels) of both ends of every segment of ``strands`` (a
    :class:`~hairlut.geometry.Strands`): (x0, y0, r0, x1, y1, r1), each (S,).  A perspective camera drops the segments
    with an end at or behind the eye."""
    p = np.asarray(strands.points, np.float64)
    if strands.thickness is None:
        raise errors.ValidationError("strands.thickness", None, "the trim needs each strand's thickness (its radius)")
    r = 0.5 * np.asarray(strands.thickness, np.float64)
    x, y, depth = cam.project(p)
    rx, ry, _ = cam.project(p + r[:, None] * cam.right)
    rpx = np.hypot(rx - x, ry - y)
    last = np.zeros(len(p), bool)
    last[np.asarray(strands.offsets)[1:] - 1] = True
    a = np.flatnonzero(~last)
    b = a + 1
    if cam.projection == "perspective":
        front = (depth[a] > 0) & (depth[b] > 0)
        a, b = a[front], b[front]
    return x[a], y[a], rpx[a], x[b], y[b], rpx[b]


def _counts(x0, y0, x1, y1) -> np.ndarray:
    """Samples per segment, both ends included: 1 / :data:`SAMPLES_PER_PIXEL` pixel apart or closer."""
    n = np.ceil(SAMPLES_PER_PIXEL * np.hypot(x1 - x0, y1 - y0))
    return np.clip(np.nan_to_num(n, nan=1.0), 1, PER_SEGMENT).astype(np.int64) + 1


def _samples(seg, lo: int, hi: int):
    """Points every 1 / :data:`SAMPLES_PER_PIXEL` pixel (or closer) along segments lo … hi − 1 of ``seg``
    (:func:`_segments`), both ends included: x, y and the radius, each interpolated."""
    x0, y0, r0, x1, y1, r1 = (v[lo:hi] for v in seg)
    n = _counts(x0, y0, x1, y1)
    i = np.repeat(np.arange(n.size), n)
    f = (np.arange(i.size) - np.repeat(np.cumsum(n) - n, n)) / (n[i] - 1)
    return x0[i] + f * (x1 - x0)[i], y0[i] + f * (y1 - y0)[i], r0[i] + f * (r1 - r0)[i]


def slack() -> float:
    """Pixels a footprint's test adds to the reach: half a pixel's diagonal (a sample lies anywhere in the pixel it
    marks) and half the sample spacing (a centre line's nearest point lies between two samples)."""
    return math.sqrt(0.5) + 0.5 / SAMPLES_PER_PIXEL


def texel_margins(cam, positions) -> np.ndarray:
    """(C,) pixels: each cluster's margin, :data:`MARGIN_TEXELS` times the median projected spacing of its layer
    texels (the larger of the medians along t and along u), at least :data:`MIN_MARGIN`; ``positions`` (C, K, n_t, n_u, 3) the texel centres
    (``hairlut.synth.PreparedCluster.position``).  The trim then cuts nothing finer than the texture resolves."""
    x, y, _ = cam.project(np.asarray(positions, np.float64))
    out = np.full(x.shape[0], MIN_MARGIN)
    for c in range(x.shape[0]):
        steps = [np.hypot(np.diff(x[c], axis=a), np.diff(y[c], axis=a)) for a in (1, 2)]
        med = [float(np.median(s)) for s in steps if s.size]
        out[c] = max(MIN_MARGIN, MARGIN_TEXELS * max(med)) if med else MIN_MARGIN
    return out


def strand_footprints(cam, strands, tile, origins, margin) -> np.ndarray:
    """(C, th, tw) bool: per cluster, the pixels of its tile (``_layered.layout``'s ``tile`` (th, tw) and
    ``origins`` (C, 2) (x, y)) whose centre lies within a strand's projected radius plus ``margin`` pixels (a number,
    or (C,) per cluster: :func:`texel_margins`) of one of its strands' centre lines (``strands``: one
    :class:`~hairlut.geometry.Strands` per cluster).

    The centre lines are sampled every 1 / :data:`SAMPLES_PER_PIXEL` pixel; each sample marks its pixel with its
    reach (radius + margin), and a pixel is kept when the nearest marked pixel (a Euclidean distance transform
    between pixel centres) is within that reach plus :func:`slack`: so every pixel whose centre lies within its reach
    of a centre line is kept, and none beyond reach + :func:`slack` + half a pixel's diagonal."""
    from scipy.ndimage import distance_transform_edt

    th, tw = (int(t) for t in tile)
    origins = np.asarray(origins, np.int64)
    if len(strands) != len(origins):
        raise errors.ValidationError("strands", len(strands), f"need one Strands per cluster ({len(origins)})")
    margins = np.broadcast_to(np.asarray(margin, np.float64), (len(origins),))
    if not (np.isfinite(margins).all() and (margins >= 0).all()):
        raise errors.ValidationError("margin", np.asarray(margin).tolist(), "pixels ≥ 0, one number or one per cluster")
    keep = np.zeros((len(origins), th, tw), bool)
    for c, s in enumerate(strands):
        seg = _segments(cam, s)
        if not seg[0].size:
            continue
        reach_max = float(np.nanmax(np.maximum(seg[2], seg[5]))) + margins[c]
        pad = int(math.ceil(min(reach_max, th + tw) + 1))  # a sample further out reaches no pixel of the tile
        h, w = th + 2 * pad, tw + 2 * pad
        most = np.full(h * w, -1.0)  # the largest reach of a sample in each pixel; −1: none
        ends = np.cumsum(_counts(seg[0], seg[1], seg[3], seg[4]))
        lo = 0
        while lo < len(ends):  # segments in chunks of about CHUNK samples
            hi = max(int(np.searchsorted(ends, (ends[lo - 1] if lo else 0) + CHUNK, side="right")), lo + 1)
            x, y, rpx = _samples(seg, lo, hi)
            ix = np.floor(np.clip(x, -1e9, 1e9)).astype(np.int64) - origins[c, 0] + pad
            iy = np.floor(np.clip(y, -1e9, 1e9)).astype(np.int64) - origins[c, 1] + pad
            ok = np.isfinite(x) & np.isfinite(y) & (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
            np.maximum.at(most, iy[ok] * w + ix[ok], rpx[ok] + margins[c])
            lo = hi
        marked = (most >= 0).reshape(h, w)
        if not marked.any():
            continue
        dist, (ny, nx) = distance_transform_edt(~marked, return_indices=True)
        inside = dist <= most.reshape(h, w)[ny, nx] + slack()
        keep[c] = inside[pad : pad + th, pad : pad + tw]
    return keep
