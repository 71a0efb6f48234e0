"""Time to contact from events: the divergence of the flow field by contrast maximisation.

A downward-looking event camera descending onto a plane sees the ground expand. Over a
short window a camera moving with velocity ``T`` (optical frame: z forward, x right, y
down) over a plane at distance ``d`` whose unit normal, seen from the camera, is ``n``
(pointing from the camera to the plane: ``n = (0, 0, 1)`` looking straight down) sees the
point of normalised image coordinates ``p = (x, y, 1)``, ``x = (u - cx) / fx``, ``y = (v -
cy) / fy``, at inverse depth ``(n . p) / d`` and moving with

    dx/dt = (n . p) (-ux + uz x),    dy/dt = (n . p) (-uy + uz y),    (ux, uy, uz) = T / d

plus the rotational flow of the camera's angular velocity, which does not depend on depth
and is removed with the gyroscope (each event's bearing is rotated back to the window's
reference time). The plane's divergence rate is ``D = n . T / d`` (1/s, > 0 while
approaching) and ``tau = -1 / D`` the time to contact of the camera with the plane
(``d`` over the closing speed along the normal), negative while approaching
(``docs/design.md`` §1: ``tau = z / vz``). The normal is the caller's: ``update``'s
``normal`` argument, the plane's unit normal in the camera's optical frame (``tau-events``
passes the world's down direction rotated by its attitude estimate, a gyro and
accelerometer filter); without it the camera is assumed to look along the normal, and a
tilt ``a`` with a sideways speed ``V`` then biases ``D`` by about ``1.5 V sin(a) / d``.

The three parameters ``(ux, uy, uz)`` are found by contrast maximisation (Gallego, Rebecq,
Scaramuzza, "A Unifying Contrast Maximization Framework for Event Cameras, with
Applications to Motion, Depth, and Optical Flow Estimation", CVPR 2018): events are warped
to the reference time along the flow model, accumulated (bilinear voting) into an image of
warped events (IWE), and the parameters maximise the IWE's variance after a Gaussian blur.
The objective's gradient is analytic (the blurred IWE's gradient sampled at the warped
events), and a gradient ascent (steps of at most one IWE pixel of motion, doubled after a
success and shrunk after a failure) runs coarse (quarter resolution) then fine (half
resolution), warm-started from the previous window. The window adapts to the expansion
rate: ``window_gain * |tau|`` (clipped), so that the ground expands by about the same few
pixels in every window, and at most ``max_events`` events (an even stride over the window)
enter the objective: the cost of one estimate is bounded whatever the event rate.

Assumptions: pinhole pixel coordinates (undistort a distorted camera's events first, as
the ``tau-events`` policy does), a textured ground plane filling most of
the view, a camera looking roughly along the plane's normal (the divergence of a tilted
plane is the average over the view), a flow field that is constant over the window.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np
import numpy.typing as npt

__all__ = ["DivergenceEstimate", "DivergenceEstimator", "DivergenceParams"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class DivergenceParams:
    """Tuning of :class:`DivergenceEstimator` (times in s).

    ``window_gain``: window length as a fraction of ``|tau|`` (the ground expands by about
    this fraction over a window); ``min_window`` / ``max_window`` clip it; ``max_events``
    caps the events per estimate (an even stride); ``min_events`` below which no estimate is
    made; ``sigma``: blur of the IWE in IWE pixels; ``max_divergence``: bound of ``D`` (1/s)
    in the search; ``levels``: IWE down-sampling factors, coarse to fine (default: ``(2 n,
    n)``, ``n = max(1, width // 120)``: ``(4, 2)`` for a DAVIS346); ``max_iterations``:
    objective evaluations per level; ``trust_px``: largest motion of an event (IWE pixels)
    per ascent step; ``search_px``: the first window's translation search range (sensor
    pixels at the window's ends).
    """

    window_gain: float = 0.03
    min_window: float = 0.02
    max_window: float = 0.1
    max_events: int = 8000
    min_events: int = 500
    sigma: float = 1.0
    max_divergence: float = 50.0
    levels: tuple[int, ...] | None = None
    max_iterations: int = 8
    trust_px: float = 1.0
    search_px: float = 24.0


@dataclass(frozen=True)
class DivergenceEstimate:
    """One estimate, at reference time ``t_ns`` (the middle of the window used).

    ``divergence``: ``D = Tz / Z`` (1/s, > 0 while approaching); ``tau``: ``-1 / D`` (s,
    negative while approaching; ``-inf`` when ``D <= 0``); ``confidence`` in [0, 1]: the
    share of the warped IWE's variance explained by the motion (0 = the motion does not
    sharpen the events at all); ``translation``: ``(ux, uy)`` (1/s); ``n_events``: events
    used; ``window``: s.
    """

    t_ns: int
    divergence: float
    tau: float
    confidence: float
    translation: tuple[float, float]
    n_events: int
    window: float


class DivergenceEstimator:
    """Estimate the divergence (and tau) of the ground from a stream of events.

    ``width``, ``height``: sensor pixels; ``fx, fy, cx, cy``: pinhole intrinsics (px);
    ``R_cam_imu``: (3, 3) rotation from the IMU frame to the camera's optical frame (gyro
    samples are given in the IMU frame); identity when None.

    Feed each control step with :meth:`update` (events of the step, time-sorted, and the
    step's gyro samples); it returns the estimate at the end of the step's data, or None
    while there are too few events. Deterministic: the same inputs give the same outputs.
    """

    def __init__(
        self,
        width: int,
        height: int,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        *,
        R_cam_imu: npt.ArrayLike | None = None,
        params: DivergenceParams | None = None,
    ) -> None:
        self.width, self.height = int(width), int(height)
        self.fx, self.fy, self.cx, self.cy = float(fx), float(fy), float(cx), float(cy)
        rot = np.eye(3) if R_cam_imu is None else np.asarray(R_cam_imu, dtype=np.float64)
        if rot.shape != (3, 3):
            msg = f"R_cam_imu must have shape (3, 3), got {rot.shape}"
            raise ValueError(msg)
        self.R_cam_imu = rot
        self.params = params or DivergenceParams()
        fine = max(1, self.width // 120)
        self.levels = self.params.levels or (2 * fine, fine)
        self._events: deque[tuple[npt.NDArray[np.int64], FloatArray, FloatArray]] = deque()
        self._gyro_t: deque[npt.NDArray[np.int64]] = deque()
        self._gyro: deque[FloatArray] = deque()
        self._theta: FloatArray | None = None
        self._tau: float | None = None
        self._normal = np.array([0.0, 0.0, 1.0])
        self._first_ns: int | None = None

    # -- input ---------------------------------------------------------------------------
    def update(
        self,
        x: npt.ArrayLike,
        y: npt.ArrayLike,
        t_ns: npt.ArrayLike,
        p: npt.ArrayLike | None = None,
        *,
        gyro_t_ns: npt.ArrayLike | None = None,
        gyro: npt.ArrayLike | None = None,
        end_ns: int | None = None,
        normal: npt.ArrayLike | None = None,
    ) -> DivergenceEstimate | None:
        """Add one step's events (pixel ``x, y``; times ``t_ns`` int ns, sorted; polarity
        ``p`` is accepted and unused: both polarities vote) and gyro samples (``gyro_t_ns``
        (N,), ``gyro`` (N, 3) rad/s in the IMU frame), then estimate over the window that
        ends at ``end_ns`` (default: the last event's time). ``normal``: (3,) the ground's
        normal in the camera's optical frame, pointing from the camera to the ground (kept
        until the next one; default ``(0, 0, 1)``)."""
        del p
        if normal is not None:
            n = np.asarray(normal, dtype=np.float64).reshape(3)
            self._normal = n / np.linalg.norm(n)
        t = np.asarray(t_ns, dtype=np.int64).ravel()
        if t.size:
            if self._first_ns is None:
                self._first_ns = int(t[0])
            xn = (np.asarray(x, dtype=np.float64).ravel() - self.cx) / self.fx
            yn = (np.asarray(y, dtype=np.float64).ravel() - self.cy) / self.fy
            self._events.append((t, xn, yn))
        if gyro_t_ns is not None and gyro is not None:
            gt = np.asarray(gyro_t_ns, dtype=np.int64).ravel()
            g = np.asarray(gyro, dtype=np.float64).reshape(-1, 3) @ self.R_cam_imu.T
            if gt.size:
                self._gyro_t.append(gt)
                self._gyro.append(g)
        end = end_ns if end_ns is not None else (int(t[-1]) if t.size else None)
        if end is None:
            return None
        self._drop_before(end - int(self.params.max_window * 1.5e9))
        return self.estimate(end)

    def _drop_before(self, t0: int) -> None:
        while self._events and (self._events[0][0].size == 0 or self._events[0][0][-1] < t0):
            self._events.popleft()
        while self._gyro_t and self._gyro_t[0][-1] < t0:
            self._gyro_t.popleft()
            self._gyro.popleft()

    # -- estimation ----------------------------------------------------------------------
    def window(self) -> float:
        """The next window's length (s) from the last tau."""
        pr = self.params
        if self._tau is None or not np.isfinite(self._tau):
            return pr.max_window
        return float(np.clip(pr.window_gain * abs(self._tau), pr.min_window, pr.max_window))

    def estimate(self, end_ns: int) -> DivergenceEstimate | None:
        """Estimate over the window ending at ``end_ns`` from the buffered data."""
        pr = self.params
        win = self.window()
        t0 = end_ns - round(win * 1e9)
        if not self._events or self._first_ns is None:
            return None
        t = np.concatenate([e[0] for e in self._events])
        t0 = max(t0, int(self._first_ns))  # the stream's start: no window before it
        sel = (t >= t0) & (t <= end_ns)
        n = int(np.count_nonzero(sel))
        if n < pr.min_events:
            return None
        idx = np.flatnonzero(sel)
        if n > pr.max_events:
            idx = idx[np.linspace(0, n - 1, pr.max_events).astype(np.int64)]
        xn = np.concatenate([e[1] for e in self._events])[idx]
        yn = np.concatenate([e[2] for e in self._events])[idx]
        te = t[idx]
        t_ref = (t0 + end_ns) // 2
        dt = (te - t_ref).astype(np.float64) * 1e-9
        xr, yr = self._derotate(xn, yn, te, t_ref)
        s_n = self._normal[0] * xr + self._normal[1] * yr + self._normal[2]
        theta, conf = self._maximise(xr, yr, dt * s_n, win)
        d = float(np.dot(self._normal, theta))
        tau = -1.0 / d if d > 0 else float("-inf")
        self._theta = theta
        if d > 0:
            self._tau = tau
        return DivergenceEstimate(
            t_ns=int(t_ref),
            divergence=d,
            tau=tau,
            confidence=conf,
            translation=(float(theta[0]), float(theta[1])),
            n_events=int(idx.size),
            window=win,
        )

    def _derotate(
        self, xn: FloatArray, yn: FloatArray, te: npt.NDArray[np.int64], t_ref: int
    ) -> tuple[FloatArray, FloatArray]:
        """Rotate each event's bearing to the camera's orientation at ``t_ref`` (small
        angles: the rotation vector integrated from the gyro between the two instants)."""
        if not self._gyro_t:
            return xn, yn
        gt = np.concatenate(list(self._gyro_t))
        g = np.concatenate(list(self._gyro))
        if gt.size < 2:
            phi = np.outer((te - t_ref) * 1e-9, g[0])
        else:
            # cumulative integral of the angular rate (trapezoid) at the gyro's instants
            dts = np.diff(gt) * 1e-9
            cum = np.vstack([np.zeros(3), np.cumsum(0.5 * (g[1:] + g[:-1]) * dts[:, None], axis=0)])
            tq = np.concatenate([te, [t_ref]]).astype(np.float64)
            ang = np.column_stack(
                [np.interp(tq, gt.astype(np.float64), cum[:, i]) for i in range(3)]
            )
            # outside the gyro's span: extrapolate with the nearest rate
            lo, hi = tq < gt[0], tq > gt[-1]
            ang[lo] += np.outer((tq[lo] - gt[0]) * 1e-9, g[0])
            ang[hi] += np.outer((tq[hi] - gt[-1]) * 1e-9, g[-1])
            phi = ang[:-1] - ang[-1]  # rotation from t_ref to each event's time
        # R_ref_t ~ I + [phi]x: a bearing seen at t, expressed in the camera at t_ref
        b = np.column_stack([xn, yn, np.ones_like(xn)])
        br = b + np.cross(phi, b)
        return br[:, 0] / br[:, 2], br[:, 1] / br[:, 2]

    def _maximise(
        self, xr: FloatArray, yr: FloatArray, dt: FloatArray, win: float
    ) -> tuple[FloatArray, float]:
        """Gradient ascent of the IWE's contrast per level, with an adaptive step
        inside a trust region of ``trust_px`` IWE pixels of motion at the window's ends."""
        pr = self.params
        dmax = min(pr.max_divergence, 1.0 / max(win, 1e-3))
        lo = np.array([-20.0, -20.0, -0.5 * dmax])
        hi = np.array([20.0, 20.0, dmax])
        theta = np.zeros(3) if self._theta is None else self._theta.copy()
        theta = np.clip(theta, lo, hi)
        # D moves a pixel by D * x * dt: scale its gradient by the events' radius
        radius = float(np.sqrt(np.mean(xr**2 + yr**2))) + 1e-6
        metric = np.array([1.0, 1.0, radius])
        dt_max = float(np.max(np.abs(dt))) + 1e-6
        iwe = _Iwe(self, xr, yr, dt, self.levels[0])
        if self._theta is None:
            theta = self._search_translation(iwe, dt_max, lo, hi)
        for scale in self.levels:
            iwe = _Iwe(self, xr, yr, dt, scale)
            # a parameter step of `trust` (metric units) moves an event by <= trust_px
            trust = pr.trust_px * scale / (self.fx * dt_max)
            f, g = iwe.objective(theta)
            step = trust
            for _ in range(pr.max_iterations):
                gm = g / metric  # ascent direction in metric units
                norm = float(np.linalg.norm(gm))
                if norm == 0.0:
                    break
                cand = np.clip(theta + (gm / norm) * min(step, trust) / metric, lo, hi)
                fc, gc = iwe.objective(cand)
                if fc > f:
                    moved = float(np.linalg.norm((cand - theta) * metric))
                    theta, f, g = cand, fc, gc
                    step = min(2.0 * moved, trust)
                    if moved < 1e-3 * trust:
                        break
                else:
                    step *= 0.3
                    if step < 1e-3 * trust:
                        break
        v0 = iwe.variance(np.zeros(3))
        v1 = iwe.variance(theta)
        conf = float(np.clip(1.0 - v0 / v1, 0.0, 1.0)) if v1 > 0 else 0.0
        return theta, conf

    def _search_translation(
        self, iwe: _Iwe, dt_max: float, lo: FloatArray, hi: FloatArray
    ) -> FloatArray:
        """First window (no previous motion): the best translation on a grid of motions
        up to ``search_px`` sensor pixels at the window's ends, with no divergence."""
        pr = self.params
        n = int(np.ceil(pr.search_px / self.levels[0]))
        u = np.arange(-n, n + 1) * self.levels[0] / (self.fx * dt_max)
        best, best_v = np.zeros(3), -np.inf
        for ux in u:
            for uy in u:
                cand = np.clip(np.array([ux, uy, 0.0]), lo, hi)
                v = iwe.variance(cand)
                if v > best_v:
                    best, best_v = cand, v
        return best


