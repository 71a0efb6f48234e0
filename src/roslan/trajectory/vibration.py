"""Body vibration as a composable layer on any :class:`~roslan.trajectory.base.Trajectory`.

:class:`VibratingTrajectory` wraps a trajectory and moves base_link by a small displacement
``d(t)`` (m, along the unvibrated base_link axes) and rotation ``E(t) = Rx(th_x) Ry(th_y)
Rz(th_z)`` (rad, about them), each a sum of sinusoids (``trajectory.vibration``:
harmonics plus broadband bands) times a C2 fade-out envelope. Every derivative is
analytic, so the world state stays exactly consistent with the pose (the IMU's specific
force and body rates are the derivatives of what the cameras see)::

    p' = p + R d
    v' = v + R (d' + w x d)
    a' = a + R (d'' + al x d + 2 w x d' + w x (w x d))
    R' = R E,   w' = E^T w + w_E,   al' = E^T al - w_E x (E^T w) + al_E

with ``w_E = u1 th_x' + u2 th_y' + e3 th_z'``, ``u1 = Rz^T Ry^T e1``, ``u2 = Rz^T e2``
(the body rate of the XYZ rotation) and ``al_E`` its exact derivative. The 18 gap
components are derived from the vibrated world state (ZYX angles relative to the inner
trajectory's reference frame; Euler rates and accelerations by inverting the body-rate
relations), so trajectory.csv, the ground truth and every sensor see one motion.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.frames import (
    euler_rates_to_body_acceleration,
    matrix_to_quat_xyzw,
    matrix_to_rpy,
    rpy_to_matrix,
)
from roslan.trajectory.base import State, Trajectory
from roslan.trajectory.config import TrajectoryConfig
from roslan.trajectory.vibration_config import VibrationConfig

__all__ = ["VibratingTrajectory", "vibration_components"]

F64 = NDArray[np.float64]
CHUNK = 2048
"""Instants evaluated per block (bounds the (n, K, 6) temporaries)."""


def vibration_components(cfg: VibrationConfig) -> tuple[F64, F64, F64]:
    """The sinusoids: frequencies (K,) Hz, amplitudes (K, 6) of the displacement (m, base_link
    x, y, z) and rotation angles (rad, about x, y, z), phases (K, 6) rad."""
    freqs: list[float] = []
    amps: list[F64] = []
    phases: list[F64] = []
    for h in cfg.harmonics:
        w = 2.0 * math.pi * h.frequency
        freqs.append(h.frequency)
        amps.append(np.concatenate([np.asarray(h.accel) / (w * w), np.asarray(h.gyro) / w]))
        phases.append(np.full(6, float(h.phase)))
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 0x56494252]))
    for b in cfg.broadband:
        lo, hi = b.band
        n = b.components
        f = lo + (np.arange(n) + rng.random(n)) * (hi - lo) / n  # one per stratum
        wb = 2.0 * math.pi * f[:, None]
        scale = math.sqrt(2.0 / n)  # n sinusoids of amplitude A have RMS A sqrt(n / 2)
        acc = scale * np.asarray(b.accel_rms)[None, :] / (wb * wb)
        gyr = scale * np.asarray(b.gyro_rms)[None, :] / wb
        freqs.extend(f.tolist())
        amps.extend(np.concatenate([acc, gyr], axis=1))
        phases.extend(rng.uniform(0.0, 2.0 * math.pi, (n, 6)))
    return (
        np.asarray(freqs, float),
        np.asarray(amps, float).reshape(-1, 6),
        np.asarray(phases, float).reshape(-1, 6),
    )


def _envelope(t: F64, T: float, fade: float) -> tuple[F64, F64, F64]:
    """1 until ``T - fade``, a quintic smoothstep down to 0 at ``T`` (C2), 0 after; and its
    first and second derivatives."""
    fade = min(fade, T) if T > 0 else 1.0
    u = np.clip((t - (T - fade)) / fade, 0.0, 1.0)
    e = 1.0 - u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
    de = -30.0 * u * u * (1.0 - u) ** 2 / fade
    dde = -60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (fade * fade)
    inside = (t >= 0.0) & (t < T) & (u < 1.0)  # exactly 0 from T on
    return np.where(inside, e, 0.0), np.where(inside, de, 0.0), np.where(inside, dde, 0.0)


def _axis_rotations(th: F64) -> tuple[F64, F64, F64]:
    """Rx, Ry, Rz (n, 3, 3) of the angles th (n, 3)."""
    n = th.shape[0]
    out = []
    for k in range(3):
        c, s = np.cos(th[:, k]), np.sin(th[:, k])
        R = np.zeros((n, 3, 3))
        i, j = [a for a in range(3) if a != k]
        R[:, k, k] = 1.0
        R[:, i, i] = c
        R[:, j, j] = c
        R[:, i, j] = -s if (k != 1) else s
        R[:, j, i] = s if (k != 1) else -s
        out.append(R)
    return out[0], out[1], out[2]


def _mv(R: F64, v: F64) -> F64:
    """R v, row-wise: (n, 3, 3), (n, 3) -> (n, 3)."""
    return np.asarray(np.einsum("nij,nj->ni", R, v), dtype=np.float64)


def _mtv(R: F64, v: F64) -> F64:
    """R^T v, row-wise."""
    return np.asarray(np.einsum("nji,nj->ni", R, v), dtype=np.float64)


class VibratingTrajectory(Trajectory):
    """``inner`` with the body vibration of ``vibration`` superimposed (module docstring)."""

    def __init__(self, inner: Trajectory, vibration: VibrationConfig) -> None:
        self.inner = inner
        self.vibration = vibration
        self.config: TrajectoryConfig = inner.config
        self.T = inner.T
        self.hold = inner.hold
        self.duration = inner.duration
        self.p_world_goal = inner.p_world_goal
        self.R_world_goal = inner.R_world_goal
        self._f, self._amp, self._phase = vibration_components(vibration)

    # -------------------------------------------------------------- the signal
    def signal(self, t: ArrayLike) -> tuple[F64, F64, F64]:
        """Vibration (n, 6) (displacement m, angles rad) and its first and second time
        derivatives at ``t`` (n,) s, the fade applied."""
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        w = 2.0 * math.pi * self._f  # (K,)
        x = np.empty((tt.size, 6))
        dx, ddx = np.empty_like(x), np.empty_like(x)
        e, de, dde = _envelope(tt, self.T, self.vibration.fade)
        for a in range(0, tt.size, CHUNK):
            sl = slice(a, a + CHUNK)
            arg = tt[sl, None, None] * w[None, :, None] + self._phase[None]  # (n, K, 6)
            sn, cs = np.sin(arg), np.cos(arg)
            s = np.einsum("nkc,kc->nc", sn, self._amp)
            ds = np.einsum("nkc,kc->nc", cs, self._amp * w[:, None])
            dds = -np.einsum("nkc,kc->nc", sn, self._amp * (w * w)[:, None])
            ee, dee, ddee = e[sl, None], de[sl, None], dde[sl, None]
            x[sl] = ee * s
            dx[sl] = dee * s + ee * ds
            ddx[sl] = ddee * s + 2.0 * dee * ds + ee * dds
        return x, dx, ddx

    # -------------------------------------------------------------- protocol
    def state(self, t: ArrayLike) -> State:
        st = self.inner.state(t)
        x, dx, ddx = self.signal(st.t)
        d, dd, ddd = x[:, :3], dx[:, :3], ddx[:, :3]
        th, dth, ddth = x[:, 3:], dx[:, 3:], ddx[:, 3:]
        R, w, al = st.R_world_body, st.omega_body, st.alpha_body
        position = st.position + _mv(R, d)
        velocity = st.velocity + _mv(R, dd + np.cross(w, d))
        acc_b = ddd + np.cross(al, d) + 2.0 * np.cross(w, dd) + np.cross(w, np.cross(w, d))
        acceleration = st.acceleration + _mv(R, acc_b)
        Rx, Ry, Rz = _axis_rotations(th)
        E = Rx @ Ry @ Rz
        e1, e2, e3 = np.eye(3)
        Ry_e1 = _mtv(Ry, np.broadcast_to(e1, d.shape))
        u1 = _mtv(Rz, Ry_e1)
        u2 = _mtv(Rz, np.broadcast_to(e2, d.shape))
        w_E = u1 * dth[:, :1] + u2 * dth[:, 1:2] + e3 * dth[:, 2:3]
        du1 = -dth[:, 2:3] * np.cross(e3, u1) - dth[:, 1:2] * _mtv(Rz, np.cross(e2, Ry_e1))
        du2 = -dth[:, 2:3] * np.cross(e3, u2)
        al_E = u1 * ddth[:, :1] + du1 * dth[:, :1] + u2 * ddth[:, 1:2] + du2 * dth[:, 1:2]
        al_E = al_E + e3 * ddth[:, 2:3]
        Etw = _mtv(E, w)
        omega = Etw + w_E
        alpha = _mtv(E, al) - np.cross(w_E, Etw) + al_E
        R_new = R @ E
        gaps, rates, accels = self._components(
            st, position, velocity, acceleration, E, omega, alpha
        )
        return State(
            t=st.t,
            gaps=gaps,
            rates=rates,
            accels=accels,
            position=position,
            velocity=velocity,
            acceleration=acceleration,
            R_world_body=R_new,
            quat_xyzw=matrix_to_quat_xyzw(R_new),
            omega_body=omega,
            alpha_body=alpha,
        )

    def _components(
        self, st: State, p: F64, v: F64, a: F64, E: F64, omega: F64, alpha: F64
    ) -> tuple[F64, F64, F64]:
        """The 18 components of the vibrated motion in the goal frame F: positions rotated
        into F; ZYX angles of ``Rzyx(rpy) E`` (the inner angles' reference frame), wrapped
        next to the inner angles; Euler rates and accelerations from the body rates."""
        RT = self.R_world_goal
        pos = (p - self.p_world_goal) @ RT
        rpy0 = st.gaps[:, 3:]
        raw = matrix_to_rpy(rpy_to_matrix(rpy0) @ E).reshape(-1, 3)
        rpy = rpy0 + (raw - rpy0 + math.pi) % (2.0 * math.pi) - math.pi
        r, pt = rpy[:, 0], rpy[:, 1]
        sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(pt), np.cos(pt)
        M = np.zeros((rpy.shape[0], 3, 3))  # body rates = M @ Euler rates
        M[:, 0, 0], M[:, 0, 2] = 1.0, -sp
        M[:, 1, 1], M[:, 1, 2] = cr, sr * cp
        M[:, 2, 1], M[:, 2, 2] = -sr, cr * cp
        rpy_dot = np.linalg.solve(M, omega[..., None])[..., 0]
        bias = euler_rates_to_body_acceleration(rpy, rpy_dot, np.zeros_like(rpy))
        rpy_ddot = np.linalg.solve(M, (alpha - bias)[..., None])[..., 0]
        gaps = np.concatenate([pos, rpy], axis=1)
        rates = np.concatenate([v @ RT, rpy_dot], axis=1)
        accels = np.concatenate([a @ RT, rpy_ddot], axis=1)
        return gaps, rates, accels

    def gaps_at(self, t: ArrayLike) -> tuple[F64, F64, F64, F64]:
        st = self.state(t)
        return st.t, st.gaps, st.rates, st.accels

    def table_times(self) -> F64:
        return self.inner.table_times()

    def summary(self) -> dict[str, Any]:
        out = dict(self.inner.summary())
        out["vibration"] = self.vibration.model_dump(mode="json")
        return out

    def warnings(self) -> list[str]:
        return self.inner.warnings()
