"""``.npz`` dataset files at a chosen deflate level: NumPy's own layout, read by ``np.load``."""

from __future__ import annotations

import io

import numpy as np

from roslan.io.files import NPZ_DEFLATE_LEVEL, save_npz


def test_save_npz_is_numpys_layout_at_any_level() -> None:
    rng = np.random.default_rng(1)
    arrays = {
        "stamp": np.asarray(123_456_789, np.int64),
        "x": rng.normal(size=5000).astype(np.float32),
        "ring": rng.integers(0, 32, 5000).astype(np.uint16),
    }
    stock = io.BytesIO()
    np.savez_compressed(stock, **arrays)  # type: ignore[arg-type]
    ours = io.BytesIO()
    save_npz(ours, arrays, level=6)  # NumPy's level: byte for byte its file
    assert ours.getvalue() == stock.getvalue()
    fast = io.BytesIO()
    save_npz(fast, arrays)
    assert NPZ_DEFLATE_LEVEL == 1
    assert fast.getvalue() != stock.getvalue()
    with np.load(io.BytesIO(fast.getvalue())) as back:
        assert list(back.keys()) == list(arrays)
        for k, v in arrays.items():
            assert back[k].dtype == v.dtype
            np.testing.assert_array_equal(back[k], v)
