"""Image formation against the supersampled reference (issue 28): the reference's
geometry and box filter, the mip-maps roslan computes, and the default event camera and
frames of a window of the default landing against ``supersampling: 4``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import roslan.render.gl as gl
from roslan.cli.simulate import load_config
from roslan.errors import ConfigError, RenderError
from roslan.events.model import EventGenerator
from roslan.events.sampling import camera_twist
from roslan.render.gl.mipmaps import mip_chain, srgb_decode, srgb_encode
from roslan.render.gl.supersample import box_down, combine_depth, supersampled_K
from roslan.scene import load_scene
from roslan.sensors.cameras import EventCameraConfig
from roslan.sensors.cameras.encoding import srgb_curve
from roslan.trajectory.spline import make_trajectory

# ------------------------------------------------------------------ reference arithmetic


def test_supersampled_K_puts_samples_on_the_pixel_grid() -> None:
    """Sample (i, j) of pixel (u, v) sees the point (u + (i + 0.5)/n - 0.5, ...) of the
    original image: project the same 3-D points with both intrinsics."""
    K = np.array([[300.0, 1.5, 160.2], [0.0, 310.0, 118.9], [0.0, 0.0, 1.0]])
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(-1, 1, (50, 2)), rng.uniform(1, 5, 50)])
    for n in (2, 3, 4):
        p = (K @ X.T).T
        u = p[:, :2] / p[:, 2:]
        q = (supersampled_K(K, n) @ X.T).T
        U = q[:, :2] / q[:, 2:]
        # U = n u' + i with u' = u - (i + 0.5)/n + 0.5  <=>  U = n u + (n - 1) / 2
        np.testing.assert_allclose(U, n * u + (n - 1) / 2, atol=1e-9)


def test_box_down_and_depth_combination() -> None:
    rng = np.random.default_rng(2)
    img = rng.random((12, 18, 3)).astype(np.float32)
    out = box_down(img, 3)
    ref = np.array(
        [
            [img[3 * r : 3 * r + 3, 3 * c : 3 * c + 3].mean(axis=(0, 1)) for c in range(6)]
            for r in range(4)
        ]
    )
    np.testing.assert_allclose(out, ref, rtol=1e-6)
    # a plane's 1/z is affine: the mean inverse depth is the centre's; a silhouette
    # (or nothing hit) takes the nearest sample
    v, u = np.mgrid[0:4, 0:4].astype(np.float64)
    inv = 0.5 + 0.001 * u + 0.002 * v
    z = (1.0 / inv).astype(np.float32)
    z[0, 0] = 0.25  # an object in front of one sample of pixel (0, 0)
    z[3, 3] = np.inf  # sky in one sample of pixel (1, 1)
    d = combine_depth(z, 2)
    assert d[0, 0] == pytest.approx(0.25)
    assert d[1, 1] == pytest.approx(z[2:4, 2:4][np.isfinite(z[2:4, 2:4])].min())
    exp = 1.0 / (0.5 + 0.001 * 2.5 + 0.002 * 0.5)  # centre of pixel (0, 1)
    assert d[0, 1] == pytest.approx(exp, rel=1e-6)
    assert np.isinf(combine_depth(np.full((4, 4), np.inf, np.float32), 2)).all()


def test_mip_chain_is_the_linear_light_area_average() -> None:
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (8, 12, 4), dtype=np.uint8)
    levels = mip_chain(img)
    assert [lv.shape[:2] for lv in levels] == [(8, 12), (4, 6), (2, 3), (1, 1)]
    # level 1 from the sRGB formula, computed independently
    c = img[..., :3].astype(np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    avg = lin.reshape(4, 2, 6, 2, 3).mean(axis=(1, 3))
    enc = np.where(avg <= 0.0031308, 12.92 * avg, 1.055 * avg ** (1 / 2.4) - 0.055)
    assert np.abs(levels[1][..., :3].astype(int) - np.rint(enc * 255)).max() <= 0
    # odd sizes: GL's floor sizes, each texel the area average (here 3 -> 1: the mean)
    odd = mip_chain(np.full((3, 5, 4), 200, dtype=np.uint8))
    assert [lv.shape[:2] for lv in odd] == [(3, 5), (1, 2), (1, 1)]
    assert all((lv == 200).all() for lv in odd)
    col = np.zeros((1, 3, 4), dtype=np.uint8)
    col[0, :, :3] = [[0, 0, 0], [255, 255, 255], [255, 255, 255]]
    assert mip_chain(col)[1][0, 0, 0] == srgb_encode(np.array([2 / 3]))[0]
    codes = np.arange(256, dtype=np.uint8)
    assert np.array_equal(srgb_encode(srgb_decode(codes)), codes)


def test_supersampling_errors() -> None:
    r = gl.get_renderer(load_scene("empty"))
    K = np.array([[50.0, 0, 31.5], [0, 50.0, 23.5], [0, 0, 1]])
    with pytest.raises(RenderError, match=r"supersampling = 9: must be an integer in \[1, 8\]"):
        r.render(np.eye(4), K, 64, 48, supersampling=9)
    big = r.max_size // 2 + 1
    with pytest.raises(RenderError, match=f"supersampling = 2 of a {big}x8 image needs"):
        r.render(np.eye(4), K, big, 8, supersampling=2)


@pytest.mark.parametrize("value", [0, 9, 2.5])
def test_supersampling_config_errors(tmp_path: Path, value: object) -> None:
    """A bad value names the file, the key and the value."""
    cfg = tmp_path / "job.yaml"
    cfg.write_text(
        "scene: empty\nsensors:\n  - {type: camera, name: cam, rate: 10.0, "
        f"topic: /cam, supersampling: {value}}}\n"
    )
    with pytest.raises(ConfigError, match=rf"job.yaml.*supersampling.*{value}") as err:
        load_config(cfg)
    assert "Traceback" not in str(err.value)


# --------------------------------------------------- the default landing vs the reference

WINDOW = (0.05, 0.20)  # s: fast and far from the ground, where the GL implementations differed
RATE = 200.0  # Hz, the default job's render cap


def _event_config(**over: Any) -> EventCameraConfig:
    """The default job's event camera (DAVIS346) with the clean pixel."""
    cfg, _ = load_config(None)
    dvs = next(s for s in cfg.sensors if s.type == "event_camera")
    data = dvs.model_dump(mode="json", exclude_unset=True)
    data.update({"preset": "clean", **over})
    return EventCameraConfig.model_validate(data)


