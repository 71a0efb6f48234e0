"""Camera sensors end to end: bags (rosbags), dataset files, calibration files, stereo
disparity, noise determinism and the errors bad input gets."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader

import roslan.render.gl as gl
from camera_helpers import board_scene, detect_corners, look_down
from pipeline_helpers import SHORT_TRAJECTORY
from roslan.config.base import validate_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError, SensorError
from roslan.pipeline import run_simulation
from roslan.sensors.base import sample_times_ns
from roslan.sensors.cameras import (
    T_LINK_OPTICAL,
    Camera,
    CameraConfig,
    CameraModel,
    DepthCamera,
    DepthCameraConfig,
    StereoCamera,
    StereoCameraConfig,
    encode_image,
    encode_linear,
    load_calibration,
    srgb_lut,
)
from roslan.trajectory import TauTrajectory, TrajectoryConfig

CAM = {"rate": 10.0, "resolution": [64, 48], "fx": 40.0, "pose": {"rpy": [0.0, 0.5, 0.0]}}


def _config(sensors: list[dict[str, Any]], seed: int = 1) -> SimConfig:
    return validate_model(
        SimConfig,
        {
            "trajectory": SHORT_TRAJECTORY,
            "scene": "empty",
            "sensors": sensors,
            "seed": seed,
            "output": {"formats": ["ros1", "ros2"]},
        },
        "sim.yaml",
    )


def _read(bag: Path, topic: str) -> list[Any]:
    with AnyReader([bag]) as r:
        conns = [c for c in r.connections if c.topic == topic]
        return [r.deserialize(raw, c.msgtype) for c, _, raw in r.messages(connections=conns)]


def _n_frames(rate: float) -> int:
    traj = TauTrajectory(TrajectoryConfig.model_validate(SHORT_TRAJECTORY))
    return len(sample_times_ns(rate, traj.duration_ns))


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cams") / "out"
    cfg = _config(
        [
            {
                "type": "imu",
                "name": "imu",
                "rate": 100.0,
                "topic": "/imu",
                "pose": {"position": [0.01, 0, 0]},
            },
            {"type": "camera", "name": "c_rgb", "topic": "/c_rgb", "encoding": "rgb8", **CAM},
            {"type": "camera", "name": "c_bgr", "topic": "/c_bgr", "encoding": "bgr8", **CAM},
            {"type": "camera", "name": "c_mono", "topic": "/c_mono", "encoding": "mono8", **CAM},
            {"type": "depth_camera", "name": "d", "topic": "/d", **CAM},
        ]
    )
    run_simulation(cfg, out, quiet=True)
    return out


def test_encodings_round_trip_through_bags(run: Path) -> None:
    for bag in (run / "landing.bag", run / "landing_ros2"):
        rgb = _read(bag, "/c_rgb/image_raw")
        bgr = _read(bag, "/c_bgr/image_raw")
        mono = _read(bag, "/c_mono/image_raw")
        info = _read(bag, "/c_rgb/camera_info")
        n = _n_frames(10.0)
        assert len(rgb) == len(bgr) == len(mono) == len(info) == n
        for a, b, m, i in zip(rgb, bgr, mono, info, strict=True):
            assert (a.encoding, b.encoding, m.encoding) == ("rgb8", "bgr8", "mono8")
            assert a.header.frame_id == "c_rgb_optical"
            assert i.header.frame_id == "c_rgb_optical"
            assert a.step == 64 * 3
            assert m.step == 64
            img = a.data.reshape(48, 64, 3)
            np.testing.assert_array_equal(b.data.reshape(48, 64, 3), img[..., ::-1])
            # mono = sRGB(luma(linear)): compare with the rgb8 image decoded to linear
            lin = np.where(
                img / 255 <= 0.04045, img / 255 / 12.92, ((img / 255 + 0.055) / 1.055) ** 2.4
            )
            y = lin @ [0.2126, 0.7152, 0.0722]
            ys = np.where(y <= 0.0031308, 12.92 * y, 1.055 * y ** (1 / 2.4) - 0.055) * 255
            err = np.abs(m.data.reshape(48, 64) - ys)
            # the edge filter runs on the luminance itself in the mono path and on green in
            # the colour path: at the horizon (ground against the sky) its decisions differ
            assert np.mean(err <= 3.0) >= 0.98
            assert err.max() <= 12.0
        assert rgb[0].data.std() > 1.0  # the ground texture is visible (not at touchdown)
        k = info[0].K if hasattr(info[0], "K") else info[0].k
        np.testing.assert_allclose(k, [40, 0, 31.5, 0, 40, 23.5, 0, 0, 1])


def test_png_files_are_rgb_whatever_the_encoding(tmp_path: Path) -> None:
    # a red floor: an rgb8 and a bgr8 camera at the same pose write the same RGB PNG file
    scene = tmp_path / "red.yaml"
    scene.write_text(
        yaml.safe_dump(
            {
                "name": "red",
                "objects": [
                    {
                        "name": "floor",
                        "primitive": {"type": "box", "size": [60.0, 60.0, 0.1]},
                        "pose": {"position": [0.0, 0.0, -0.05]},
                        "material": {"color": [0.9, 0.1, 0.05]},
                    }
                ],
            }
        )
    )
    cfg = _config(
        [
            {"type": "camera", "name": "a", "topic": "/a", "encoding": "rgb8", **CAM},
            {"type": "camera", "name": "b", "topic": "/b", "encoding": "bgr8", **CAM},
        ]
    ).model_copy(update={"scene": str(scene)})
    run_simulation(cfg, tmp_path / "out", quiet=True, overview=False)
    from PIL import Image

    # Event Camera Dataset layout: the first camera at the root, the other in b/
    with Image.open(tmp_path / "out/images/00000002.png") as im:
        a = np.asarray(im)
    with Image.open(tmp_path / "out/b/images/00000002.png") as im:
        b = np.asarray(im)
    assert a.shape == (48, 64, 3)
    assert a[..., 0].mean() > 3 * a[..., 2].mean() + 20  # red, seen as red
    np.testing.assert_array_equal(b, a)
    msg = _read(tmp_path / "out/landing.bag", "/b/image_raw")[2]
    np.testing.assert_array_equal(msg.data.reshape(48, 64, 3)[..., ::-1], a)


def test_dataset_files_and_pngs(run: Path) -> None:
    # the first camera (c_rgb) at the OUTDIR root, every other one in <name>/
    lines = (run / "images.txt").read_text().splitlines()
    assert len(lines) == _n_frames(10.0)
    assert lines[1] == "0.100000000 images/00000001.png"
    png = cv2.imread(str(run / "images/00000003.png"))[..., ::-1]
    msg = _read(run / "landing.bag", "/c_rgb/image_raw")[3]
    np.testing.assert_array_equal(png, msg.data.reshape(48, 64, 3))
    # a PNG file is RGB whatever the topic's encoding: the bgr8 camera's file is the same
    # picture (both cameras sit at the same pose)
    png_bgr = cv2.imread(str(run / "c_bgr/images/00000003.png"))[..., ::-1]
    assert (run / "c_bgr/images.txt").read_text().splitlines() == lines
    assert (run / "c_bgr/calib.txt").read_text() == (run / "calib.txt").read_text()
    np.testing.assert_array_equal(png_bgr, png)
    cal = load_calibration(run / "calib/c_rgb.yaml")
    np.testing.assert_allclose(cal.K, [[40, 0, 31.5], [0, 40, 23.5], [0, 0, 1]])
    chain = yaml.safe_load((run / "calib/camchain.yaml").read_text())
    assert list(chain) == ["cam0", "cam1", "cam2", "cam3"]
    T_cam_imu = np.array(chain["cam0"]["T_cam_imu"])
    # IMU 1 cm forward of base_link, seen from a camera pitched down 0.5 rad: ahead and up (-y)
    np.testing.assert_allclose(
        T_cam_imu[:3, 3], [0, -0.01 * np.sin(0.5), 0.01 * np.cos(0.5)], atol=1e-12
    )
    assert (run / "calib.txt").read_text().split()[:4] == ["40.0", "40.0", "31.5", "23.5"]
    depth = _read(run / "landing_ros2", "/d/image_raw")
    z = np.frombuffer(depth[0].data.tobytes(), "<f4").reshape(48, 64)
    assert depth[0].encoding == "32FC1"
    assert np.isnan(z).any() or np.isfinite(z).all()
    assert np.nanmin(z) > 0


def test_noise_is_seeded(tmp_path: Path) -> None:
    cam = {
        "type": "camera",
        "name": "c",
        "topic": "/c",
        **CAM,
        "noise_std": 0.02,
        "full_well": 2000.0,
    }
    cam["rate"] = 5.0
    outs = []
    for i, seed in enumerate((4, 4, 5)):
        out = tmp_path / f"o{i}"
        run_simulation(_config([cam], seed=seed), out, quiet=True)
        outs.append([m.data.tobytes() for m in _read(out / "landing.bag", "/c/image_raw")])
    assert outs[0] == outs[1]
    assert outs[0] != outs[2]


class _Ctx:
    def __init__(self, scene: Any) -> None:
        self._r = gl.get_renderer(scene)

    def renderer(self) -> Any:
        return self._r


def test_stereo_disparity_is_fb_over_z() -> None:
    scene = board_scene()
    cfg = StereoCameraConfig.model_validate(
        {
            "type": "stereo_camera",
            "name": "s",
            "rate": 1.0,
            "topic": "/s",
            "resolution": [320, 240],
            "fx": 200.0,
            "baseline": 0.3,
            "encoding": "mono8",
        }
    )
    cam = StereoCamera(cfg)
    cam._plans(_Ctx(scene))  # type: ignore[arg-type]
    Z = 6.0
    T_wb = look_down(-0.15, 0.0, Z) @ np.linalg.inv(T_LINK_OPTICAL)
    rng = np.random.default_rng(0)
    corners = []
    for e in cam._eyes:
        img = cam.finish_image(cam.render_linear(gl.get_renderer(scene), e, T_wb[None]), rng)
        c = detect_corners(img)
        assert c is not None
        corners.append(c)
    left, right = corners
    np.testing.assert_allclose(left[:, 1], right[:, 1], atol=0.2)  # rectified rows
    np.testing.assert_allclose(left[:, 0] - right[:, 0], 200.0 * 0.3 / Z, atol=0.3)
    tf = {t.child: t for t in cam.static_transforms()}
    np.testing.assert_allclose(tf["s_right_optical"].T[:3, 3], [0, -0.3, 0], atol=1e-12)


@pytest.mark.parametrize(
    ("model", "coeffs"),
    [("plumb_bob", [-0.25, 0.08, 0.002, -0.001, 0.0]), ("equidistant", [0.05, -0.02, 0.01, 0.0])],
)
def test_distorted_depth_camera_is_analytic(model: str, coeffs: list[float]) -> None:
    # Every output pixel's depth equals the z-depth of its own (distorted) ray hitting the
    # board, off the board's outline; beyond the board nothing is hit (inf, NaN in the
    # message). The remap interpolates 1/z (affine on planes) and takes the nearest sample
    # at depth edges: no pixel may blend the board with the background.
    scene = board_scene()
    cfg = DepthCameraConfig.model_validate(
        {
            "type": "depth_camera",
            "name": "d",
            "rate": 1.0,
            "topic": "/d",
            "resolution": [160, 120],
            "fx": 110.0,
            "fy": 112.0,
            "cx": 81.3,
            "cy": 58.6,
            "distortion_model": model,
            "distortion_coeffs": coeffs,
        }
    )
    cam = DepthCamera(cfg)
    cam._plans(_Ctx(scene))  # type: ignore[arg-type]
    e = cam._eyes[0]
    assert e.plan is not None
    assert not e.plan.identity
    T = look_down(0.3, -0.2, 2.2, tilt=0.35)
    T_wb = T @ np.linalg.inv(T_LINK_OPTICAL)
    z = cam.render_depth(gl.get_renderer(scene), e, T_wb)
    u, v = np.meshgrid(np.arange(160.0), np.arange(120.0))
    xy = e.model.undistort_normalized(np.stack([u.ravel(), v.ravel()], 1)).reshape(120, 160, 2)
    rays = np.concatenate([xy, np.ones((120, 160, 1))], axis=-1) @ T[:3, :3].T
    s = -T[2, 3] / rays[..., 2]  # the plane z = 0; z-depth = s (optical z of the ray is 1)
    hit = T[:3, 3] + s[..., None] * rays
    half = np.array([(7 + 3) * 0.25, (5 + 3) * 0.25])
    margin = 0.08  # ~2.5 render pixels at this range (nearest samples within 2 of an edge)
    inside = np.all(np.abs(hit[..., :2]) < half - margin, axis=-1)
    outside = np.any(np.abs(hit[..., :2]) > half + margin, axis=-1)
    assert inside.sum() > 4000
    assert outside.sum() > 1000
    np.testing.assert_allclose(z[inside], s[inside], rtol=2e-4)
    assert np.all(np.isinf(z[outside]))
    edge = ~inside & ~outside  # the outline: the board's depth or nothing, never a blend
    ze = z[edge]
    board = np.isfinite(ze)
    np.testing.assert_allclose(ze[board], s[edge][board], rtol=0.02)


def test_calibration_round_trip(tmp_path: Path) -> None:
    m = CameraModel.create(
        640, 480, 400.5, 401.0, 320.2, 239.9, "equidistant", [0.1, -0.01, 0.002, 0.0]
    )
    p = tmp_path / "cam.yaml"
    p.write_text(yaml.safe_dump(m.to_camera_info_yaml()))
    a = load_calibration(p)
    k = tmp_path / "chain.yaml"
    k.write_text(yaml.safe_dump({"cam0": m.to_kalibr(rostopic="/c"), "cam1": m.to_kalibr()}))
    b = load_calibration(k, camera="cam1")
    for x in (a, b):
        np.testing.assert_array_equal(x.K, m.K)
        np.testing.assert_array_equal(x.D, m.D)
        assert x.distortion_model == "equidistant"
        assert (x.width, x.height) == (640, 480)
    # a plumb_bob lens inverts exactly
    r = CameraModel.create(320, 240, 200, 200, 160, 120, "radtan", [-0.3, 0.1, 0.001, 0.002])
    uv = np.array([[0.0, 0.0], [319.0, 239.0], [100.5, 30.25]])
    xy = r.undistort_normalized(uv)
    np.testing.assert_allclose(r.project(np.c_[xy, np.ones(3)]), uv, atol=1e-9)


@pytest.mark.parametrize(
    ("keys", "match"),
    [
        ({"cx": 80.0}, r"cx = 80.0: principal point must lie inside the image"),
        ({"cy": -1.0}, r"cy = -1.0"),
        ({"fx": 0.0}, r"fx = 0.0: focal length must be > 0"),
        ({"distortion_model": "fisheye62"}, r"distortion_model = 'fisheye62': allowed"),
        (
            {"distortion_model": "plumb_bob", "distortion_coeffs": [0.1, 0.2]},
            r"needs 4 or 5 coefficients",
        ),
        (
            {"distortion_model": "equidistant", "distortion_coeffs": [0.1] * 5},
            r"needs 4 coefficients",
        ),
        ({"calibration": "nope.yaml"}, r"nope.yaml: file not found"),
        ({"render_scale": 0.0}, r"render_scale"),
        ({"render_scale": 3.0}, r"render_scale"),
    ],
)
def test_bad_intrinsics(keys: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        _config(
            [
                {
                    "type": "camera",
                    "name": "c",
                    "rate": 1.0,
                    "topic": "/c",
                    "resolution": [64, 48],
                    **keys,
                }
            ]
        )


def test_bad_calibration_files(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("image_width: 64\nimage_height: [\n")
    with pytest.raises(SensorError, match=r"bad.yaml: malformed YAML"):
        load_calibration(bad)
    info = CameraModel.create(64, 48, 40, 40, 31.5, 23.5).to_camera_info_yaml()
    info["camera_matrix"]["data"][2] = 99.0
    f = tmp_path / "cx.yaml"
    f.write_text(yaml.safe_dump(info))
    with pytest.raises(SensorError, match=r"cx.yaml: camera_matrix.data\[2\] \(cx\) = 99.0"):
        load_calibration(f)
    del info["camera_matrix"]
    f.write_text(yaml.safe_dump(info))
    with pytest.raises(SensorError, match=r"cx.yaml: camera_matrix: missing key"):
        load_calibration(f)
    chain = tmp_path / "chain.yaml"
    chain.write_text(yaml.safe_dump({"cam0": {"intrinsics": [1, 1, 1], "resolution": [4, 4]}}))
    with pytest.raises(SensorError, match=r"chain.yaml: cam0.intrinsics"):
        load_calibration(chain)
    with pytest.raises(SensorError, match=r"calibration_camera = 'cam3'"):
        load_calibration(chain, camera="cam3")


def test_resolution_larger_than_renderer(tmp_path: Path) -> None:
    big = gl.get_renderer(board_scene()).max_size + 8
    cfg = _config(
        [
            {
                "type": "camera",
                "name": "c",
                "rate": 1.0,
                "topic": "/c",
                "resolution": [big, 4],
                "cx": 1.0,
                "cy": 1.0,
            }
        ]
    )
    with pytest.raises(SensorError, match=r"resolution"):
        run_simulation(cfg, tmp_path / "o", quiet=True)


class _FakeRenderer:
    max_size = 4096

    def check_size(self, width: int, height: int) -> None:
        pass


class _FakeCtx:
    def renderer(self) -> _FakeRenderer:
        return _FakeRenderer()


@pytest.mark.parametrize("render_scale", [None, 1.0, 0.6])
def test_render_scale_sets_the_plan(render_scale: float | None) -> None:
    """Distorted lens: the plan's focal length is ``render_scale`` x the camera's; by
    default the render has about as many pixels as the output (< 1.59x at scale 1)."""
    sensor = {
        "type": "camera",
        "name": "c",
        "rate": 1.0,
        "topic": "/c",
        "resolution": [640, 480],
        "fx": 320.0,
        "distortion_model": "plumb_bob",
        "distortion_coeffs": [-0.2, 0.05, 0.0, 0.0, 0.0],
        **({} if render_scale is None else {"render_scale": render_scale}),
    }
    cam = Camera(CameraConfig.model_validate(sensor))
    cam._plans(_FakeCtx())  # type: ignore[arg-type]
    plan = cam._eyes[0].plan
    assert plan is not None
    # the output border's rays set the render's extent (a lens maps the border to the
    # border); left edge column u = 0, top row v = 0
    u = np.arange(640.0)
    v = np.arange(480.0)
    border = np.concatenate([np.c_[np.zeros(480), v], np.c_[u, np.zeros(640)]])
    xy = cam._eyes[0].model.undistort_normalized(border)
    f = plan.K[0, 0]
    if render_scale is None:
        assert 0.5 * 320.0 < f < 320.0
        assert 640 * 480 <= plan.width * plan.height <= 1.03 * 640 * 480
    else:
        assert f == pytest.approx(render_scale * 320.0)
    # the render just covers the corner ray (+ the 2 px interpolation margin)
    assert plan.K[0, 2] == pytest.approx(-f * xy[:, 0].min() + 2.0, abs=1.0)
    assert plan.K[1, 2] == pytest.approx(-f * xy[:, 1].min() + 2.0, abs=1.0)
    assert plan.width == pytest.approx(2.0 * plan.K[0, 2], abs=2.0)  # symmetric lens


@pytest.mark.parametrize("gamma", ["srgb", 2.2])
def test_encode_kernel_matches_numpy(gamma: str | float) -> None:
    """The fused numba encoding gives encode_linear's bytes: every float32 step around
    the LUT's rounding boundaries, out-of-range values, NaN, gain and bgr order."""
    lut = srgb_lut(gamma)
    # the values i / 16383 +- a few ulp are where the index rounds: the hard cases
    centres = (np.arange(16384, dtype=np.float32) + np.float32(0.5)) / np.float32(16383)
    near = np.concatenate([np.nextafter(centres, 2), centres, np.nextafter(centres, -1)])
    rng = np.random.default_rng(3)
    x = np.concatenate(
        [
            near,
            rng.uniform(-0.2, 1.2, 100_000).astype(np.float32),
            np.array([np.inf, -np.inf, -0.0, 0.0, 1.0, 0.0031308], np.float32),
        ]
    )
    for gain in (1.0, 0.37, 2.5):
        ref = encode_linear(x * np.float32(gain), lut) if gain != 1.0 else encode_linear(x, lut)
        np.testing.assert_array_equal(encode_image(x, lut, gain=gain), ref)
    # NaN (NumPy's cast of it is platform-defined): the darkest code
    assert encode_image(np.array([np.nan], np.float32), lut)[0] == lut[0]
    # sRGB by hand: 0.1 -> 1.055 * 0.1 ** (1 / 2.4) - 0.055 = 0.3492 -> 89.04; the linear
    # segment: 0.001 -> 12.92e-3 * 255 = 3.29
    np.testing.assert_array_equal(
        encode_image(np.array([0.0, 0.001, 0.1, 1.0], np.float32), srgb_lut("srgb")),
        [0, 3, 89, 255],
    )
    img = rng.uniform(0.0, 1.0, (7, 5, 3)).astype(np.float32)
    np.testing.assert_array_equal(
        encode_image(img, lut, reverse=True), encode_linear(img, lut)[..., ::-1]
    )
    np.testing.assert_array_equal(encode_image(img[..., 1], lut), encode_linear(img[..., 1], lut))


