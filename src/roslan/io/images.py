"""PNG files of the dataset (camera images, APS frames), written fast and checked.

Simulated images carry sensor noise, which deflate's match search barely compresses, so
the encoder settings matter more than usual: the SUB filter with zlib's run-length
strategy at level 1 costs ~0.6x the CPU of OpenCV's default level-1 encoding (adaptive
filters, full match search) for files ~5 % larger (640x480 rgb8 warehouse frames with
noise, benchmarks/bench_camera.py). Lossless either way: the pixels read back equal.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import OutputError

__all__ = ["write_png"]


@functools.cache
def _params() -> list[int]:
    """OpenCV ``imwrite`` parameters (cv2 is imported lazily)."""
    import cv2

    return [
        cv2.IMWRITE_PNG_COMPRESSION,
        1,
        cv2.IMWRITE_PNG_FILTER,
        cv2.IMWRITE_PNG_FILTER_SUB,
        cv2.IMWRITE_PNG_STRATEGY,
        cv2.IMWRITE_PNG_STRATEGY_RLE,
    ]


def write_png(path: Path, image: NDArray[Any]) -> None:
    """Write ``image`` to ``path`` as PNG.

    Args:
        path: destination file (its folder must exist).
        image: (H, W) mono or (H, W, 3) **RGB** image, uint8 or uint16.
    Raises:
        OutputError: the image has another shape or dtype, or the file cannot be written.
    """
    import cv2

    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16) or not (
        img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3)
    ):
        msg = f"{path}: cannot write a {img.dtype} image of shape {img.shape} as PNG"
        raise OutputError(msg)
    if img.ndim == 3:
        img = img[..., ::-1]  # OpenCV writes BGR
    try:
        ok = cv2.imwrite(str(path), img, _params())
    except cv2.error as e:
        msg = f"{path}: cannot write image: {e}"
        raise OutputError(msg) from None
    if not ok:
        msg = f"{path}: cannot write image"
        raise OutputError(msg)
