"""The one lens remap of every camera kind (:mod:`roslan.sensors.cameras.remap`) against
independent calculations: bilinear radiance reproduces an affine image at each output
pixel's virtual-view point, depth and ids read one render pixel (never a blend), bands of
rows equal the same rows of the whole image, and a pinhole plan passes the render on."""

from __future__ import annotations

import numpy as np
import pytest

from roslan.render import RenderResult
from roslan.sensors.cameras import CameraModel
from roslan.sensors.cameras.remap import remap_result, remap_view

W, H = 80, 60


def _plan(distorted: bool = True):  # type: ignore[no-untyped-def]
    K = np.array([[60.0, 0.0, 39.5], [0.0, 60.0, 29.5], [0.0, 0.0, 1.0]])
    D = np.array([-0.2, 0.05, 0.0, 0.0, 0.0]) if distorted else np.zeros(5)
    model = CameraModel(W, H, K, D, "plumb_bob" if distorted else "none")
    return model.render_plan()


def _ramp(plan, a: float = 0.01, b: float = 0.02) -> np.ndarray:  # type: ignore[no-untyped-def]
    v, u = np.mgrid[0 : plan.height, 0 : plan.width].astype(np.float32)
    return (a * u + b * v + 0.1).astype(np.float32)


def test_bilinear_radiance_is_exact_on_an_affine_image() -> None:
    plan = _plan()
    assert not plan.identity
    img = _ramp(plan)
    out = remap_view(plan, img)
    expected = 0.01 * plan.mapx + 0.02 * plan.mapy + 0.1  # the ramp at each point
    # fixed-point maps: 1/32 px, so within (0.01 + 0.02) / 32 / 2 of the exact value
    np.testing.assert_allclose(out, expected, atol=0.03 / 64 + 1e-6)
    # colour: each channel the same way
    rgb = np.stack([img, 2 * img, 3 * img], axis=-1)
    out3 = remap_view(plan, rgb)
    np.testing.assert_allclose(out3[..., 2], 3 * out, rtol=1e-5)


def test_depth_and_ids_are_never_blended() -> None:
    plan = _plan()
    rng = np.random.default_rng(1)
    depth = rng.choice(np.array([1.0, 5.0, np.inf], np.float32), size=(plan.height, plan.width))
    ids = rng.integers(0, 1000, size=(plan.height, plan.width)).astype(np.int32)
    res = remap_result(plan, RenderResult(None, depth, _ramp(plan), ids=ids))
    assert res.depth is not None
    assert res.ids is not None
    assert res.luminance is not None
    assert set(np.unique(res.depth)) <= {1.0, 5.0, np.inf}  # one surface's depth each
    assert res.ids.dtype == np.int32
    # the fixed-point maps: a render pixel within about a pixel of the point (OpenCV's
    # nearest rounds the 1/32 px maps, sometimes one pixel past a tap)
    v, u = np.mgrid[0 : plan.height, 0 : plan.width].astype(np.float32)
    for coord, point in ((u, plan.mapx), (v, plan.mapy)):
        read = remap_view(plan, coord, nearest=True)
        assert np.all(read == np.round(read))  # a pixel, not a blend
        assert np.abs(read - point).max() < 1.1
    # exact: the nearest render pixel
    near = remap_view(plan, depth, nearest=True, exact=True)
    ru = np.rint(plan.mapx).astype(int).clip(0, plan.width - 1)
    rv = np.rint(plan.mapy).astype(int).clip(0, plan.height - 1)
    assert np.mean(near == depth[rv, ru]) > 0.99
    assert res.flow is None  # absent products stay absent
    assert res.color is None


@pytest.mark.parametrize("exact", [False, True])
def test_a_band_of_rows_equals_those_rows_of_the_whole(exact: bool) -> None:
    plan = _plan()
    img = _ramp(plan) ** 2  # not affine: the taps matter
    whole = remap_view(plan, img, nearest=exact, exact=exact)
    r0, r1 = 20, 41
    a = int(np.floor(plan.mapy[r0:r1].min())) - 2
    b = int(np.ceil(plan.mapy[r0:r1].max())) + 3
    band = remap_view(plan, img[a:b], nearest=exact, exact=exact, rows=(r0, r1), first_row=a)
    np.testing.assert_array_equal(band, whole[r0:r1])


def test_pinhole_plan_passes_the_render_on() -> None:
    plan = _plan(distorted=False)
    assert plan.identity
    img = _ramp(plan)
    assert remap_view(plan, img) is img
    np.testing.assert_array_equal(remap_view(plan, img, rows=(5, 9), first_row=2), img[3:7])
    res = RenderResult(None, img, img)
    assert remap_result(plan, res).luminance is img
