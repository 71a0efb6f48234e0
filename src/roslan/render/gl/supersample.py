"""The arithmetic of the supersampled reference (:meth:`Renderer.render
<roslan.render.gl.Renderer.render>` with ``supersampling = N``): the intrinsics of the
N-times larger render whose pixels sit on a regular N x N grid inside each output pixel,
and the box filter back to the output size."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError
from roslan.render.base import RenderResult
from roslan.render.color import REC709_LUMA
from roslan.render.gl.settings import MAX_SUPERSAMPLING

__all__ = [
    "DEPTH_SPREAD",
    "Passes",
    "box_down",
    "combine_depth",
    "render_supersampled",
    "supersampled_K",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]


class Passes(Protocol):
    """What the supersampled reference needs of the renderer
    (:class:`~roslan.render.gl.renderer.Renderer`, which imports this module): its size
    limit and GL context, its views and its depth and colour passes (``view``: the
    renderer's own view record)."""

    @property
    def max_size(self) -> int: ...

    @property
    def ctx(self) -> Any: ...

    def _view(
        self, T_world_cam: F64, K: F64, width: int, height: int, near: float | None
    ) -> Any: ...

    def _render_depth(self, width: int, height: int, view: Any) -> F32: ...

    def _render_color(
        self,
        view: Any,
        width: int,
        height: int,
        color: bool,
        depth: bool,
        luminance: bool,
        ns: int,
        reference: bool,
        out: F32 | None,
    ) -> RenderResult: ...


DEPTH_SPREAD = 0.05
"""A pixel's N x N inverse depths that spread by more than this fraction of the largest
do not lie on one surface (:func:`combine_depth`)."""


def supersampled_K(K: F64, n: int) -> F64:
    """Intrinsics of the ``n``-times larger render (OpenCV convention, pixel centres at
    integers): its pixel ``(n u + i, n v + j)`` looks through the point
    ``(u + (i + 0.5) / n - 0.5, v + (j + 0.5) / n - 0.5)`` of the output pixel ``(u, v)``."""
    Kn = np.array(K, dtype=np.float64, copy=True)
    Kn[:2, :] *= n
    Kn[:2, 2] = n * np.asarray(K, dtype=np.float64)[:2, 2] + 0.5 * (n - 1)
    Kn[2] = (0.0, 0.0, 1.0)
    return Kn


def box_down(img: F32, n: int, out: F32 | None = None) -> F32:
    """Mean of each ``n`` x ``n`` block of an (nH, nW[, C]) image: (H, W[, C]) float32,
    into ``out`` if given (C-contiguous, checked by the caller)."""
    H, W = img.shape[0] // n, img.shape[1] // n
    blocks = img.reshape(H, n, W, n, *img.shape[2:])
    acc = blocks.sum(axis=(1, 3), dtype=np.float64)
    res = out if out is not None else np.empty((H, W, *img.shape[2:]), dtype=np.float32)
    np.multiply(acc, 1.0 / (n * n), out=res, casting="same_kind")
    return res


def combine_depth(z: F32, n: int) -> F32:
    """One z-depth per output pixel from its ``n`` x ``n`` samples (inf: nothing hit):
    where every sample hits and their inverse depths lie within :data:`DEPTH_SPREAD`
    (one surface), the inverse of their mean (exact on a plane, whose 1/z is affine in
    the image); elsewhere (silhouettes, sky) the nearest sample, as the MSAA resolve
    does."""
    with np.errstate(divide="ignore"):
        inv = np.reciprocal(z.astype(np.float64))  # inf -> 0
    H, W = z.shape[0] // n, z.shape[1] // n
    b = inv.reshape(H, n, W, n)
    lo = b.min(axis=(1, 3))
    hi = b.max(axis=(1, 3))
    one = (lo > 0.0) & (hi - lo <= DEPTH_SPREAD * hi)
    pick = np.where(one, b.mean(axis=(1, 3)), hi)
    with np.errstate(divide="ignore"):
        out: F32 = np.reciprocal(pick).astype(np.float32)
    return out


def render_supersampled(
    r: Passes,
    T_world_cam: F64,
    K: F64,
    width: int,
    height: int,
    n: int,
    outputs: tuple[bool, bool, bool],
    out: F32 | None,
    near: float | None,
) -> RenderResult:
    """:meth:`Renderer.render` of ``r`` with ``supersampling = n``; ``outputs`` is
    ``(color, depth, luminance)``."""
    color, depth, luminance = outputs
    if not 1 <= n <= MAX_SUPERSAMPLING:
        msg = f"supersampling = {n}: must be an integer in [1, {MAX_SUPERSAMPLING}]"
        raise RenderError(msg)
    W, H = n * width, n * height
    if max(W, H) > r.max_size:
        msg = (
            f"supersampling = {n} of a {width}x{height} image needs a {W}x{H} render: "
            f"more than this OpenGL renderer ({r.ctx.info['GL_RENDERER']}) supports "
            f"({r.max_size}); use a smaller supersampling"
        )
        raise RenderError(msg)
    view = r._view(T_world_cam, supersampled_K(K, n), W, H, near)
    if not (color or luminance):
        return RenderResult(None, combine_depth(r._render_depth(W, H, view), n))
    big = r._render_color(view, W, H, color, depth, luminance, 1, True, None)
    col = None if big.color is None else box_down(big.color, n, None if luminance else out)
    lum = None
    if luminance:
        if col is not None:
            lum = col @ np.asarray(REC709_LUMA, dtype=np.float32)
        else:
            assert big.luminance is not None
            lum = box_down(big.luminance, n, out)
    dep = None if big.depth is None else combine_depth(big.depth, n)
    return RenderResult(col, dep, lum)
