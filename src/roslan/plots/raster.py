"""NumPy/OpenCV rasters shared by the preview video and the overview figure.

Everything here is vectorized over pixels and points (no Python loop per event or
point) and returns (H, W, 3) uint8 RGB images.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from roslan.plots.style import EVENT_NEG_RGB, EVENT_POS_RGB, colormap_lut

__all__ = [
    "BACKGROUND_RGB",
    "bev_image",
    "event_frame",
    "fit_into",
    "label",
    "placeholder",
]

U8 = NDArray[np.uint8]
BACKGROUND_RGB = (18, 20, 26)


def event_frame(
    x: NDArray[np.int64],
    y: NDArray[np.int64],
    p: NDArray[np.int8],
    width: int,
    height: int,
    background: U8 | None = None,
) -> U8:
    """Events of one time window drawn over a (dimmed) grayscale image.

    Args:
        x, y: (M,) pixel coordinates (column, row; row 0 at the top).
        p: (M,) polarity, +1 ON / -1 OFF.
        width, height: sensor resolution, px.
        background: (H, W, 3) uint8 frame (resized if its size differs) or None for white.
    Returns:
        (height, width, 3) uint8 RGB: pixels whose net polarity is positive blue,
        negative red, the rest the background.
    """
    if background is None:
        img = np.full((height, width, 3), 255, np.uint8)
    else:
        bg = fit_exact(background, width, height)
        gray = bg.mean(axis=2, dtype=np.float32)
        # brighten and flatten the frame so coloured events stand out on it
        img = np.repeat((110.0 + 0.55 * gray).astype(np.uint8)[:, :, None], 3, axis=2)
    ok = (x >= 0) & (x < width) & (y >= 0) & (y < height)
    if np.any(ok):
        flat = y[ok] * width + x[ok]
        net = np.bincount(flat, weights=p[ok].astype(np.float64), minlength=width * height)
        net = net.reshape(height, width)
        img[net > 0] = EVENT_POS_RGB
        img[net < 0] = EVENT_NEG_RGB
    return img


def fit_exact(img: U8, width: int, height: int) -> U8:
    """``img`` resized to exactly (height, width) (area filter when shrinking)."""
    import cv2

    if img.shape[0] == height and img.shape[1] == width:
        return img
    shrink = img.shape[1] > width
    interp = cv2.INTER_AREA if shrink else cv2.INTER_NEAREST
    return np.asarray(cv2.resize(img, (width, height), interpolation=interp), dtype=np.uint8)


def fit_into(img: U8, width: int, height: int, fill: tuple[int, int, int] = BACKGROUND_RGB) -> U8:
    """``img`` scaled to fit (height, width) keeping its aspect ratio, letterboxed."""
    h, w = img.shape[:2]
    scale = min(width / w, height / h)
    nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
    out = np.empty((height, width, 3), np.uint8)
    out[:] = fill
    y0, x0 = (height - nh) // 2, (width - nw) // 2
    out[y0 : y0 + nh, x0 : x0 + nw] = fit_exact(img, nw, nh)
    return out


def label(img: U8, text: str, org: tuple[int, int] = (6, 6), scale: float = 0.45) -> U8:
    """Write ``text`` (ASCII) at ``org`` (top-left, px) on a dark box, in place."""
    import cv2

    font = cv2.FONT_HERSHEY_SIMPLEX
    (tw, th), base = cv2.getTextSize(text, font, scale, 1)
    x, y = org
    x1, y1 = min(x + tw + 8, img.shape[1]), min(y + th + base + 6, img.shape[0])
    img[y:y1, x:x1] = (img[y:y1, x:x1] * 0.35).astype(np.uint8)
    cv2.putText(img, text, (x + 4, y + th + 3), font, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def placeholder(width: int, height: int, text: str) -> U8:
    """A dark panel saying what is missing (e.g. "no camera configured")."""
    import cv2

    img = np.empty((height, width, 3), np.uint8)
    img[:] = BACKGROUND_RGB
    font = cv2.FONT_HERSHEY_SIMPLEX
    scale = 0.5
    (tw, th), _ = cv2.getTextSize(text, font, scale, 1)
    org = (max((width - tw) // 2, 2), (height + th) // 2)
    cv2.putText(img, text, org, font, scale, (170, 170, 170), 1, cv2.LINE_AA)
    return img


def bev_image(
    xyz: NDArray[np.float64],
    values: NDArray[np.float64],
    size: int,
    extent: float,
    *,
    vmin: float | None = None,
    vmax: float | None = None,
    cmap: str = "turbo",
    rings: float | None = 10.0,
) -> U8:
    """Bird's-eye raster of a point cloud seen from above (sensor x up, y left).

    Args:
        xyz: (M, 3) points in the sensor frame, m.
        values: (M,) values mapped to colours (height, ring...).
        size: output side, px.
        extent: half-width of the square shown, m (sensor at the centre).
        vmin, vmax: colour range (default: the values' 2nd-98th percentile).
        rings: spacing of the grey range rings, m (None: no rings).
    Returns:
        (size, size, 3) uint8 RGB.
    """
    import cv2

    img = np.empty((size, size, 3), np.uint8)
    img[:] = BACKGROUND_RGB
    c = (size - 1) / 2.0
    px_per_m = (size / 2.0) / extent
    if rings:
        r = rings
        while r <= extent * 1.42:
            cv2.circle(img, (round(c), round(c)), round(r * px_per_m), (55, 58, 68), 1, cv2.LINE_AA)
            r += rings
    if xyz.shape[0]:
        lo = float(np.percentile(values, 2)) if vmin is None else vmin
        hi = float(np.percentile(values, 98)) if vmax is None else vmax
        if hi <= lo:
            hi = lo + 1.0
        lut = colormap_lut(cmap)
        # skip the darkest quarter of the colormap: points must stand out on the dark ground
        idx = (64 + np.clip((values - lo) / (hi - lo), 0.0, 1.0) * 191.0).astype(np.intp)
        col = np.rint(c - xyz[:, 1] * px_per_m).astype(np.intp)  # y (left) -> image left
        row = np.rint(c - xyz[:, 0] * px_per_m).astype(np.intp)  # x (forward) -> image up
        # draw low values first so the highest value wins each pixel
        order = np.argsort(values, kind="stable")
        col, row, idx = col[order], row[order], idx[order]
        for dr, dc in ((0, 0), (0, 1), (1, 0), (1, 1)):  # 2x2 splat: points stay visible
            r_, c_ = row + dr, col + dc
            ok = (r_ >= 0) & (r_ < size) & (c_ >= 0) & (c_ < size)
            img[r_[ok], c_[ok]] = lut[idx[ok]]
    # the sensor and its forward direction
    cv2.circle(img, (round(c), round(c)), 3, (255, 255, 255), -1, cv2.LINE_AA)
    cv2.arrowedLine(
        img,
        (round(c), round(c)),
        (round(c), round(c - 2.0 * px_per_m)),
        (255, 255, 255),
        1,
        cv2.LINE_AA,
        tipLength=0.3,
    )
    return img
