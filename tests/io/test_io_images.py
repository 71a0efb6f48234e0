"""PNG writing of dataset images: lossless round trip through Pillow, clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from roslan.errors import OutputError
from roslan.io.images import write_png


@pytest.mark.parametrize(
    ("shape", "dtype", "mode"),
    [((48, 64, 3), np.uint8, "RGB"), ((48, 64), np.uint8, "L"), ((48, 64), np.uint16, None)],
)
def test_png_round_trip_is_lossless_and_rgb_ordered(
    tmp_path: Path, shape: tuple[int, ...], dtype: type, mode: str | None
) -> None:
    rng = np.random.default_rng(3)
    img = rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)
    img[:8] = 0  # a flat band too, not only noise
    path = tmp_path / "a.png"
    write_png(path, img)
    with Image.open(path) as im:
        if mode is not None:
            assert im.mode == mode
        back = np.asarray(im)
    # Pillow reads RGB: channel order must be the caller's, not OpenCV's BGR
    np.testing.assert_array_equal(back.astype(dtype), img)


def test_png_rejects_wrong_images_and_unwritable_paths(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match="float32 image"):
        write_png(tmp_path / "f.png", np.zeros((4, 4), np.float32))
    with pytest.raises(OutputError, match=r"shape \(4, 4, 4\)"):
        write_png(tmp_path / "c.png", np.zeros((4, 4, 4), np.uint8))
    with pytest.raises(OutputError, match="cannot write image"):
        write_png(tmp_path / "missing" / "x.png", np.zeros((4, 4), np.uint8))
