"""The ``tau-events`` policy: land with constant tau-dot on tau read from the event camera.

Perception (docs/guide/closed-loop.md, "Tau from events"):

* :class:`roslan.events.DivergenceEstimator` turns each step's events (``info["events"]``)
  and gyro samples (``observation["imu"]``) into the divergence ``D`` of the ground seen
  by the downward-looking event camera, i.e. the camera's time to contact with the ground
  ``tau_cam = -1 / D`` (contrast maximisation of a scaling warp, Gallego et al., CVPR
  2018), with the ground's normal in the camera from the IMU's attitude.
* A strapdown integration of the IMU (gyro for attitude, accelerometer for velocity),
  started from the launch state of the config (``trajectory.initial``: attitude and
  velocity; not the height), gives the vertical velocity ``vz`` and a dead-reckoned
  height ``p`` that is exact up to an unknown offset: the ground's level.
* Each estimate gives the camera's height ``h_cam = tau_cam * vz`` at the window's
  reference time, hence one measurement of the ground's level in the dead-reckoned frame;
  the median of the last 40 weighted by ``1 / h_cam`` (an estimate's error grows with the
  height; a median ignores the outliers; the first 10 are only collected) gives the height
  gap now, ``h``, and the tau of the height gap ``tau = h / vz`` (the camera sits higher
  than the feet: this offset, known from the vehicle's geometry, is why the gap's tau is
  not the camera's).

Control: constant tau-dot ``k`` (``trajectory.k``) on the height gap. For ``tau = h / h'``,
``tau' = 1 - h h'' / h'^2``, so ``tau' = k`` needs ``h'' = (1 - k) h'^2 / h = (1 - k) vz /
tau``: the braking acceleration of the constant-tau-dot guide through the current state,
which needs only ``vz`` and ``tau``. The horizontal gaps are tau-coupled to it (``x' = x /
(kappa_x tau)``, dead-reckoned from the launch position relative to the goal; in the last
``COUPLING_TAU_MIN`` seconds the coupling's tau is held there) and the attitude gaps are
levelled to the goal's attitude. A distorted camera's events are moved to their pixels'
ideal (undistorted) positions first. Assumptions: a flat, textured ground under the camera,
the launch state known, an IMU without large biases.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import ConfigError
from roslan.events.divergence import DivergenceEstimate, DivergenceEstimator, DivergenceParams
from roslan.frames import R_LINK_OPTICAL, euler_rates_to_body_rates, matrix_to_rpy, rpy_to_matrix

if TYPE_CHECKING:
    from roslan.env.policies import PolicyContext

__all__ = ["TauEventsEstimate", "TauEventsPolicy"]

F64 = NDArray[np.float64]

G_WORLD = np.array([0.0, 0.0, -9.81])


@dataclass(frozen=True)
class TauEventsEstimate:
    """The policy's view of the height gap at the end of the last step.

    ``tau``: the height gap's time to contact (s, negative while descending; nan before
    the first estimate); ``height``: the height gap (m); ``vz``: vertical velocity (m/s,
    IMU); ``tau_camera``: the last estimate of the camera's tau from events (s);
    ``confidence`` of that estimate; ``measurements``: estimates accepted so far.
    """

    tau: float
    height: float
    vz: float
    tau_camera: float
    confidence: float
    measurements: int


@dataclass
class _Imu:
    """Strapdown state of base_link in the world: attitude, velocity, relative position."""

    R_wb: F64
    v: F64
    p: F64
    t_ns: int


class TauEventsPolicy:
    """Constant tau-dot landing on tau estimated from events (module docstring).

    Attributes:
        estimate: :class:`TauEventsEstimate` after each :meth:`act` (None before).
        history: (t_ref s, tau_cam s, confidence, accepted) of every event estimate.
    """

    MIN_CONFIDENCE = 0.02
    """Event estimates below this confidence are ignored."""
    MAX_TAU = 20.0
    """s: camera tau estimates longer than this (barely any expansion) are ignored."""
    MEMORY = 40
    """Ground-level measurements kept (the last ones; 0.8 s at 50 Hz)."""
    MIN_HEIGHT = 0.3
    """m: an estimate's weight is 1 / max(h_cam, MIN_HEIGHT) (its error grows with h)."""
    INIT = 10
    """Accepted estimates before the height is trusted (the launch velocity is held)."""
    HORIZONTAL_TIME = 0.4
    """s: velocity tracking time constant of the horizontal and attitude loops."""
    MAX_SPEED = 3.0
    """m/s: bound of the horizontal speed the tau coupling asks for."""
    COUPLING_TAU_MIN = 1.0
    """s: the tau coupling's tau is held at ``-COUPLING_TAU_MIN`` once closer to contact:
    the residual horizontal gap is then centred with time constant ``kappa *
    COUPLING_TAU_MIN`` instead of a speed that grows as ``1 / tau``."""

    def __init__(self, params: DivergenceParams | None = None) -> None:
        self.params = params
        self.estimate: TauEventsEstimate | None = None
        self.history: list[tuple[float, float, float, bool]] = []
        self._ctx: PolicyContext | None = None

    # ------------------------------------------------------------------ episode
    def reset(self, context: PolicyContext) -> None:
        from roslan.trajectory.generator import TauTrajectory

        cfg = context.config
        self._ctx = context
        ev = next((s for s in cfg.sensors if s.type == "event_camera"), None)
        imu = next((s for s in cfg.sensors if s.type == "imu"), None)
        if ev is None or imu is None:
            msg = (
                "--policy tau-events needs an event camera and an IMU in `sensors` "
                f"(found: {', '.join(s.type for s in cfg.sensors) or 'none'}); the default "
                "configuration (roslan/Landing-v0) has both"
            )
            raise ConfigError(msg)
        model = ev.calibration_cameras()[0].model  # type: ignore[attr-defined]
        self._ideal: tuple[F64, F64] | None = None
        self._width = int(model.width)
        if not model.is_pinhole:
            # every pixel's ideal (undistorted) position, once: an event's is a lookup
            w, h = int(model.width), int(model.height)
            uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
            xy = model.undistort_normalized(np.stack([uu.ravel(), vv.ravel()], axis=1))
            self._ideal = (model.fx * xy[:, 0] + model.cx, model.fy * xy[:, 1] + model.cy)
        self._R_body_cam = R_body_cam = rpy_to_matrix(np.asarray(ev.pose.rpy)) @ R_LINK_OPTICAL
        self._R_body_imu = rpy_to_matrix(np.asarray(imu.pose.rpy))
        K = np.asarray(model.K, dtype=np.float64)
        self._est = DivergenceEstimator(
            int(model.width), int(model.height), K[0, 0], K[1, 1], K[0, 2], K[1, 2],
            R_cam_imu=R_body_cam.T @ self._R_body_imu, params=self.params,
        )  # fmt: skip
        self._cam_pos = np.asarray(ev.pose.position, dtype=np.float64)
        feet = np.asarray(cfg.vehicle.feet, dtype=np.float64)
        self._contact_z = float(feet[:, 2].min())  # base_link above the ground at rest
        tr = cfg.trajectory
        self._k = float(tr.k)
        self._kappa = np.array([tr.kappa.x, tr.kappa.y])
        # the launch state (what the vehicle is told at release): attitude and velocity
        # (flapping included: the IMU measures the flapping body's motion from there)
        s0 = TauTrajectory(tr, warn=False).state([0.0])
        gaps, rates = s0.gaps[0], s0.rates[0]
        Rwg = np.asarray(context.R_world_goal, dtype=np.float64)
        self._R_world_goal = Rwg
        self._imu = _Imu(Rwg @ rpy_to_matrix(gaps[3:6]), Rwg @ rates[:3], np.zeros(3), 0)
        self._xy0 = gaps[:2].copy()  # horizontal gaps at launch (goal frame)
        self._hist_t: list[F64] = []
        self._hist_p: list[F64] = []
        self._hist_v: list[F64] = []
        self._grounds: list[float] = []
        self._weights: list[float] = []
        self._ground = math.nan
        self._n_meas = 0
        self._steps = 0
        self._last: DivergenceEstimate | None = None
        self.estimate = None
        self.history = []

    # ------------------------------------------------------------------ sensing
    def _integrate(self, rows: F64, end_ns: int) -> tuple[NDArray[np.int64], F64]:
        """Strapdown over the step's IMU rows (valid, t - end s, acc (3), gyro (3));
        returns the samples' times (ns) and gyro (N, 3)."""
        rows = rows[rows[:, 0] > 0.5]
        t = end_ns + np.round(rows[:, 1].astype(np.float64) * 1e9).astype(np.int64)
        acc = rows[:, 2:5].astype(np.float64) @ self._R_body_imu.T
        gyro = rows[:, 5:8].astype(np.float64)
        st = self._imu
        ts, ps, vs = [], [], []
        # a sequential update per IMU sample (~20 per step): attitude is a product
        for i in range(t.shape[0]):
            dt = max(int(t[i]) - st.t_ns, 0) * 1e-9
            w = (self._R_body_imu @ gyro[i]) * dt
            st.R_wb = st.R_wb @ _expm_so3(w)
            a = st.R_wb @ acc[i] + G_WORLD
            st.p = st.p + st.v * dt + 0.5 * a * dt * dt
            st.v = st.v + a * dt
            st.t_ns = int(t[i])
            ts.append(st.t_ns)
            ps.append(st.p[2])
            vs.append(st.v[2])
        if ts:
            self._hist_t.append(np.asarray(ts, dtype=np.int64).astype(np.float64))
            self._hist_p.append(np.asarray(ps))
            self._hist_v.append(np.asarray(vs))
            del self._hist_t[:-20], self._hist_p[:-20], self._hist_v[:-20]
        return t, gyro

    def _at(self, t_ns: int) -> tuple[float, float]:
        """Dead-reckoned vertical position and velocity of base_link at ``t_ns``."""
        if not self._hist_t:
            return float(self._imu.p[2]), float(self._imu.v[2])
        t = np.concatenate(self._hist_t)
        return (
            float(np.interp(t_ns, t, np.concatenate(self._hist_p))),
            float(np.interp(t_ns, t, np.concatenate(self._hist_v))),
        )

    def _camera_offset_z(self) -> float:
        """Height of the camera above base_link in the world now (m; negative below)."""
        return float((self._imu.R_wb @ self._cam_pos)[2])

    def _height(self) -> float:
        """The height gap now (base_link above its touchdown height), nan if unknown."""
        if self._n_meas < self.INIT:
            return math.nan
        return float(self._imu.p[2] - self._ground + self._contact_z)

    def _measure(self, e: DivergenceEstimate) -> None:
        p, vz = self._at(e.t_ns)
        ok = e.confidence >= self.MIN_CONFIDENCE and -self.MAX_TAU < e.tau < 0.0 and vz < -0.05
        if ok:
            h_cam = e.tau * vz  # the camera's distance to the ground, m
            # the ground's level in the dead-reckoned frame (the camera's offset from
            # base_link with the attitude at the end of the step, a few ms later)
            self._grounds.append(p + self._camera_offset_z() - h_cam)
            self._weights.append(1.0 / max(h_cam, self.MIN_HEIGHT))
            del self._grounds[: -self.MEMORY], self._weights[: -self.MEMORY]
            self._ground = _weighted_median(np.array(self._grounds), np.array(self._weights))
            self._n_meas += 1
        self.history.append((e.t_ns * 1e-9, e.tau, e.confidence, ok))

    # ------------------------------------------------------------------ control
    def act(self, observation: Mapping[str, Any], info: Mapping[str, Any]) -> F64:
        """(6,) action: world acceleration (m/s^2) and body rates (rad/s) (module docstring)."""
        ctx = self._ctx
        assert ctx is not None, "reset() first"
        step_ns = round(ctx.control_dt * 1e9)
        end_ns = self._steps * step_ns
        self._steps += 1
        gyro_t, gyro = self._integrate(np.asarray(observation["imu"], dtype=np.float64), end_ns)
        ev = info.get("events") or {}
        if end_ns > 0:
            x, y = ev.get("x", ()), ev.get("y", ())
            if self._ideal is not None and len(x):
                at = np.asarray(y, dtype=np.int64) * self._width + np.asarray(x, dtype=np.int64)
                x, y = self._ideal[0][at], self._ideal[1][at]
            e = self._est.update(
                x, y, ev.get("t", ()),
                gyro_t_ns=gyro_t, gyro=gyro, end_ns=end_ns,
                normal=(self._imu.R_wb @ self._R_body_cam).T @ np.array([0.0, 0.0, -1.0]),
            )  # fmt: skip
            if e is not None:
                self._last = e
                self._measure(e)
        h = self._height()
        vz = float(self._imu.v[2])
        tau = h / vz if math.isfinite(h) and vz < -1e-3 else math.nan
        last = self._last
        self.estimate = TauEventsEstimate(
            tau=tau,
            height=h,
            vz=vz,
            tau_camera=last.tau if last is not None else math.nan,
            confidence=last.confidence if last is not None else 0.0,
            measurements=self._n_meas,
        )
        return self._command(h, tau)

    def _command(self, h: float, tau: float) -> F64:
        assert self._ctx is not None
        st = self._imu
        vz = float(st.v[2])
        k = self._k
        if not math.isfinite(h):
            az = 0.0  # no height yet: hold the launch velocity
        elif h <= 0.02 or vz >= -0.1:
            az = (-0.25 - vz) / 0.2  # at (estimated) contact or hovering: settle down slowly
        else:
            az = (1.0 - k) * vz / tau  # constant tau-dot guide through the current state
        # horizontal gaps (goal frame), dead-reckoned, tau-coupled: x' = x / (kappa tau)
        Rgw = self._R_world_goal.T
        v_goal = Rgw @ st.v
        xy = self._xy0 + (Rgw @ st.p)[:2]
        tc = self.HORIZONTAL_TIME
        if math.isfinite(tau) and tau < -0.05:
            tau_c = min(tau, -self.COUPLING_TAU_MIN)
            v_des = np.clip(xy / (self._kappa * tau_c), -self.MAX_SPEED, self.MAX_SPEED)
        else:
            v_des = -xy / (2.0 * tc)
        a_goal = np.array([*((v_des - v_goal[:2]) / tc), 0.0])
        a_world = self._R_world_goal @ a_goal
        a_world[2] = az
        # attitude: level to the goal's attitude
        rpy = matrix_to_rpy(Rgw @ st.R_wb)
        rates = euler_rates_to_body_rates(rpy, -rpy / tc)
        out = np.concatenate([a_world, rates])
        lim = np.array([self._ctx.max_acceleration] * 3 + [self._ctx.max_body_rate] * 3)
        return np.asarray(np.clip(out, -lim, lim), dtype=np.float64)


def _weighted_median(values: F64, weights: F64) -> float:
    """The weighted median of ``values``."""
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])


def _expm_so3(w: F64) -> F64:
    """Rotation matrix of the rotation vector ``w`` (Rodrigues)."""
    th = float(np.linalg.norm(w))
    k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th < 1e-9:
        return np.asarray(np.eye(3) + k, dtype=np.float64)
    out = np.eye(3) + math.sin(th) / th * k + (1.0 - math.cos(th)) / th**2 * (k @ k)
    return np.asarray(out, dtype=np.float64)
