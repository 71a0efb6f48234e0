"""The row-formation kernels read their renders within the renders' own width.

A lens's virtual view (``CameraModel.render_plan``) is not the output's size: the default
640x480 camera renders a 635-pixel-wide view. The kernels once clamped render coordinates
with the output's width, reading past each render row (and, at the last row, past the
array). Checked against an independent value: a render that is a linear ramp in x, read
bilinearly at a known position, is the ramp there exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from roslan.sensors.cameras import depth_readout, row_exposure

H, W, F, CX, CY = 6, 40, 20.0, 3.0, 2.5  # output rows, columns; the render's f, cx, cy


def _rays(render_width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Output pixel u's ray lands on render column xr(u): the render's full width and 3
    columns past its edge (a pixel whose motion leaves the render reads its last column)."""
    xr = np.linspace(0.0, render_width + 2.0, W)
    rx = np.broadcast_to(((xr - CX) / F).astype(np.float32), (H, W)).copy()
    ry = np.broadcast_to(((np.arange(H) - CY) / F).astype(np.float32)[:, None], (H, W))
    return xr, rx, ry.copy()


def _one_band() -> tuple[np.ndarray, ...]:
    """base, a0, hgt of one band of H rows; the render's Kv."""
    one = np.zeros(1, np.int64)
    return one, one, np.full(1, H, np.int64), np.array([F, 0.0, CX, F, CY])


def _identity_poses(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.repeat(np.eye(3)[None], n, axis=0), np.zeros((n, 3))


@pytest.mark.parametrize("render_width", [27, 53])  # narrower and wider than the output
@pytest.mark.parametrize("jit", [True, False])
def test_row_exposure_reads_within_the_render(render_width: int, jit: bool) -> None:
    H, W, h = 6, 40, 6
    f = 20.0
    # output pixel u's ray lands on render column xr(u): the render's full width and 3
    # columns past its edge (a pixel whose motion leaves the render reads its last column)
    xr = np.linspace(0.0, render_width + 2.0, W)
    cx, cy = 3.0, 2.5
    rx = np.broadcast_to(((xr - cx) / f).astype(np.float32), (H, W)).copy()
    ry = np.broadcast_to(((np.arange(H) - cy) / f).astype(np.float32)[:, None], (H, W)).copy()
    ramp = 0.25 + 0.01 * np.arange(render_width, dtype=np.float32)
    imgs = np.broadcast_to(ramp[None, :, None], (h, render_width, 1)).copy()
    zs = np.full((h, render_width), 2.0, np.float32)  # a fronto-parallel plane
    base, a0, hgt = np.zeros(1, np.int64), np.zeros(1, np.int64), np.full(1, h, np.int64)
    Kv = np.array([f, 0.0, cx, f, cy])
    R, c = _identity_poses(3 * H)
    out = np.zeros((H, W, 1), np.float32)
    fn = row_exposure._integrate if jit else row_exposure._integrate.py_func
    fn(imgs, zs, base, a0, hgt, Kv, rx, ry, R, c, np.zeros(H, np.int64), 0.5, 1, out)
    expected = np.interp(xr, np.arange(render_width), ramp)
    np.testing.assert_allclose(out[..., 0], np.broadcast_to(expected, (H, W)), atol=1e-5)


@pytest.mark.parametrize("render_width", [27, 53])
@pytest.mark.parametrize("jit", [True, False])
def test_depth_rows_read_within_the_render(render_width: int, jit: bool) -> None:
    xr, rx, ry = _rays(render_width)
    # a plane tilted about y: inverse depth affine in the render's column
    inv_ramp = 1.0 / (2.0 + 0.05 * np.arange(render_width, dtype=np.float32))
    inv = np.broadcast_to(inv_ramp[None, :], (H, render_width)).astype(np.float32).copy()
    flag = np.ones_like(inv)  # nearest tap everywhere: the value is a tap's own
    base, a0, hgt, Kv = _one_band()
    R, c = _identity_poses(H)
    out = np.zeros((H, W), np.float32)
    fn = depth_readout._depth_rows if jit else depth_readout._depth_rows.py_func
    fn(inv, flag, base, a0, hgt, Kv, rx, ry, R, c, np.zeros(H, np.int64), 0, out)
    nearest = np.clip(np.floor(xr + 0.5), 0, render_width - 1).astype(int)
    expected = 1.0 / inv_ramp[nearest]
    np.testing.assert_allclose(out, np.broadcast_to(expected, (H, W)), rtol=1e-5)
