"""Mip-map chains computed here, not by the driver: every level is the area average, in
linear light, of the level above (sRGB-decoded, averaged, sRGB-encoded with rounding).

``glGenerateMipmap`` is left to each OpenGL implementation (its filter, and whether it
averages sRGB texels in linear light, differ between Mesa and GPU drivers), so the
levels, and with them every minified texture in an image, would depend on the machine.
These levels are the same bytes everywhere.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

__all__ = ["mip_chain", "srgb_decode", "srgb_encode"]

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]


def _decode_table() -> NDArray[np.float64]:
    c = np.arange(256, dtype=np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


_DECODE = _decode_table()
# linear values at which the nearest sRGB code changes: the decoded half-code points
_HALF = (np.arange(255, dtype=np.float64) + 0.5) / 255.0
_THRESH = np.where(_HALF <= 0.04045, _HALF / 12.92, ((_HALF + 0.055) / 1.055) ** 2.4)


def srgb_decode(codes: U8) -> NDArray[np.float64]:
    """Linear values in [0, 1] of sRGB 8-bit codes (IEC 61966-2-1 transfer function)."""
    out: NDArray[np.float64] = _DECODE[codes]
    return out


def srgb_encode(linear: NDArray[np.floating]) -> U8:
    """The nearest sRGB 8-bit code (in code space) of linear values in [0, 1]."""
    return np.searchsorted(_THRESH, linear, side="right").astype(np.uint8)


def _area_matrix(n: int, m: int) -> sparse.csr_matrix:
    """(m, n) weights of an area-average resampling of ``n`` texels to ``m``: output
    ``i`` covers ``[i n/m, (i+1) n/m)`` of the input; each row sums to 1."""
    r = n / m
    rows, cols, vals = [], [], []
    lo = np.arange(m) * r
    hi = lo + r
    first = np.floor(lo).astype(np.int64)
    for k in range(int(np.ceil(r)) + 1):  # each output meets at most ceil(r) + 1 inputs
        j = first + k
        ok = j < n
        w = np.minimum(hi, j + 1.0) - np.maximum(lo, j)
        ok &= w > 0
        rows.append(np.flatnonzero(ok))
        cols.append(j[ok])
        vals.append(w[ok] / r)
    return sparse.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, n)
    )


def _halve(a: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
    """Area-average ``a`` to ``max(1, n // 2)`` along ``axis`` (n = its length there)."""
    n = a.shape[axis]
    m = max(1, n // 2)
    if n == m:
        return a
    b = np.moveaxis(a, axis, 0)
    if n % 2 == 0:
        out = 0.5 * (b[0::2] + b[1::2])
    else:
        flat = b.reshape(n, -1)
        out = np.asarray(_area_matrix(n, m) @ flat).reshape((m, *b.shape[1:]))
    return np.moveaxis(out, 0, axis)


def mip_chain(rgba: U8) -> list[U8]:
    """Every mip level (level 0 first, down to 1x1) of an (H, W, 4) sRGB8+alpha image;
    level ``k`` is ``max(1, W >> k)`` x ``max(1, H >> k)`` as OpenGL sizes them. Colour is
    averaged in linear light, alpha linearly."""
    levels = [np.ascontiguousarray(rgba)]
    lin = np.concatenate(
        [srgb_decode(rgba[..., :3]), rgba[..., 3:].astype(np.float64) / 255.0], axis=-1
    )
    while lin.shape[0] > 1 or lin.shape[1] > 1:
        lin = _halve(_halve(lin, 0), 1)
        lvl = np.empty(lin.shape, dtype=np.uint8)
        lvl[..., :3] = srgb_encode(lin[..., :3])
        lvl[..., 3] = np.rint(np.clip(lin[..., 3], 0.0, 1.0) * 255.0).astype(np.uint8)
        levels.append(lvl)
    return levels