class _Iwe:
    """The blurred image of warped events at one down-sampling ``scale``, its mean square
    (relative to the squared mean) and its gradient with respect to ``theta = (ux, uy, D)``."""

    def __init__(
        self, est: DivergenceEstimator, xr: FloatArray, yr: FloatArray, dt: FloatArray, scale: int
    ) -> None:
        self.w = int(np.ceil(est.width / scale))
        self.h = int(np.ceil(est.height / scale))
        self.ax, self.ay = est.fx / scale, est.fy / scale
        self.bx, self.by = est.cx / scale, est.cy / scale
        self.xr, self.yr, self.dt = xr, yr, dt
        sigma = est.params.sigma
        self.ksize = 2 * int(np.ceil(3 * sigma)) + 1
        self.sigma = sigma

    def _blur(self, img: FloatArray) -> FloatArray:
        out = cv2.GaussianBlur(
            img, (self.ksize, self.ksize), self.sigma, borderType=cv2.BORDER_CONSTANT
        )
        return np.asarray(out, dtype=np.float64)

    def _warp(self, theta: FloatArray) -> tuple[FloatArray, FloatArray]:
        ux, uy, d = theta
        xw = self.xr - self.dt * (-ux + d * self.xr)
        yw = self.yr - self.dt * (-uy + d * self.yr)
        return xw * self.ax + self.bx, yw * self.ay + self.by

    def _splat(self, px: FloatArray, py: FloatArray) -> _Splat:
        x0 = np.floor(px).astype(np.int64)
        y0 = np.floor(py).astype(np.int64)
        ok = (x0 >= 0) & (y0 >= 0) & (x0 < self.w - 1) & (y0 < self.h - 1)
        x0, y0 = x0[ok], y0[ok]
        fx, fy = px[ok] - x0, py[ok] - y0
        base = y0 * self.w + x0
        size = self.w * self.h
        votes = (
            np.bincount(base, (1 - fx) * (1 - fy), size)
            + np.bincount(base + 1, fx * (1 - fy), size)
            + np.bincount(base + self.w, (1 - fx) * fy, size)
            + np.bincount(base + self.w + 1, fx * fy, size)
        ).reshape(self.h, self.w)
        img: FloatArray = np.asarray(votes, dtype=np.float64)
        return _Splat(img, x0, y0, fx, fy, ok)

    def variance(self, theta: FloatArray) -> float:
        return float(np.var(self._blur(self._splat(*self._warp(theta)).img)))

    def objective(self, theta: FloatArray) -> tuple[float, FloatArray]:
        """``mean(blurred IWE^2) / mean(IWE)^2`` and its gradient."""
        sp = self._splat(*self._warp(theta))
        blurred = self._blur(sp.img)
        m = sp.img.size
        norm = (m / max(int(sp.x0.size), 1)) ** 2
        f = float(np.sum(blurred**2)) / m * norm
        # d f / d (event position): 2/m * gradient of the bilinear interpolant of G*G*I
        j = self._blur(blurred)
        x0, y0, fx, fy = sp.x0, sp.y0, sp.fx, sp.fy
        j00, j10 = j[y0, x0], j[y0, x0 + 1]
        j01, j11 = j[y0 + 1, x0], j[y0 + 1, x0 + 1]
        gx = ((j10 - j00) * (1 - fy) + (j11 - j01) * fy) * self.ax
        gy = ((j01 - j00) * (1 - fx) + (j11 - j10) * fx) * self.ay
        dt, xr, yr = self.dt[sp.ok], self.xr[sp.ok], self.yr[sp.ok]
        # x_pix = ax * (xr - dt * (-ux + D xr)) + bx
        grad = np.array(
            [np.dot(gx, dt), np.dot(gy, dt), -np.dot(gx * xr + gy * yr, dt)]
        ) * (2.0 * norm / m)  # fmt: skip
        return f, grad


class _Splat(NamedTuple):
    """Bilinear votes: the image and, per event inside it, its cell and fractions."""

    img: FloatArray
    x0: npt.NDArray[np.int64]
    y0: npt.NDArray[np.int64]
    fx: FloatArray
    fy: FloatArray
    ok: npt.NDArray[np.bool_]