@pytest.fixture(scope="module")
def landing() -> dict[str, Any]:
    """The default landing's warehouse, trajectory and its clean event camera."""
    cfg, _ = load_config(None)
    return {
        "renderer": gl.get_renderer(load_scene(cfg.scene, seed=cfg.seed)),
        "trajectory": make_trajectory(cfg.trajectory),
        "camera": _event_config(),
        "frame_camera": next(s for s in cfg.sensors if s.type == "camera"),
    }


def _events(landing: dict[str, Any], n: int) -> tuple[int, np.ndarray]:
    """Events of the window and the APS frame (sRGB8) at its middle, supersampling ``n``."""
    ec: EventCameraConfig = landing["camera"]
    model = ec.camera_model()
    r: gl.Renderer = landing["renderer"]
    gen = EventGenerator(model.width, model.height, ec.model_params(), np.random.default_rng(0))
    total = 0
    mid = None
    times = np.arange(int(WINDOW[0] * 1e9), int(WINDOW[1] * 1e9) + 1, int(1e9 / RATE))
    for k, t in enumerate(times.tolist()):
        T, _, _ = camera_twist(landing["trajectory"], t, ec.T_base_optical())
        res = r.render(
            T, model.K, model.width, model.height, color=False, depth=False, luminance=True,
            supersampling=n,
        )  # fmt: skip
        assert res.luminance is not None
        total += gen.update(res.luminance, t).size
        if k == len(times) // 2:
            mid = np.rint(srgb_curve(np.clip(res.luminance, 0, 1)) * 255).astype(np.uint8)
    assert mid is not None
    return total, mid


def test_default_event_camera_matches_the_reference(landing: dict[str, Any]) -> None:
    """Clean pixel, the default job's DAVIS346, 150 ms of the fast, far part of the
    default landing (flapping included): the default image formation's event count within
    3 % of the 4 x 4 supersampled reference's (issue 28's limit per 250 ms window; measured
    -2.66 %; the image formation before the texture-space 2 x 2 taps: -7.6 %, llvmpipe's
    before issue 28: about -20 %), and the APS frame at the window's middle within 1.6 DN
    on average (measured 1.51, before 1.80)."""
    ref, ref_aps = _events(landing, 4)
    got, aps = _events(landing, 1)
    assert ref > 20_000  # textures and edges in view
    assert abs(got - ref) / ref < 0.03, (got, ref)
    diff = np.abs(aps.astype(int) - ref_aps.astype(int))
    assert diff.mean() <= 1.6, diff.mean()


def test_camera_frame_matches_the_reference(landing: dict[str, Any]) -> None:
    """The default job's frame camera (640x480, its focal length, without the lens
    distortion) 2 s into the landing: mono8 frame within 1 DN on average of the
    reference's (issue 28's limit; measured 0.98 DN, 1.28 before the texture-space 2 x 2
    taps)."""
    cam = landing["frame_camera"]
    r: gl.Renderer = landing["renderer"]
    f = cam.camera_model().fx
    K = np.array([[f, 0, 319.5], [0, f, 239.5], [0, 0, 1]])
    T, _, _ = camera_twist(landing["trajectory"], int(2.0e9), cam.T_base_optical())
    imgs = []
    for n in (1, 4):
        lum = r.render(T, K, 640, 480, color=False, depth=False, luminance=True, supersampling=n)
        assert lum.luminance is not None
        imgs.append(np.rint(srgb_curve(np.clip(lum.luminance, 0, 1)) * 255).astype(int))
    diff = np.abs(imgs[0] - imgs[1])
    assert imgs[1].std() > 10  # a structured view, not a blank wall
    assert diff.mean() <= 1.0, diff.mean()
