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

from roslan.env.attitude import AttitudeFilter
from roslan.env.marker_bearing import MarkerDetector
from roslan.env.navigation import HorizontalFilter, VerticalEstimator
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
    gaps_xy: F64 | None = None
    R_world_body: F64 | None = None
    marker_fixes: int = 0


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
    HORIZONTAL_TIME = 0.4
    """s: velocity tracking time constant of the horizontal and attitude loops."""
    MAX_SPEED = 3.0
    """m/s: bound of the horizontal speed the tau coupling asks for."""
    COUPLING_TAU_MIN = 1.0
    """s: the tau coupling's tau is held at ``-COUPLING_TAU_MIN`` once closer to contact:
    the residual horizontal gap is then centred with time constant ``kappa *
    COUPLING_TAU_MIN`` instead of a speed that grows as ``1 / tau``."""

    FIX_AGREEMENT = 0.1
    """m per m of camera height: two consecutive marker candidates closer than this are
    a fix."""
    ATTITUDE_MAX_ACCEL = 3.0
    """m/s^2: the attitude filter's accelerometer correction pauses while the expected
    horizontal acceleration is larger (:class:`~roslan.env.attitude.AttitudeFilter`'s
    ``max_accel``)."""
    TRACK_STEPS = 5
    """Steps after a fix during which the marker is tracked: looked for near its
    prediction, at the height the fixes gave (``TRACK_BAND``)."""
    TRACK_BAND = (0.85, 1.2)
    """The heights searched while tracking, as multiples of the height estimate."""
    SETTLED_FIXES = 5
    """Fixes after which the marker's position and height are known well enough to gate
    the next fixes: the height searched within ``KNOWN_BAND`` of the estimate, a fix
    outside 4 sigma of the horizontal filter's prediction rejected."""
    KNOWN_BAND = (0.8, 1.25)
    """The heights searched once settled, as multiples of the height estimate."""
    MAX_GOAL_HEIGHT = 0.5
    """m: a goal farther from the world's ground plane than this is refused (a perch)."""

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
        est = context.start_estimate
        if est is None or context.goal_position is None or context.base_link_goal is None:
            msg = (
                "tau-events: the PolicyContext has no start estimate or goal; build it with "
                "env.policy_context() after env.reset()"
            )
            raise ConfigError(msg)
        goal_z = float(context.goal_position[2])
        if abs(goal_z) > self.MAX_GOAL_HEIGHT:
            msg = (
                f"--policy tau-events: the goal is at z = {goal_z:.2f} m in the world, not on "
                f"the ground plane (|z| <= {self.MAX_GOAL_HEIGHT} m): tau-events lands on the "
                "surface its downward event camera sees (the ground and its marker), not on a "
                "perch above it (roslan/Perching-v0); fly tau-state there"
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
        self._K = K
        self._est = DivergenceEstimator(
            int(model.width), int(model.height), K[0, 0], K[1, 1], K[0, 2], K[1, 2],
            R_cam_imu=R_body_cam.T @ self._R_body_imu, params=self.params,
        )  # fmt: skip
        self._marker = MarkerDetector(int(model.width), int(model.height), float(K[0, 0]))
        self._cam_pos = np.asarray(ev.pose.position, dtype=np.float64)
        feet = np.asarray(cfg.vehicle.feet, dtype=np.float64)
        self._contact_z = float(feet[:, 2].min())  # base_link above the ground at rest
        tr = cfg.trajectory
        self._k = float(tr.k)
        self._kappa = np.array([tr.kappa.x, tr.kappa.y])
        Rwg = np.asarray(context.R_world_goal, dtype=np.float64)
        self._R_world_goal = Rwg
        # the marker (the goal) relative to base_link's touchdown position, world
        self._goal_offset = np.asarray(context.goal_position) - np.asarray(context.base_link_goal)
        cl = cfg.closed_loop
        se = cl.start_estimate if cl is not None else None
        sp, sv, sa = (0.3, 0.1, 0.02) if se is None else (
            se.position_sigma, se.velocity_sigma, se.attitude_sigma
        )  # fmt: skip
        sb = float(imu.accelerometer_turn_on_bias_sigma) + float(  # type: ignore[attr-defined]
            np.linalg.norm(imu.accelerometer_bias)  # type: ignore[attr-defined]
        )
        self._lag = 0.0 if cl is None else float(cl.dynamics.acceleration_lag)
        # the commanded acceleration the vehicle starts with: the nominal landing's
        s0 = TauTrajectory(tr, warn=False).state([0.0])
        self._a_model = Rwg @ s0.accels[0, :3]
        self._a_cmd = self._a_model.copy()
        gravity = float(imu.gravity)  # type: ignore[attr-defined]
        self._att = AttitudeFilter(
            est.R_world_body, gravity=gravity, max_accel=self.ATTITUDE_MAX_ACCEL
        )
        self._g = np.array([0.0, 0.0, -gravity])
        self._imu = _Imu(
            self._att.R, np.asarray(est.velocity, dtype=np.float64).copy(), np.zeros(3), 0
        )
        self._tilt_sigma = 1.5 * sa + 0.005
        self._vert = VerticalEstimator(float(est.gaps[2]), sp, sv, sb + 0.01)
        self._horiz = HorizontalFilter(
            np.asarray(est.gaps[:2]),
            np.asarray(est.rates[:2]),
            sp,
            sv,
            sb + 0.5 * 9.81 * sa,
            heading_sigma=sa,
        )
        self._hist_t: list[F64] = []
        self._hist_p: list[F64] = []
        self._hist_v: list[F64] = []
        self._candidate: F64 | None = None
        self._last_fix_step = -(10**6)
        self._n_meas = 0
        self._steps = 0
        self._last: DivergenceEstimate | None = None
        self.estimate = None
        self.history = []

    # ------------------------------------------------------------------ sensing
    def _integrate(self, rows: F64, end_ns: int) -> tuple[NDArray[np.int64], F64, F64, float]:
        """Strapdown over the step's IMU rows (valid, t - end s, acc (3), gyro (3)) with
        the attitude filter; returns the samples' times (ns), gyro (N, 3), the world
        velocity increment (3,) and the time covered (s)."""
        rows = rows[rows[:, 0] > 0.5]
        t = end_ns + np.round(rows[:, 1].astype(np.float64) * 1e9).astype(np.int64)
        acc = rows[:, 2:5].astype(np.float64) @ self._R_body_imu.T
        gyro = rows[:, 5:8].astype(np.float64)
        gyro_b = gyro @ self._R_body_imu.T
        st = self._imu
        v_before, t_before = st.v.copy(), st.t_ns
        ts, ps, vs = [], [], []
        lag = self._lag
        # a sequential update per IMU sample (~20 per step): attitude is a product
        for i in range(t.shape[0]):
            dt = max(int(t[i]) - st.t_ns, 0) * 1e-9
            if lag > 0.0:
                self._a_model = self._a_model + (self._a_cmd - self._a_model) * (
                    1.0 - math.exp(-dt / lag)
                )
            else:
                self._a_model = self._a_cmd
            st.R_wb = self._att.update(gyro_b[i], acc[i], dt, self._a_model)
            a = st.R_wb @ acc[i] + self._g
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
        return t, gyro, st.v - v_before, (st.t_ns - t_before) * 1e-9

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

    def _measure(self, e: DivergenceEstimate) -> None:
        p, v = self._at(e.t_ns)
        t = e.t_ns * 1e-9
        vz = self._vert.velocity(t, v)
        ok = e.confidence >= self.MIN_CONFIDENCE and -self.MAX_TAU < e.tau < 0.0 and vz < -0.05
        if ok:
            # D h_cam = -vz, h_cam = the height gap + the camera's height above it
            # a tilt error of the normal biases D by ~1.5 V tilt / h: D h_cam by 1.5 V tilt
            extra = 1.5 * float(np.linalg.norm(self._horiz.rates)) * self._tilt_sigma
            o = self._camera_offset_z() - self._contact_z
            ok = self._vert.add(-1.0 / e.tau, t, p, v, o, extra)
            self._n_meas += int(ok)
        self.history.append((t, e.tau, e.confidence, ok))

    def _look(self, x: Any, y: Any, t: Any, h: float) -> None:
        """Find the marker in the step's events; a fix corrects the horizontal filter and
        gives the vertical estimator a height (the marker's known size)."""
        R_wc = self._imu.R_wb @ self._R_body_cam
        Rwg = self._R_world_goal
        h_cam = h + self._camera_offset_z() - self._contact_z
        if not (math.isfinite(h_cam) and h_cam > 0.2):
            return
        hz = self._horiz
        base = Rwg @ np.array([*hz.gaps, h])  # base_link relative to its touchdown position
        rel = self._goal_offset - base - self._imu.R_wb @ self._cam_pos  # marker - camera
        r = R_wc.T @ rel
        K = self._K
        tracking = self._steps - self._last_fix_step <= self.TRACK_STEPS
        if r[2] > 0.1 * float(np.linalg.norm(r)):
            u, v = K[0, 0] * r[0] / r[2] + K[0, 2], K[1, 1] * r[1] / r[2] + K[1, 2]
        else:
            u = v = math.nan
        margin = 3.0 * hz.sigma * K[0, 0] / h_cam + 40.0
        if not self._marker.visible(u, v, h_cam, margin):
            self._candidate = None
            return
        # tracking: the height known from the last fixes, the marker near its prediction;
        # once the marker gave heights, the height is searched near the estimate
        if tracking:
            band: tuple[float, float] | None = self.TRACK_BAND
        else:
            band = self.KNOWN_BAND if self._vert.heights >= self.SETTLED_FIXES else None
        fix = self._marker.find(
            x, y, h_cam,
            predicted=(u, v) if tracking else None,
            gate=margin if tracking else math.inf,
            t=t,
            band=band,
        )  # fmt: skip
        if fix is None:
            self._candidate = None
            return
        ray = R_wc @ np.array([(fix.u - K[0, 2]) / K[0, 0], (fix.v - K[1, 2]) / K[1, 1], 1.0])
        if ray[2] > -0.1:
            return
        marker_rel = ray * fix.height  # marker - camera, world (fix.height: its depth)
        h_cam_fix = -float(marker_rel[2])
        base_rel = -marker_rel + self._goal_offset - self._imu.R_wb @ self._cam_pos
        xy = (Rwg.T @ base_rel)[:2]
        # the events' mean time is before the step's end: carry the fix forward
        dt = max(self._imu.t_ns - fix.t_ns, 0) * 1e-9 if fix.t_ns else 0.0
        xy = xy + hz.rates * dt
        prev, self._candidate = self._candidate, xy
        # fused only when the last step's candidate agrees (the gap moves ~v dt a step)
        if prev is None or float(np.linalg.norm(xy - prev)) > self.FIX_AGREEMENT * h_cam_fix:
            return
        off = float(np.linalg.norm(xy))
        sigma = 3.0 * h_cam_fix / K[0, 0] + 0.04 * off + 0.01
        # once settled on the marker, a fix far outside the filter's uncertainty is wrong
        # (a partial view at low height can fit the checker ring as the white one)
        if hz.fixes >= self.SETTLED_FIXES:
            limit = 4.0 * math.hypot(hz.sigma, sigma) + 0.1 * h_cam_fix
            if float(np.linalg.norm(xy - hz.gaps)) > limit:
                return
        self._last_fix_step = self._steps
        hz.correct(xy, sigma)
        if fix.t_ns:
            p, _ = self._at(fix.t_ns)
            h_gap = h_cam_fix - (self._camera_offset_z() - self._contact_z)
            self._vert.add_height(h_gap, fix.t_ns * 1e-9, p, 0.04 * h_cam_fix + 0.01)

    # ------------------------------------------------------------------ control
    def act(self, observation: Mapping[str, Any], info: Mapping[str, Any]) -> F64:
        """(6,) action: world acceleration (m/s^2) and body rates (rad/s) (module docstring).

        Reads ``observation["imu"]`` and ``info["events"]`` (the raw events) only."""
        ctx = self._ctx
        assert ctx is not None, "reset() first"
        step_ns = round(ctx.control_dt * 1e9)
        end_ns = self._steps * step_ns
        self._steps += 1
        imu_rows = np.asarray(observation["imu"], dtype=np.float64)
        gyro_t, gyro, dv, span = self._integrate(imu_rows, end_ns)
        self._horiz.predict((self._R_world_goal.T @ dv)[:2], span)
        ev = info.get("events") or {}
        t_now = self._imu.t_ns * 1e-9
        x, y = ev.get("x", ()), ev.get("y", ())
        if end_ns > 0:
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
        h = self._vert.height(t_now, float(self._imu.p[2]))
        vz = self._vert.velocity(t_now, float(self._imu.v[2]))
        if end_ns > 0 and len(x):
            self._look(x, y, ev.get("t", None), h)
        tau = h / vz if vz < -1e-3 else math.nan
        last = self._last
        self.estimate = TauEventsEstimate(
            tau=tau,
            height=h,
            vz=vz,
            tau_camera=last.tau if last is not None else math.nan,
            confidence=last.confidence if last is not None else 0.0,
            measurements=self._n_meas,
            gaps_xy=self._horiz.gaps,
            R_world_body=self._imu.R_wb.copy(),
            marker_fixes=self._horiz.fixes,
        )
        out = self._command(h, vz, tau)
        self._a_cmd = out[:3].copy()
        return out

    def _command(self, h: float, vz: float, tau: float) -> F64:
        assert self._ctx is not None
        st = self._imu
        k = self._k
        if h <= 0.02 or vz >= -0.1 or not math.isfinite(tau):
            az = (-0.25 - vz) / 0.2  # at (estimated) contact or hovering: settle down slowly
        else:
            az = (1.0 - k) * vz / tau  # constant tau-dot guide through the current state
        # horizontal gaps (goal frame) from the filter, tau-coupled: x' = x / (kappa tau)
        Rgw = self._R_world_goal.T
        xy, v_xy = self._horiz.gaps, self._horiz.rates
        tc = self.HORIZONTAL_TIME
        if math.isfinite(tau) and tau < -0.05:
            tau_c = min(tau, -self.COUPLING_TAU_MIN)
            v_des = np.clip(xy / (self._kappa * tau_c), -self.MAX_SPEED, self.MAX_SPEED)
        else:
            v_des = -xy / (2.0 * tc)
        a_goal = np.array([*((v_des - v_xy) / tc), 0.0])
        a_world = self._R_world_goal @ a_goal
        a_world[2] = az
        # attitude: level to the goal's attitude
        rpy = matrix_to_rpy(Rgw @ st.R_wb)
        rates = euler_rates_to_body_rates(rpy, -rpy / tc)
        out = np.concatenate([a_world, rates])
        lim = np.array([self._ctx.max_acceleration] * 3 + [self._ctx.max_body_rate] * 3)
        return np.asarray(np.clip(out, -lim, lim), dtype=np.float64)
