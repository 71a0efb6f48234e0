"""Linear radiance -> 8-bit codes: the sRGB / gamma transfer curve and its lookup table."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from roslan.events.jit import kernel

__all__ = ["encode_image", "encode_linear", "srgb_curve", "srgb_lut"]

F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

_LUT_SIZE = 16384  # linear quantization steps of the encoding LUT (< 1 code in the darks)


def srgb_curve(x: NDArray[np.floating]) -> NDArray[np.floating]:
    """The sRGB transfer curve (IEC 61966-2-1) of linear values ``x`` in [0, 1], in the
    dtype of ``x``."""
    out: NDArray[np.floating] = np.where(
        x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055
    )
    return out


def srgb_lut(gamma: str | float) -> U8:
    """(_LUT_SIZE,) uint8 codes of linear values ``i / (_LUT_SIZE - 1)``."""
    x = np.linspace(0.0, 1.0, _LUT_SIZE)
    v = srgb_curve(x) if gamma == "srgb" else np.power(x, 1.0 / float(gamma))
    return np.clip(np.round(v * 255.0), 0, 255).astype(np.uint8)


def encode_linear(img: F32, lut: U8) -> U8:
    """Linear float image (any shape, values clipped to [0, 1]) -> uint8 codes via ``lut``.

    The NumPy reference of :func:`encode_image` (same bytes)."""
    idx = np.clip(img, 0.0, 1.0)
    idx *= _LUT_SIZE - 1
    idx += 0.5
    # uint16 indices (_LUT_SIZE <= 65536) and np.take: 15 % faster than intp fancy indexing
    out: U8 = np.take(lut, idx.astype(np.uint16))
    return out


@kernel
def _encode_kernel(
    src: F32, gain: np.float32, lut: U8, channels: int, reverse: bool, out: U8
) -> None:
    """``out = lut[idx(gain * src)]`` over flat (N * channels,) arrays, channel order
    reversed per pixel if ``reverse``; idx: :func:`encode_linear`'s float32 clip, scale,
    + 0.5 and truncation, operation for operation (NaN -> index 0, like NumPy's cast)."""
    zero = np.float32(0.0)
    one = np.float32(1.0)
    half = np.float32(0.5)
    scale = np.float32(_LUT_SIZE - 1)
    if reverse:
        for i in range(0, src.size, channels):
            for j in range(channels):
                v = src[i + channels - 1 - j] * gain
                v = v if v > zero else zero  # (NaN too)
                v = v if v < one else one
                out[i + j] = lut[np.uint16(v * scale + half)]
    else:
        for i in range(src.size):
            v = src[i] * gain
            v = v if v > zero else zero
            v = v if v < one else one
            out[i] = lut[np.uint16(v * scale + half)]


def encode_image(img: F32, lut: U8, *, gain: float = 1.0, reverse: bool = False) -> U8:
    """Gain, clip to [0, 1] and ``lut`` codes in one pass (numba): (H, W[, C]) float32
    linear -> uint8 of the same shape, channels reversed if ``reverse`` (rgb -> bgr).

    Same bytes as ``encode_linear(img * float32(gain), lut)`` (tested)."""
    src = np.ascontiguousarray(img, dtype=np.float32)
    out = np.empty(src.shape, dtype=np.uint8)
    channels = src.shape[-1] if src.ndim == 3 else 1
    # (x * 1.0f == x exactly: the NumPy path's skipped multiply gives the same bytes)
    _encode_kernel(src.reshape(-1), np.float32(gain), lut, channels, reverse, out.reshape(-1))
    return out
