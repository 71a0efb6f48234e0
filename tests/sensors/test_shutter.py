"""Frame-camera shutters against geometry: rolling-shutter skew under a known rotation,
motion-blur length, the shared-render plan, auto-exposure convergence and the recorded
exposure of a simulated run."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import roslan.render.gl as gl
from pipeline_helpers import SHORT_TRAJECTORY
from roslan.config.base import validate_model
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError
from roslan.pipeline import run_simulation
from roslan.scene.model import Lights, Material, Scene, SceneObject
from roslan.sensors.cameras import Camera, CameraConfig
from roslan.sensors.cameras.shutter import (
    AutoExposure,
    auto_exposure_sequence,
    meter_level,
    shutter_plan,
)

FX = 200.0
W, H = 160, 120
DIST = 4.0  # m from the camera to the edge wall


def _edge_scene() -> Scene:
    """A 6 m x 6 m wall in the plane x = DIST facing -x, dark for y > 0 and bright for
    y < 0: one vertical edge through the origin's line of sight."""
    tex = np.full((8, 512, 3), 230, np.uint8)
    tex[:, :256] = 20  # texture u from y = +3 (left in the image) to y = -3
    s = 3.0
    v = np.array([[DIST, s, -s], [DIST, -s, -s], [DIST, -s, s], [DIST, s, s]], np.float32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    n = np.tile(np.array([-1.0, 0.0, 0.0], np.float32), (4, 1))
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    obj = SceneObject("wall", v, n, uv, f, Material(color=(1.0, 1.0, 1.0), texture=tex))
    return Scene(
        "edge", (obj,), Lights(sun_direction=(1.0, 0.0, 0.0), sun_intensity=0.0, ambient=1.0)
    )


def _camera(**keys: Any) -> Camera:
    cfg = {"type": "camera", "name": "c", "rate": 10.0, "topic": "/c", "encoding": "mono8"}
    cfg |= {"resolution": [W, H], "fx": FX, "gamma": 1.0} | keys
    return Camera(CameraConfig.model_validate(cfg))


class _Ctx:
    def __init__(self, r: Any) -> None:
        self._r = r

    def renderer(self) -> Any:
        return self._r


def _poses(t_ns: np.ndarray, omega: float) -> np.ndarray:
    """Body poses (N, 4, 4) of a camera at the origin looking along +x (body = link),
    yawing about the world (= camera vertical) axis at ``omega`` rad/s from t = 0."""
    a = omega * t_ns.astype(np.float64) * 1e-9
    T = np.tile(np.eye(4), (len(a), 1, 1))
    T[:, 0, 0] = np.cos(a)
    T[:, 0, 1] = -np.sin(a)
    T[:, 1, 0] = np.sin(a)
    T[:, 1, 1] = np.cos(a)
    return T


class _Yaw:
    """A trajectory stand-in: the body (= camera link) at the origin looking along +x,
    yawing about the world (= camera vertical) axis at ``omega`` rad/s from t = 0."""

    def __init__(self, omega: float) -> None:
        self.omega = omega

    def state(self, t: np.ndarray) -> Any:
        from types import SimpleNamespace

        T = _poses(np.round(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64), self.omega)
        return SimpleNamespace(R_world_body=T[:, :3, :3], position=T[:, :3, 3])


def _frame(
    omega: float, exposure: float, readout: float, samples: int, stamp_ns: int = 0
) -> np.ndarray:
    """The camera's own frame (its image formation, :meth:`Camera.frame_linear`) stamped
    ``stamp_ns`` while yawing at ``omega``."""
    r = gl.get_renderer(_edge_scene())
    cam = _camera(exposure_time=exposure, readout_time=readout, exposure_samples=samples)

    class Ctx(_Ctx):
        trajectory = _Yaw(omega)

    ctx = Ctx(r)
    cam._plans(ctx)  # type: ignore[arg-type]
    e = cam._eyes[0]
    lin = cam.frame_linear(ctx, r, e, stamp_ns, exposure)  # type: ignore[arg-type]
    return np.asarray(lin, dtype=np.float64).copy()


def _renders_frame(omega: float, exposure: float, readout: float, samples: int) -> np.ndarray:
    """The same frame from ``samples`` renders weighted per row (the reference)."""
    r = gl.get_renderer(_edge_scene())
    cam = _camera(exposure_time=exposure, readout_time=readout, exposure_samples=samples)
    cam._plans(_Ctx(r))  # type: ignore[arg-type]
    e = cam._eyes[0]
    plan = shutter_plan(0, exposure, readout, samples, H)
    lin = cam.render_linear(r, e, _poses(plan.instants_ns, omega), plan)
    return np.asarray(lin, dtype=np.float64).copy()


def _edge_x(img: np.ndarray) -> np.ndarray:
    """Sub-pixel edge column of every row: the dark-to-bright step's position from the
    integral of the normalized profile (exact for any symmetric edge blur)."""
    lo, hi = np.percentile(img, 1), np.percentile(img, 99)
    n = np.clip((img - lo) / (hi - lo), 0.0, 1.0)
    # a step at x_e: pixel i (covering [i - 1/2, i + 1/2]) is bright by its overlap
    return (img.shape[1] - 0.5) - n.sum(axis=1)


def _profile_width(img: np.ndarray) -> float:
    """Standard deviation (px) of the edge's derivative profile, averaged over rows."""
    lo, hi = np.percentile(img, 1), np.percentile(img, 99)
    n = np.clip((img - lo) / (hi - lo), 0.0, 1.0)
    d = np.diff(n, axis=1)
    x = np.arange(d.shape[1]) + 0.5
    wsum = d.sum(axis=1)
    mu = (d * x).sum(axis=1) / wsum
    var = (d * (x - mu[:, None]) ** 2).sum(axis=1) / wsum
    return float(np.sqrt(var.mean()))


def test_rolling_shutter_skews_a_vertical_edge_by_omega_readout_fx() -> None:
    omega, readout = 2.0, 0.04  # rad/s about the camera's vertical axis, s
    rows = np.arange(H, dtype=np.float64)
    still = _edge_x(_frame(0.0, 0.0, 0.0, 1))
    fit0 = np.polyfit(rows, still, 1)
    assert abs(fit0[0] * H) < 0.2  # the edge is vertical in a still frame
    glob = _edge_x(_frame(omega, 0.0, 0.0, 1))
    assert abs(np.polyfit(rows, glob, 1)[0] * H) < 0.2  # global shutter: no skew
    rolled = _edge_x(_frame(omega, 0.0, readout, 16))
    skew = np.polyfit(rows, rolled, 1)[0] * H
    # yawing left (+z up, omega > 0) moves the scene right in the image; later rows see
    # it further right: omega * readout * fx pixels from the first row to the last
    expected = omega * readout * FX
    assert expected == pytest.approx(16.0)
    assert skew == pytest.approx(expected, abs=0.5)
    # the frame's stamp is the middle of the window: the middle row sees the stamp's pose
    assert np.interp((H - 1) / 2, rows, np.polyval(np.polyfit(rows, rolled, 1), rows)) == (
        pytest.approx(float(np.mean(glob)), abs=0.5)
    )


def test_motion_blur_length_is_image_speed_times_exposure() -> None:
    omega, exposure = 5.0, 0.02
    sharp = _profile_width(_frame(0.0, 0.0, 0.0, 1))
    blurred = _profile_width(_frame(omega, exposure, 0.0, 32))
    # a box blur of length L adds L^2 / 12 to the edge profile's variance
    length = math.sqrt(12.0 * (blurred**2 - sharp**2))
    expected = omega * exposure * FX  # image-plane speed (px/s) x exposure
    assert expected == pytest.approx(20.0)
    assert length == pytest.approx(expected, rel=0.10)


def test_rolling_shutter_with_exposure_blurs_and_skews() -> None:
    omega, exposure, readout = 5.0, 0.01, 0.02
    rows = np.arange(H, dtype=np.float64)
    img = _frame(omega, exposure, readout, 24)
    skew = np.polyfit(rows, _edge_x(img), 1)[0] * H
    assert skew == pytest.approx(omega * readout * FX, abs=0.5)
    sharp = _profile_width(_frame(0.0, 0.0, 0.0, 1))
    length = math.sqrt(12.0 * (_profile_width(img) ** 2 - sharp**2))
    assert length == pytest.approx(omega * exposure * FX, rel=0.15)


ROWS = {"top": slice(0, 4), "middle": slice(H // 2 - 2, H // 2 + 2), "bottom": slice(H - 4, H)}
"""The rows checked: the top, middle and bottom four."""


@pytest.mark.parametrize("exposure", [0.0, 0.008])
def test_every_row_is_shifted_by_its_own_instant(exposure: float) -> None:
    """Pure rotation in front of a fronto-parallel plane (2 renders, the default job's
    count): every row's edge sits f * tan(omega * (t_r + E / 2 - t_stamp)) from the still
    frame's, t_r + E / 2 the middle of its own window, within 0.1 px in the top, middle
    and bottom rows (each row on its own, not a fit); the middle row is the stamp's."""
    omega, readout = 2.0, 0.03
    still = _edge_x(_frame(0.0, 0.0, 0.0, 1))
    img = _frame(omega, exposure, readout, 2, stamp_ns=40_000_000)
    rows = np.arange(H, dtype=np.float64)
    t_mid = 0.04 + (rows - (H - 1) / 2) * readout / H  # middle of each row's window (s)
    # the stamp's own pose is yawed by omega * 0.04: the still frame seen from there
    expected = FX * np.tan(omega * t_mid)
    got = _edge_x(img) - still
    for name, sl in ROWS.items():
        err = np.abs(got[sl] - expected[sl])
        assert err.max() <= 0.1, (name, got[sl], expected[sl])
    assert np.ptp(got) > 0.9 * omega * readout * FX  # the rows do differ (~18 px)


@pytest.mark.parametrize(("readout", "samples"), [(0.0, 1), (0.02, 2)])
def test_every_row_is_blurred_by_its_own_motion(readout: float, samples: int) -> None:
    """The edge spread of every checked row (top, middle, bottom) under a pure rotation:
    a box of length f * omega * E adds L^2 / 12 to the edge profile's variance; the length
    measured from the image is within 5 % of the prediction, with a global shutter from
    one render and with a rolling shutter from two."""
    omega, exposure = 5.0, 0.02
    still = _frame(0.0, 0.0, 0.0, 1)
    img = _frame(omega, exposure, readout, samples)
    expected = omega * exposure * FX  # image-plane speed (px/s) x exposure
    assert expected == pytest.approx(20.0)
    for name, sl in ROWS.items():
        sharp = _profile_width(still[sl])
        length = math.sqrt(12.0 * (_profile_width(img[sl]) ** 2 - sharp**2))
        assert length == pytest.approx(expected, rel=0.05), name


def test_stereo_eyes_form_their_rows_the_same_way() -> None:
    """A rolling-shutter stereo camera under the same pure rotation: in each eye every
    checked row's edge is shifted from that eye's still frame by f * tan(omega * t_mid)
    within 0.1 px (the eyes' own poses, the right one 0.12 m along the optical x)."""
    from roslan.sensors.cameras import StereoCamera, StereoCameraConfig

    omega, readout, exposure = 2.0, 0.03, 0.004
    r = gl.get_renderer(_edge_scene())
    cfg = {"type": "stereo_camera", "name": "s", "rate": 10.0, "topic": "/s"}
    cfg |= {"encoding": "mono8", "resolution": [W, H], "fx": FX, "gamma": 1.0}

    def frames(w: float, ro: float, ex: float) -> list[np.ndarray]:
        cam = StereoCamera(
            StereoCameraConfig.model_validate(
                cfg | {"exposure_time": ex, "readout_time": ro, "exposure_samples": 2}
            )
        )

        class Ctx(_Ctx):
            trajectory = _Yaw(w)

        ctx = Ctx(r)
        cam._plans(ctx)  # type: ignore[arg-type]
        return [
            np.asarray(cam.frame_linear(ctx, r, e, 40_000_000, ex), np.float64).copy()  # type: ignore[arg-type]
            for e in cam._eyes
        ]

    still = frames(0.0, 0.0, 0.0)
    moving = frames(omega, readout, exposure)
    rows = np.arange(H, dtype=np.float64)
    expected = FX * np.tan(omega * (0.04 + (rows - (H - 1) / 2) * readout / H))
    for eye, (s0, m) in enumerate(zip(still, moving, strict=True)):
        got = _edge_x(m) - _edge_x(s0)
        for name, sl in ROWS.items():
            assert np.abs(got[sl] - expected[sl]).max() <= 0.1, (eye, name)
    # the eyes do see the edge apart: f * baseline / distance = 6 px of disparity
    assert float(np.mean(_edge_x(still[0]) - _edge_x(still[1]))) == pytest.approx(6.0, abs=0.2)


def test_row_formation_matches_many_renders() -> None:
    """Two renders and the per-row integral against 48 renders weighted per row (the
    reference, renders only): the same image within 1 % of full scale on average and 6 %
    at worst (the reference's own steps are 0.6 px)."""
    omega, exposure, readout = 4.0, 0.008, 0.02
    ours = _frame(omega, exposure, readout, 2)
    ref = _renders_frame(omega, exposure, readout, 48)
    d = np.abs(ours - ref)
    assert d.mean() < 0.01 * ref.max()
    assert d.max() < 0.06 * ref.max()


def _silhouette_scene() -> Scene:
    """A bright wall at x = DIST behind a dark panel at x = DIST - 1 whose right edge is
    slanted 11 degrees from the vertical through the line of sight: a geometric edge
    (a depth step), whose one-sample staircase the edge filter does not remove."""
    n = np.tile(np.array([-1.0, 0.0, 0.0], np.float32), (4, 1))
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    s, x = 3.0, DIST - 1.0
    e = s * np.tan(np.radians(11.0))  # the edge's y at the bottom (-e at the top)
    wall = np.array([[DIST, s, -s], [DIST, -s, -s], [DIST, -s, s], [DIST, s, s]], np.float32)
    panel = np.array([[x, s, -s], [x, e, -s], [x, -e, s], [x, s, s]], np.float32)
    bright = Material(color=(1.0, 1.0, 1.0), texture=np.full((4, 4, 3), 230, np.uint8))
    dark = Material(color=(1.0, 1.0, 1.0), texture=np.full((4, 4, 3), 20, np.uint8))
    objs = (
        SceneObject("wall", wall, n, uv, f, bright),
        SceneObject("panel", panel, n, uv, f, dark),
    )
    return Scene("silhouette", objs, Lights(sun_direction=(1.0, 0.0, 0.0), sun_intensity=0.0))


def test_moving_silhouette_has_no_staircase(monkeypatch: pytest.MonkeyPatch) -> None:
    """A slanted depth edge moving across the image during the exposure: the many renders
    of the reference (64 over the window, one sample per pixel each) average its
    one-sample staircase out; the row formation from two renders does so only because
    they are multisampled (row_exposure.RENDER_SAMPLES): with one sample per pixel its
    warp keeps the staircase, at least 1.5x the RMS error (2.7x measured)."""
    import roslan.sensors.cameras.row_exposure as rx

    omega, exposure, readout = 2.0, 0.01, 0.01  # a 4 px blur, 2 px of skew
    scene = _silhouette_scene()

    def frame(samples: int | None) -> np.ndarray:
        if samples is not None:
            monkeypatch.setattr(rx, "RENDER_SAMPLES", samples)
        r = gl.get_renderer(scene)
        cam = _camera(exposure_time=exposure, readout_time=readout, exposure_samples=2)

        class Ctx(_Ctx):
            trajectory = _Yaw(omega)

        ctx = Ctx(r)
        cam._plans(ctx)  # type: ignore[arg-type]
        lin = cam.frame_linear(ctx, r, cam._eyes[0], 0, exposure)  # type: ignore[arg-type]
        return np.asarray(lin, dtype=np.float64).copy()

    r = gl.get_renderer(scene)
    cam = _camera(exposure_time=exposure, readout_time=readout, exposure_samples=64)
    cam._plans(_Ctx(r))  # type: ignore[arg-type]
    plan = shutter_plan(0, exposure, readout, 64, H)
    ref = np.asarray(cam.render_linear(r, cam._eyes[0], _poses(plan.instants_ns, omega), plan))
    assert rx.RENDER_SAMPLES > 1
    multi = frame(None)
    single = frame(1)
    e_multi = float(np.sqrt(np.mean((multi - ref) ** 2)))
    e_single = float(np.sqrt(np.mean((single - ref) ** 2)))
    assert e_multi < 0.006 * ref.max()  # 0.4 % measured
    assert e_single > 1.5 * e_multi


def test_shutter_plan_shares_renders() -> None:
    # global shutter: the midpoint rule over the exposure, equal weights
    g = shutter_plan(1_000_000_000, 0.004, 0.0, 4, 480)
    assert g.global_shutter
    np.testing.assert_array_equal(
        g.instants_ns - 1_000_000_000, [-1500000, -500000, 500000, 1500000]
    )
    # rolling: n renders over the window, each row's weights sum to 1 and cover exactly
    # its own exposure window
    R, E, n, h = 0.02, 0.004, 12, 480
    p = shutter_plan(0, E, R, n, h)
    assert p.instants_ns.size == n
    np.testing.assert_allclose(p.weights.sum(axis=1), 1.0, atol=1e-6)  # type: ignore[union-attr]
    span = R * (h - 1) / h + E
    assert p.start_ns == round(-0.5 * span * 1e9)
    dt = span / n
    t_r = p.start_ns * 1e-9 + np.arange(h) * R / h + E / 2  # middle of each row's exposure
    tau = p.instants_ns * 1e-9
    mean_t = (p.weights * tau[None, :]).sum(axis=1)  # type: ignore[union-attr]
    np.testing.assert_allclose(mean_t, t_r, atol=dt / 2)
    # each render serves a band of rows, not the whole image
    served = (p.rows[:, 1] - p.rows[:, 0]).max()
    assert served < h * (E + 2 * dt) / R
    # exposure 0: each row takes the render whose cell holds its start
    z = shutter_plan(0, 0.0, R, 8, h)
    assert set(np.unique(z.weights)) == {0.0, 1.0}  # type: ignore[arg-type]


def test_auto_exposure_converges_within_its_time_constant() -> None:
    """A step of scene brightness (x4 at frame 30) under the controller: the log error of
    the image level after one time constant is at most exp(-1) of the error at the step
    (first-order decay), and exp(-4) of it after four."""
    rng = np.random.default_rng(0)
    scene = rng.uniform(0.08, 0.12, size=(60, 80)).astype(np.float32)  # unsaturated
    rate, tau = 30.0, 0.1
    ae = AutoExposure(target=0.18, min_exposure=1e-5, max_exposure=0.03, time_constant=tau)
    e_ref = 0.004

    def brightness(k: int) -> float:
        return 1.0 if k < 30 else 4.0

    def meter(k: int, e: float) -> float:
        return meter_level(scene * np.float32(brightness(k)), e / e_ref)

    n = 30 + int(6 * tau * rate)
    ex = auto_exposure_sequence(meter, n, e_ref, ae, rate)
    level = np.array([meter(k, float(ex[k])) for k in range(n)])
    assert np.all((ex >= ae.min_exposure) & (ex <= ae.max_exposure))
    assert level[29] == pytest.approx(0.18, rel=0.02)  # converged before the step
    err0 = abs(math.log(level[30] / 0.18))
    assert err0 > 1.0  # the step: x4 brighter
    k_tau = 30 + round(tau * rate)
    assert abs(math.log(level[k_tau] / 0.18)) <= math.exp(-1.0) * err0 + 0.02
    k_4tau = 30 + round(4 * tau * rate)
    assert abs(math.log(level[k_4tau] / 0.18)) <= math.exp(-4.0) * err0 + 0.005
    # monotone approach (no overshoot) in an unsaturated scene
    assert np.all(np.diff(level[30:]) <= 1e-12)


def test_auto_exposure_config_errors() -> None:
    base = {"type": "camera", "name": "c", "rate": 30.0, "topic": "/c"}
    with pytest.raises(ValueError, match="max_exposure"):
        CameraConfig.model_validate(
            base | {"exposure_time": 0.01, "auto_exposure": {"max_exposure": 0.05}}
        )
    with pytest.raises(ValueError, match="initial exposure"):
        CameraConfig.model_validate(base | {"auto_exposure": {}})
    with pytest.raises(ValueError, match="readout_time"):
        CameraConfig.model_validate(base | {"readout_time": 0.04})
    with pytest.raises(ValueError, match="min_exposure"):
        AutoExposure(min_exposure=0.01, max_exposure=0.001)


def _sim(sensors: list[dict[str, Any]]) -> SimConfig:
    data = {"trajectory": SHORT_TRAJECTORY, "scene": "empty", "seed": 3}
    data |= {"output": {"formats": ["ros1"]}, "sensors": sensors}
    try:
        return validate_model(SimConfig, data, source="test")
    except ConfigError as err:  # pragma: no cover - a broken fixture
        raise AssertionError(str(err)) from None


def test_recorded_exposure_is_the_one_used(tmp_path: Path) -> None:
    """A camera with auto-exposure beside a fixed-exposure twin (one render at the stamp,
    linear encoding, no noise): each frame's brightness ratio to the twin is its recorded
    exposure over exposure_time, and the level approaches the target."""
    common = {"rate": 10.0, "resolution": [64, 48], "fx": 40.0, "encoding": "mono8"}
    common |= {"gamma": 1.0, "exposure_samples": 1, "exposure_time": 0.004}
    pose = {"position": [0.1, 0.0, 0.0], "rpy": [0.0, 0.4, 0.0]}
    ae = {"target": 0.3, "min_exposure": 0.0005, "max_exposure": 0.05, "time_constant": 0.2}
    sensors = [
        {"type": "camera", "name": "fixed", "topic": "/f", "pose": pose, "gain": 0.5} | common,
        {"type": "camera", "name": "auto", "topic": "/a", "pose": pose, "gain": 0.5}
        | common
        | {"auto_exposure": ae},
    ]
    tmp_path = tmp_path / "out"
    run_simulation(_sim(sensors), tmp_path, quiet=True, overview=False, workers=0)
    from PIL import Image

    def frames(name: str) -> tuple[np.ndarray, list[np.ndarray]]:
        folder = tmp_path / name if name != "fixed" else tmp_path  # the root camera
        lines = (folder / "images.txt").read_text().split("\n")
        paths = [ln.split()[1] for ln in lines if ln]
        imgs = [np.asarray(Image.open(folder / p), dtype=np.float64) for p in paths]
        t = np.array([float(ln.split()[0]) for ln in lines if ln])
        return t, imgs

    t_a, auto = frames("auto")
    t_f, fixed = frames("fixed")
    ex = np.loadtxt(tmp_path / "auto" / "exposures.txt")
    np.testing.assert_array_equal(ex[:, 0], t_a)
    np.testing.assert_array_equal(t_a, t_f)
    assert len(auto) >= 8
    assert ex[0, 1] == pytest.approx(0.004)
    assert np.ptp(ex[:, 1]) > 0.002  # it adapted
    for k, (a, f) in enumerate(zip(auto, fixed, strict=True)):
        ok = (f > 20) & (f < 100) & (a < 250)  # unclipped, well above quantization
        ratio = float(np.median(a[ok] / f[ok]))
        assert ratio == pytest.approx(ex[k, 1] / 0.004, rel=0.03), k
    # centre-weighted metering: the central quarter of the last frame sits at the target
    assert auto[-1][12:36, 16:48].mean() / 255.0 == pytest.approx(0.3, rel=0.1)
    fixed_ex = np.loadtxt(tmp_path / "exposures.txt")
    np.testing.assert_allclose(fixed_ex[:, 1], 0.004)


class _Descent:
    """A trajectory stand-in: the body (= camera link) looking straight down from
    ``z0 - v t`` above the origin."""

    def __init__(self, z0: float, v: float) -> None:
        self.z0, self.v = z0, v

    def state(self, t: np.ndarray) -> Any:
        from types import SimpleNamespace

        t = np.asarray(t, dtype=np.float64)
        R = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # x forward -> down
        pos = np.zeros((t.size, 3))
        pos[:, 2] = self.z0 - self.v * t
        return SimpleNamespace(R_world_body=np.tile(R, (t.size, 1, 1)), position=pos)


def test_depth_camera_rows_see_their_own_instants() -> None:
    """A depth camera descending onto a plane at 2 m/s with a 40 ms readout: the centre
    column's depth in row r is the height at the row's own readout instant (formed from
    8 renders), and a global shutter sees the stamp's height."""
    from roslan.sensors.cameras import DepthCamera, DepthCameraConfig

    scene = Scene(
        "floor",
        (
            SceneObject(
                "floor",
                np.array([[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]], np.float32),
                np.tile(np.array([0, 0, 1], np.float32), (4, 1)),
                np.zeros((4, 2), np.float32),
                np.array([[0, 1, 2], [0, 2, 3]], np.int32),
                Material(color=(0.5, 0.5, 0.5)),
            ),
        ),
        Lights(),
    )
    z0, v, readout = 3.0, 2.0, 0.04
    keys = {"type": "depth_camera", "name": "d", "rate": 10.0, "topic": "/d"}
    cam = DepthCamera(
        DepthCameraConfig.model_validate(
            keys | {"resolution": [40, 30], "fx": 30.0, "readout_time": readout}
        )
    )

    class Ctx(_Ctx):
        trajectory = _Descent(z0, v)

    ctx = Ctx(gl.get_renderer(scene))
    cam._plans(ctx)  # type: ignore[arg-type]
    e = cam._eyes[0]
    stamp = 100_000_000
    z = cam.rolling_depth(ctx, ctx.renderer(), e, stamp)  # type: ignore[arg-type]
    # each row's own readout instant, independently: t_r = t_start + r R / H
    t_r = stamp * 1e-9 - 0.5 * readout * 29 / 30 + np.arange(30) * readout / 30
    np.testing.assert_allclose(z[:, 20], z0 - v * t_r, rtol=1e-4)
    assert np.ptp(z[:, 20]) > 0.05  # the rows do differ
    glob = DepthCamera(
        DepthCameraConfig.model_validate(keys | {"resolution": [40, 30], "fx": 30.0})
    )
    glob._plans(ctx)  # type: ignore[arg-type]
    zg = glob.rolling_depth(ctx, ctx.renderer(), glob._eyes[0], stamp)  # type: ignore[arg-type]
    np.testing.assert_allclose(zg[:, 20], z0 - v * 0.1, rtol=1e-4)


def test_shutter_outputs_identical_across_workers_and_reruns(tmp_path: Path) -> None:
    """A rolling-shutter, auto-exposed, blurred camera and a rolling-shutter depth camera
    give byte-identical outputs in one process and again with two worker processes."""
    from pipeline_helpers import tree_bytes

    sensors = [
        {"type": "imu", "name": "imu", "rate": 100.0, "topic": "/imu"},
        {"type": "camera", "name": "cam", "rate": 10.0, "topic": "/cam", "resolution": [48, 36]}
        | {"exposure_time": 0.004, "readout_time": 0.02, "exposure_samples": 3}
        | {"auto_exposure": {"target": 0.25, "max_exposure": 0.02}, "noise_std": 0.01},
        {"type": "depth_camera", "name": "depth", "rate": 10.0, "topic": "/depth"}
        | {"resolution": [32, 24], "readout_time": 0.02, "readout_samples": 4},
    ]
    cfg = _sim(sensors)
    outs = []
    for i, w in enumerate((0, 2)):
        out = tmp_path / f"o{i}"
        run_simulation(cfg, out, quiet=True, overview=False, workers=w)
        outs.append(tree_bytes(out))
    assert "cam/exposures.txt" in outs[0] or "exposures.txt" in outs[0]
    for got in outs[1:]:
        assert got.keys() == outs[0].keys()
        assert [k for k in outs[0] if got[k] != outs[0][k]] == []


def test_row_kernel_clamps_to_the_render_width() -> None:
    """The row kernel reads the render (the lens's virtual view, here 5 px wide) at its own
    width, not the output's (8 px): a pixel warped past the render's right edge reads the
    edge column, not the next row's first pixels."""
    import roslan.sensors.cameras.row_exposure as rx

    h, wr, H, wo = 4, 5, 2, 8
    imgs = np.arange(h * wr, dtype=np.float32).reshape(h, wr, 1)
    zs = np.ones((h, wr), np.float32)
    one = np.zeros(1, np.int64)
    Kv = np.array([1.0, 0.0, 0.0, 1.0, 0.0])  # fx, skew, cx, fy, cy: pixel = ray
    rays_x = np.tile(np.arange(wo, dtype=np.float32), (H, 1))  # rays at x = 0..7
    rays_y = np.ones((H, wo), np.float32)  # row 1 of the render
    R = np.tile(np.eye(3), (3 * H, 1, 1))
    c = np.zeros((3 * H, 3))
    out = np.full((H, wo, 1), -1.0, np.float32)
    ks = np.zeros(H, np.int64)
    rx._integrate(imgs, zs, one, one, one + h, Kv, rays_x, rays_y, R, c, ks, 0.25, 1, out)
    want = imgs[1, np.minimum(np.arange(wo), wr - 1), 0]
    np.testing.assert_array_equal(out[..., 0], np.tile(want, (H, 1)))
