"""One lens remap for every camera kind: a render of the virtual pinhole view
(:class:`~.model.RenderPlan`) into the camera's output pixels.

Every camera renders a pinhole view and, when its lens distorts, remaps it with OpenCV
(``cv2.remap``, ``BORDER_REPLICATE``) through the plan's maps. What differs between the
products of a render (:class:`~roslan.render.RenderResult`) is the interpolation:

* radiance (colour, luminance) and flow: bilinear, on the fixed-point maps
  (``map1``/``map2``, 1/32 px);
* depth and ids: never a blend of two surfaces. ``nearest=True`` reads one render pixel:
  with ``exact=True`` the one nearest the point (the float maps ``mapx``/``mapy``; the
  depth camera's silhouettes), else what ``cv2.INTER_NEAREST`` reads through the
  fixed-point maps: a render pixel within about a pixel of the point (OpenCV rounds the
  1/32 px map, and on 1-2 % of the pixels reads one pixel past the point's four taps;
  the event camera's depth, as it has always been read: its bytes stay those of earlier
  versions).

:func:`remap_view` is the one call site of ``cv2.remap`` for camera images;
:func:`remap_result` applies it to a whole render product. The frame camera's rows
(:mod:`.row_exposure`) read the virtual view through the same maps' float coordinates
(:func:`~.row_exposure.output_rays`), pixel by pixel along each row's motion.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.render import RenderResult
from roslan.sensors.cameras.model import RenderPlan

__all__ = ["remap_result", "remap_view"]


def remap_view(
    plan: RenderPlan,
    img: NDArray[Any],
    *,
    nearest: bool = False,
    exact: bool = False,
    rows: tuple[int, int] | None = None,
    first_row: int = 0,
    dst: NDArray[Any] | None = None,
) -> NDArray[Any]:
    """``img`` (the virtual view, or its rows from ``first_row`` on) at the output pixels
    (of output rows ``[r0, r1)`` = ``rows``, default all): bilinear, or the render pixel
    of ``nearest`` (see the module docstring; ``exact``: the nearest one). ``dst``: an
    array of the output's shape to write into. A pinhole plan returns ``img`` itself
    (its rows ``rows``)."""
    if plan.identity:
        if rows is None:
            return img
        return img[rows[0] - first_row : rows[1] - first_row]
    import cv2

    r0, r1 = (0, plan.map1.shape[0]) if rows is None else rows
    if nearest and exact:
        m1, m2 = plan.mapx[r0:r1], plan.mapy[r0:r1]
        if first_row:
            m2 = m2 - np.float32(first_row)
        interp = cv2.INTER_NEAREST
    else:
        m1, m2 = plan.map1[r0:r1], plan.map2[r0:r1]
        if first_row:
            m1 = m1.copy()
            m1[..., 1] -= first_row
        interp = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
    if dst is None:
        out: NDArray[Any] = cv2.remap(img, m1, m2, interp, borderMode=cv2.BORDER_REPLICATE)
        return out
    cv2.remap(img, m1, m2, interp, dst=dst, borderMode=cv2.BORDER_REPLICATE)
    return dst


def remap_result(plan: RenderPlan, res: RenderResult) -> RenderResult:
    """Every product of the render ``res`` at the output pixels: colour, luminance and
    flow bilinear, depth and ids one render pixel each (the fixed-point maps)."""

    def lin(a: NDArray[Any] | None) -> Any:
        return None if a is None else remap_view(plan, a)

    def near(a: NDArray[Any] | None) -> Any:
        return None if a is None else remap_view(plan, a, nearest=True)

    return replace(
        res,
        color=lin(res.color),
        depth=near(res.depth),
        luminance=lin(res.luminance),
        flow=lin(res.flow),
        ids=near(res.ids),
    )
