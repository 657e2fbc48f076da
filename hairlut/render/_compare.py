"""Two frames compared: what the layered model loses against the strands it stands for.

``compare(a, b)`` (b the frame a is measured against, e.g. the strand render) returns, over the whole frame:

- ``rgb_rmse``: RMSE of the premultiplied linear RGB; ``alpha_rmse``: RMSE of α;
- ``alpha_bias``: mean α of a minus mean α of b, and ``alpha_bias_relative`` (over b's mean α; None, with the
  reason in ``alpha_bias_relative_undefined``, when b's α is zero everywhere: there is no coverage to be relative to);
- ``alpha_outside``: the fraction of a's α (summed over the frame) that lies outside b's silhouette, the pixels
  where b's α exceeds :data:`SILHOUETTE_ALPHA`, dilated by a disc of :data:`OUTSIDE_PIXELS` pixels (issue 26's
  "α outside the strands"; None, with the reason in ``alpha_outside_undefined``, when a's α is zero everywhere);
- ``colour_per_alpha``: a's colour per unit α over b's, each the mean luminance (Rec. 709) of its premultiplied RGB
  over its mean α (issue 26: how bright the hair is where it covers, apart from how much it covers; None, with
  the reason in ``colour_per_alpha_undefined``, when either frame has no α or b no light);
- the same RMSEs after 8 × 8 block averaging (``rgb_rmse_8x8``, ``alpha_rmse_8x8``): coverage and tone,
  apart from where single strands fall;
- ``flip_mean`` and the FLIP heat map (LDR-FLIP of NVIDIA's ``flip-evaluator`` package, on the frames
  over black, clipped to [0, 1] and encoded as sRGB).
"""

from __future__ import annotations

import numpy as np

from .. import errors

BLOCK = 8
#: b's silhouette for ``alpha_outside``: the pixels where its α exceeds this ...
SILHOUETTE_ALPHA = 0.01
#: ... dilated by a disc of this radius, pixels.
OUTSIDE_PIXELS = 3


def block_average(x: np.ndarray, block: int = BLOCK) -> np.ndarray:
    """Means over ``block`` × ``block`` tiles of (h, w, …) (ragged edges dropped)."""
    h, w = (x.shape[0] // block) * block, (x.shape[1] // block) * block
    if h == 0 or w == 0:
        raise errors.ValidationError("frame", list(x.shape[:2]), f"smaller than one {block} × {block} block")
    y = x[:h, :w]
    return y.reshape(h // block, block, w // block, block, *x.shape[2:]).mean(axis=(1, 3))


def alpha_outside(a, b, *, pixels: int = OUTSIDE_PIXELS, threshold: float = SILHOUETTE_ALPHA) -> float | None:
    """The fraction of ``a``'s α (frame sum) outside ``b``'s silhouette (α > ``threshold``) dilated by a disc of
    ``pixels``; (h, w, 4) frames or (h, w) α.  None when ``a``'s α is zero everywhere."""
    from scipy.ndimage import binary_dilation

    aa, bb = (np.asarray(getattr(x, "rgba", x), np.float64) for x in (a, b))
    aa, bb = (x[..., 3] if x.ndim == 3 else x for x in (aa, bb))
    r = int(pixels)
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1]
    sil = bb > threshold
    if r > 0:
        sil = binary_dilation(sil, structure=xx * xx + yy * yy <= r * r)
    total = float(aa.sum())
    return float(aa[~sil].sum()) / total if total > 0 else None


def _srgb(rgb: np.ndarray) -> np.ndarray:
    v = np.clip(rgb, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055).astype(np.float32)


def _luminance(rgba: np.ndarray) -> float:
    return float((0.2126 * rgba[..., 0] + 0.7152 * rgba[..., 1] + 0.0722 * rgba[..., 2]).mean())


def colour_per_alpha(a, b) -> float | None:
    """a's mean luminance per unit of mean α over b's (module docstring); None when undefined."""
    ra, rb = (np.asarray(getattr(x, "rgba", x), np.float64) for x in (a, b))
    ma, mb, lb = ra[..., 3].mean(), rb[..., 3].mean(), _luminance(rb)
    if ma <= 0 or mb <= 0 or lb <= 0:
        return None
    return float((_luminance(ra) / ma) / (lb / mb))


def _rmse(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2)))


def compare(a, b, *, flip: bool = True) -> tuple[dict, np.ndarray | None]:
    """Figures (module docstring) of RGBA frames ``a`` against ``b`` ((h, w, 4) arrays or Frames), and the
    FLIP heat map (h, w, 3) in [0, 1] (magma), None without ``flip``.  Every figure of frames in float32 range is a
    finite number (their squares are summed in float64) or None with its reason: strict JSON."""
    ra, rb = (np.asarray(getattr(x, "rgba", x), np.float64) for x in (a, b))
    for name, x in (("a", ra), ("b", rb)):
        if x.ndim != 3 or x.shape[2] != 4:
            raise errors.ValidationError(name, list(x.shape), "need an (h, w, 4) RGBA frame")
        if not np.isfinite(x).all():
            raise errors.ValidationError(name, "non-finite", "frames must be finite")
    if ra.shape != rb.shape:
        raise errors.ValidationError("b", list(rb.shape), f"frames differ in size: a is {list(ra.shape)}")
    ma, mb = float(ra[..., 3].mean()), float(rb[..., 3].mean())
    ba, bb = block_average(ra), block_average(rb)
    out = {
        "rgb_rmse": _rmse(ra[..., :3], rb[..., :3]),
        "alpha_rmse": _rmse(ra[..., 3], rb[..., 3]),
        "alpha_mean_a": ma,
        "alpha_mean_b": mb,
        "alpha_bias": ma - mb,
        "alpha_bias_relative": (ma - mb) / mb if mb > 0 else None,
        "alpha_outside": alpha_outside(ra, rb),
        "colour_per_alpha": colour_per_alpha(ra, rb),
        "rgb_rmse_8x8": _rmse(ba[..., :3], bb[..., :3]),
        "alpha_rmse_8x8": _rmse(ba[..., 3], bb[..., 3]),
    }
    if mb <= 0:
        out["alpha_bias_relative_undefined"] = "b's alpha is zero everywhere"
    if out["colour_per_alpha"] is None:
        out["colour_per_alpha_undefined"] = "a frame has no alpha, or b no light"
    if out["alpha_outside"] is None:
        out["alpha_outside_undefined"] = "a's alpha is zero everywhere"
    heat = None
    if flip:
        import flip_evaluator

        heat, mean, _ = flip_evaluator.evaluate(_srgb(rb[..., :3]), _srgb(ra[..., :3]), "LDR")
        out["flip_mean"] = float(mean)
        heat = np.asarray(heat, np.float32)
    return out, heat


def side_by_side(*images, gap: int = 4) -> np.ndarray:
    """(h, Σw + gaps, 3) of linear RGB images of equal height, for one PNG."""
    h = images[0].shape[0]
    if any(im.shape[0] != h for im in images):
        raise errors.ValidationError("images", [im.shape for im in images], "need equal heights")
    parts = []
    for i, im in enumerate(images):
        if i:
            parts.append(np.zeros((h, gap, 3)))
        parts.append(np.asarray(im, np.float64)[..., :3])
    return np.concatenate(parts, axis=1)