@pytest.mark.parametrize("distorted", [False, True])
def test_exposure_average_through_reused_buffers(distorted: bool) -> None:
    """render_linear over several poses = the mean of the renderer's frames (remapped
    through the plan's maps), computed here from fresh renders; repeated calls reuse the
    eye's buffers and give the same values."""
    scene = board_scene()
    keys: dict[str, Any] = {"type": "camera", "name": "c", "rate": 1.0, "topic": "/c"}
    keys |= {"resolution": [96, 72], "fx": 60.0}
    if distorted:
        keys |= {"distortion_model": "plumb_bob", "distortion_coeffs": [-0.2, 0.05, 0, 0, 0]}
    cam = Camera(CameraConfig.model_validate(keys))
    cam._plans(_Ctx(scene))  # type: ignore[arg-type]
    e = cam._eyes[0]
    p = e.plan
    assert p is not None
    r = gl.get_renderer(scene)
    base = look_down(0.05, 0.02, 1.2, tilt=0.1) @ np.linalg.inv(T_LINK_OPTICAL)
    T_wb = np.stack([base.copy() for _ in range(3)])
    T_wb[:, 0, 3] += [0.0, 0.01, 0.02]  # a sideways blur
    frames = [r.render(T @ T_LINK_OPTICAL, p.K, p.width, p.height, depth=False).color for T in T_wb]
    expected = (frames[0] + frames[1] + frames[2]) * np.float32(1 / 3)
    if distorted:
        expected = cv2.remap(
            expected, p.map1, p.map2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
    got = cam.render_linear(r, e, T_wb).copy()
    assert got.shape == (72, 96, 3)
    np.testing.assert_allclose(got, expected, atol=1e-6)
    assert np.abs(frames[2] - frames[0]).max() > 0.1  # the poses differ
    cam.render_linear(r, e, T_wb[:1])  # a different frame in the same buffers
    np.testing.assert_array_equal(cam.render_linear(r, e, T_wb), got)
