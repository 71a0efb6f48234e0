"""Procedural, tileable textures made with NumPy (deterministic from a seed).

Every function returns an (N, N, 3) uint8 sRGB image with N a power of two (so the
renderer can mip-map) that tiles seamlessly: noise is shaped in the Fourier domain,
which is periodic by construction. Detail at several scales gives event cameras and
feature trackers something to see at any distance.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "bark",
    "cardboard",
    "checker",
    "concrete",
    "fbm",
    "gravel",
    "hazard",
    "landing_marker",
    "painted_metal",
    "rng_for",
    "wood",
]

U8 = NDArray[np.uint8]
F64 = NDArray[np.float64]


def rng_for(seed: int, name: str) -> np.random.Generator:
    """Independent generator for one named texture/element, from the scene seed."""
    key = [int(b) for b in name.encode("utf-8")]
    return np.random.default_rng(np.random.SeedSequence([int(seed), *key]))


def _check_size(size: int) -> int:
    if size < 4 or size & (size - 1):
        msg = f"texture size {size} must be a power of two >= 4"
        raise ValueError(msg)
    return size


def fbm(rng: np.random.Generator, size: int, beta: float = 2.0, lowcut: float = 1.0) -> F64:
    """Tileable fractal noise (power spectrum ~ 1/f**beta), normalised to zero mean, unit std.

    Returns:
        (size, size) float64.
    """
    _check_size(size)
    white = rng.standard_normal((size, size))
    f = np.fft.fftfreq(size) * size
    fr = np.hypot(f[:, None], f[None, :])
    amp = np.where(fr >= lowcut, np.maximum(fr, 1.0) ** (-beta / 2.0), 0.0)
    out: F64 = np.fft.ifft2(np.fft.fft2(white) * amp).real
    sd = float(out.std())
    res: F64 = (out - out.mean()) / (sd if sd > 0 else 1.0)
    return res


def _to_u8(rgb: F64) -> U8:
    return np.ascontiguousarray(np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8))


def _tint(gray: F64, color: Sequence[float]) -> F64:
    return gray[..., None] * np.asarray(color, dtype=np.float64)[None, None, :]


def _lines(
    img: F64, rng: np.random.Generator, count: int, length: float, value: float, width: int = 1
) -> None:
    """Draw ``count`` random short straight strokes (wrapping) into a gray image, vectorised."""
    n = img.shape[0]
    x0 = rng.uniform(0, n, count)
    y0 = rng.uniform(0, n, count)
    ang = rng.uniform(0, math.pi, count)
    ln = rng.uniform(0.3, 1.0, count) * length
    t = np.linspace(0.0, 1.0, max(int(length * 2), 2))
    xs = (x0[:, None] + np.cos(ang)[:, None] * ln[:, None] * t[None, :]).astype(np.int64)
    ys = (y0[:, None] + np.sin(ang)[:, None] * ln[:, None] * t[None, :]).astype(np.int64)
    for w in range(width):
        img[(ys + w) % n, xs % n] = value


def concrete(seed: int, size: int = 512, tone: float = 0.55) -> U8:
    """Concrete floor/wall: blotchy low-frequency shading, fine grain, pores and hairline cracks."""
    rng = rng_for(seed, f"concrete{size}{tone}")
    g = tone + 0.06 * fbm(rng, size, 2.4) + 0.035 * fbm(rng, size, 0.6, lowcut=size / 8)
    pores = rng.random((size, size)) < 0.004
    g[pores] -= 0.18
    _lines(g, rng, 6, size / 3, tone - 0.12)
    return _to_u8(_tint(g, (1.0, 0.98, 0.94)))


def gravel(seed: int, size: int = 512) -> U8:
    """Outdoor ground (asphalt/gravel): dark, strongly speckled, with faint oil stains."""
    rng = rng_for(seed, f"gravel{size}")
    g = 0.36 + 0.05 * fbm(rng, size, 2.2) + 0.08 * fbm(rng, size, 0.2, lowcut=size / 6)
    stones = rng.random((size, size)) < 0.02
    g[stones] += rng.uniform(0.1, 0.3, int(stones.sum()))
    return _to_u8(_tint(g, (1.0, 0.97, 0.92)))


def painted_metal(seed: int, color: Sequence[float], size: int = 256, ribs: int = 0) -> U8:
    """Painted steel: base colour with roller noise, scratches (bright) and grime (dark);
    ``ribs`` > 0 adds that many corrugation ribs across the tile (cladding)."""
    rng = rng_for(seed, f"metal{size}{tuple(color)}{ribs}")
    g = 1.0 + 0.05 * fbm(rng, size, 2.0) + 0.03 * fbm(rng, size, 0.5, lowcut=size / 8)
    if ribs:
        xx = np.arange(size)[None, :]
        g = g + 0.12 * np.sin(2 * math.pi * ribs * xx / size)
    grime = np.clip(fbm(rng, size, 3.0), 0.0, None)
    g -= 0.12 * grime
    _lines(g, rng, 40, size / 5, 1.35)
    rgb = _tint(g, color)
    return _to_u8(rgb)


def cardboard(seed: int, size: int = 256) -> U8:
    """Cardboard box side: corrugation stripes, a tape band and dark printed marks."""
    rng = rng_for(seed, f"cardboard{size}")
    yy, xx = np.mgrid[0:size, 0:size]
    g = 1.0 + 0.04 * fbm(rng, size, 2.0) + 0.02 * np.sin(2 * math.pi * xx / 8.0)
    rgb = _tint(g, (0.62, 0.45, 0.28))
    band = np.abs(yy - size // 2) < size // 14
    rgb[band] = rgb[band] * 0.8 + np.array([0.75, 0.66, 0.45]) * 0.2
    # printed marks: a few dark rectangles and an arrow-like bar
    for _ in range(int(rng.integers(2, 5))):
        x0, y0 = rng.integers(0, size - size // 4, 2)
        w, h = rng.integers(size // 16, size // 4, 2)
        rgb[y0 : y0 + h // 3, x0 : x0 + w] = (0.12, 0.1, 0.08)
    return _to_u8(rgb)


def wood(seed: int, size: int = 256) -> U8:
    """Pallet wood: warped grain lines along x."""
    rng = rng_for(seed, f"wood{size}")
    yy, _ = np.mgrid[0:size, 0:size]
    warp = 6.0 * fbm(rng, size, 3.0)
    grain = 0.5 + 0.5 * np.sin(2 * math.pi * (yy + warp) / 11.0)
    g = 0.85 + 0.12 * grain + 0.05 * fbm(rng, size, 1.0)
    return _to_u8(_tint(g, (0.72, 0.56, 0.38)))


def bark(seed: int, size: int = 256) -> U8:
    """Tree bark for branch perches: vertical ridges and dark furrows."""
    rng = rng_for(seed, f"bark{size}")
    _, xx = np.mgrid[0:size, 0:size]
    warp = 8.0 * fbm(rng, size, 2.5)
    ridges = np.abs(np.sin(2 * math.pi * (xx + warp) / 24.0))
    g = 0.55 + 0.35 * ridges + 0.08 * fbm(rng, size, 0.8)
    return _to_u8(_tint(g, (0.42, 0.32, 0.22)))


def hazard(
    size: int = 256, colors: Sequence[Sequence[float]] = ((0.95, 0.75, 0.05), (0.08, 0.08, 0.08))
) -> U8:
    """Diagonal hazard stripes (two stripe pairs per tile, so it tiles)."""
    _check_size(size)
    yy, xx = np.mgrid[0:size, 0:size]
    stripe = ((xx + yy) // (size // 4)) % 2
    c = np.asarray(colors, dtype=np.float64)
    return _to_u8(c[stripe])


def checker(seed: int, size: int = 512, squares: int = 8) -> U8:
    """Calibration ground: a checkerboard with mild grain (features at every scale)."""
    rng = rng_for(seed, f"checker{size}{squares}")
    yy, xx = np.mgrid[0:size, 0:size]
    sq = size // squares
    board = ((xx // sq + yy // sq) % 2).astype(np.float64)
    g = 0.3 + 0.45 * board + 0.04 * fbm(rng, size, 1.5)
    return _to_u8(_tint(g, (1.0, 1.0, 1.0)))


def landing_marker(size: int = 512) -> U8:
    """Helipad-style marker: white 'H' in a white circle on dark grey, with a checker ring
    of 16 sectors (corners for feature trackers). Covers the whole UV square [0, 1]."""
    _check_size(size)
    c = (size - 1) / 2.0
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    x = (xx - c) / (size / 2.0)
    y = (c - yy) / (size / 2.0)
    r = np.hypot(x, y)
    a = np.arctan2(y, x)
    g = np.full((size, size), 0.18)
    sectors = (np.floor(a / (2 * math.pi / 16)) % 2).astype(bool)
    ring = (r > 0.82) & (r < 0.97)
    g[ring & sectors] = 0.92
    g[(r > 0.66) & (r < 0.74)] = 0.92
    h = ((np.abs(x + 0.25) < 0.07) | (np.abs(x - 0.25) < 0.07)) & (np.abs(y) < 0.4)
    h |= (np.abs(x) < 0.25) & (np.abs(y) < 0.06)
    g[h] = 0.95
    rgb = _tint(g, (1.0, 1.0, 1.0))
    rgb[h] = (0.95, 0.85, 0.1)
    return _to_u8(rgb)
