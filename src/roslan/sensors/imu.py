"""IMU (``type: imu``): sensor_msgs/Imu from the closed-form kinematics plus Kalibr noise.

Measurement model (docs/design.md §3), for the sensor frame S at lever arm ``r`` (in
base_link B) with rotation ``R_bs`` (both from ``pose``)::

    a_s   = a_w + R_wb (alpha x r + w x (w x r))          # world accel. of the sensor point
    f     = R_ws^T (a_s - g_w),   g_w = (0, 0, -gravity)   # specific force: +g up at rest
    w_s   = R_bs^T w_b                                     # angular velocity in S
    meas  = true + bias_k + sigma_d * n_k,  sigma_d = density * sqrt(rate)
    bias_k = bias_{k-1} + random_walk * sqrt(dt) * n'_k,   bias_0 = turn-on bias

(Kalibr / RotorS discrete-time convention). Each noise process has its own random
stream (``ctx.rng('<name>/...')``), so outputs do not depend on the chunking.

Outputs: the ``topic`` (sensor_msgs/Imu in ``frame_id``), ``imu.txt`` (Event Camera
Dataset layout ``t ax ay az gx gy gz``, seconds since the trajectory start), and
``calib/imu.yaml`` (Kalibr IMU file). A second IMU writes ``imu_<name>.txt`` and
``calib/imu_<name>.yaml``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import IO, Annotated, Any, ClassVar, Literal

import numpy as np
import yaml
from numpy.typing import NDArray
from pydantic import Field

from roslan.config.base import FiniteFloat, Vec3
from roslan.frames import matrix_to_quat_xyzw
from roslan.io.messages import MessageStore
from roslan.io.packing import FixedLayout, Leaf, PackedBatch
from roslan.io.text import write_columns
from roslan.limits import MAX_RATE_HZ
from roslan.sensors.base import (
    Message,
    SensorConfig,
    SimContext,
    StaticTransform,
    TopicSpec,
    paced,
    sample_times_ns,
)
from roslan.sensors.measurements import ImuSamples

__all__ = ["GRAVITY", "Imu", "ImuConfig", "imu_measurements"]

GRAVITY = 9.81
"""Default gravity magnitude, m/s^2 (Kalibr/RotorS/ESIM value)."""

F64 = NDArray[np.float64]
NonNegative = Annotated[FiniteFloat, Field(ge=0)]
CHUNK_S = 1.0
"""Trajectory seconds of samples computed per vectorized step (bounds memory)."""


class ImuConfig(SensorConfig):
    """``type: imu``. Noise: Kalibr's continuous-time densities; defaults are ESIM's."""

    type: Literal["imu"] = "imu"
    needs_scene: ClassVar[bool] = False
    rate: Annotated[FiniteFloat, Field(gt=0, le=MAX_RATE_HZ)] = 1000.0
    accelerometer_noise_density: NonNegative = 1.86e-3
    """m/s^2/sqrt(Hz)."""
    accelerometer_random_walk: NonNegative = 4.33e-4
    """m/s^3/sqrt(Hz)."""
    gyroscope_noise_density: NonNegative = 1.86e-4
    """rad/s/sqrt(Hz)."""
    gyroscope_random_walk: NonNegative = 2.66e-5
    """rad/s^2/sqrt(Hz)."""
    accelerometer_bias: Vec3 = (0.0, 0.0, 0.0)
    """Initial accelerometer bias, m/s^2 (added to the turn-on draw)."""
    gyroscope_bias: Vec3 = (0.0, 0.0, 0.0)
    """Initial gyroscope bias, rad/s."""
    accelerometer_turn_on_bias_sigma: NonNegative = 0.0
    """Std of a random turn-on accelerometer bias per axis, m/s^2 (0: none)."""
    gyroscope_turn_on_bias_sigma: NonNegative = 0.0
    """Std of a random turn-on gyroscope bias per axis, rad/s (0: none)."""
    gravity: Annotated[FiniteFloat, Field(gt=0)] = GRAVITY
    orientation: bool = False
    """Publish the exact orientation of the sensor frame in ``world`` (else covariance[0] = -1)."""


def imu_measurements(
    trajectory: Any, t_ns: NDArray[np.int64], T_bs: F64, gravity: float = GRAVITY
) -> tuple[F64, F64, F64]:
    """Noise-free IMU readings at instants ``t_ns``.

    Args:
        trajectory: a :class:`~roslan.trajectory.Trajectory`.
        t_ns: (N,) int64 trajectory times.
        T_bs: (4, 4) sensor pose in base_link.
        gravity: m/s^2.
    Returns:
        specific force (N, 3) m/s^2 and angular velocity (N, 3) rad/s, both in the
        sensor frame, and R_world_sensor (N, 3, 3).
    """
    st = trajectory.state_ns(t_ns)
    R_bs = T_bs[:3, :3]
    r = T_bs[:3, 3]
    w, al = st.omega_body, st.alpha_body
    lever_b = np.cross(al, r) + np.cross(w, np.cross(w, r))
    a_s = st.acceleration + np.einsum("nij,nj->ni", st.R_world_body, lever_b)
    R_ws = st.R_world_body @ R_bs
    g_w = np.array([0.0, 0.0, -gravity])
    f = np.einsum("nji,nj->ni", R_ws, a_s - g_w)
    gyro = w @ R_bs  # R_bs^T w, row-wise
    return f, gyro, R_ws


class Imu:
    """Simulated IMU; see the module docstring for the model."""

    def __init__(self, config: ImuConfig) -> None:
        self.config = config
        self._layouts: dict[str, FixedLayout] = {}
        self._fh: IO[str] | None = None
        self._bias: tuple[F64, F64] | None = None

    # ------------------------------------------------------------------ interface
    def topics(self) -> list[TopicSpec]:
        return [TopicSpec(self.config.topic, "sensor_msgs/msg/Imu")]

    def static_transforms(self) -> list[StaticTransform]:
        return []  # base_link -> frame comes from the extrinsics (pipeline)

    def _file_stem(self, ctx: SimContext) -> str:
        return "imu" if ctx.root_imu in (None, self.config.name) else f"imu_{self.config.name}"

    @property
    def sigmas(self) -> tuple[float, float]:
        """Discrete white-noise std of (accelerometer m/s^2, gyroscope rad/s)."""
        c = self.config
        s = math.sqrt(c.rate)
        return c.accelerometer_noise_density * s, c.gyroscope_noise_density * s

    def messages(self, ctx: SimContext) -> Iterator[Message]:
        c = self.config
        T_bs = c.pose.matrix()
        rate = c.rate
        grid = ctx.clock.grid(lambda end: sample_times_ns(rate, end))
        per_chunk = max(1, round(c.rate * CHUNK_S))
        sig_a, sig_g = self.sigmas
        dt = 1.0 / c.rate
        rw_a = c.accelerometer_random_walk * math.sqrt(dt)
        rw_g = c.gyroscope_random_walk * math.sqrt(dt)
        rng = {
            k: ctx.rng(f"{c.name}/{k}")
            for k in ("acc_noise", "gyro_noise", "acc_walk", "gyro_walk", "turn_on")
        }
        b_a = np.asarray(
            c.accelerometer_bias, dtype=float
        ) + c.accelerometer_turn_on_bias_sigma * rng["turn_on"].standard_normal(3)
        b_g = np.asarray(c.gyroscope_bias, dtype=float) + c.gyroscope_turn_on_bias_sigma * rng[
            "turn_on"
        ].standard_normal(3)
        self._bias = (b_a.copy(), b_g.copy())
        fh = None
        if ctx.files is not None:  # (no file sink: a run that records nothing)
            fh = ctx.files.path(self._file_stem(ctx) + ".txt").open(
                "w", encoding="utf-8", newline="\n"
            )
        self._fh = fh
        last = [-1]
        # a chunk of ``per_chunk`` samples may come in pieces (closed loop: up to each
        # step's end); the bias walk sums are carried over so that every value is the
        # one of the whole chunk: b_chunk + cumsum(steps), accumulated left to right
        walk = [b_a, b_g]  # the bias at the start of the current chunk
        carry: list[F64 | None] = [None, None]  # the chunk's running sums so far
        end_bias = [b_a, b_g]
        try:
            # t ax ay az gx gy gz (s since trajectory start; m/s^2, rad/s; IMU frame); the
            # Event Camera Dataset's imu.txt has no header line (columns in OUTDIR/README.md)
            for item in paced(grid, per_chunk, lambda: last[0] + 1):
                if isinstance(item, Message):
                    yield item  # wait for the horizon
                    continue
                i0, t = item
                n = t.size
                last[0] = int(t[-1])
                if i0 % per_chunk == 0:
                    walk, carry = list(end_bias), [None, None]
                f, g, R_ws = imu_measurements(ctx.trajectory, t, T_bs, c.gravity)
                steps = (
                    rw_a * rng["acc_walk"].standard_normal((n, 3)),
                    rw_g * rng["gyro_walk"].standard_normal((n, 3)),
                )
                walks = []
                for k in range(2):
                    st = steps[k]
                    if carry[k] is not None:
                        st[0] += carry[k]
                    sums = np.cumsum(st, axis=0)
                    carry[k] = sums[-1].copy()
                    walks.append(walk[k] + sums)
                end_bias = [walks[0][-1].copy(), walks[1][-1].copy()]
                acc = f + walks[0] + sig_a * rng["acc_noise"].standard_normal((n, 3))
                gyro = g + walks[1] + sig_g * rng["gyro_noise"].standard_normal((n, 3))
                if fh is not None:
                    write_columns(fh, t, *acc.T, *gyro.T)
                ctx.clock.tap(c.name, ImuSamples(t, acc, gyro))
                yield from self._chunk_messages(ctx, t, i0, acc, gyro, R_ws)
        finally:
            if fh is not None:
                fh.close()

    def _chunk_messages(
        self, ctx: SimContext, t: NDArray[np.int64], i0: int, acc: F64, gyro: F64, R_ws: F64
    ) -> Iterator[Message]:
        n = t.size
        sec, nsec = np.divmod(ctx.start_time_ns + t, 1_000_000_000)
        q = matrix_to_quat_xyzw(R_ws) if self.config.orientation else None

        def pack(store: MessageStore) -> NDArray[np.uint8]:
            cols: dict[str, Any] = {"header.stamp.sec": sec, "header.stamp.nanosec": nsec}
            if store.is_ros1:
                cols["header.seq"] = np.arange(i0, i0 + n)
            for i, a in enumerate("xyz"):
                cols[f"linear_acceleration.{a}"] = acc[:, i]
                cols[f"angular_velocity.{a}"] = gyro[:, i]
            if q is not None:
                for i, a in enumerate("xyzw"):
                    cols[f"orientation.{a}"] = q[:, i]
            return self._layout(store).pack(cols, n)

        batch = PackedBatch(pack)
        topic = self.config.topic
        for i, ti in enumerate(t.tolist()):
            yield Message(ti, topic, "sensor_msgs/msg/Imu", batch.build(i))

    def _layout(self, store: MessageStore) -> FixedLayout:
        key = store.flavor.value
        if key not in self._layouts:
            self._layouts[key] = FixedLayout(
                store, "sensor_msgs/msg/Imu", self.template(store), self._leaves(store)
            )
        return self._layouts[key]

    def _leaves(self, store: MessageStore) -> list[Leaf]:
        leaves: list[Leaf] = [("header.stamp.sec", "<u4", 1), ("header.stamp.nanosec", "<u4", 1)]
        if store.is_ros1:
            leaves.append(("header.seq", "<u4", 1))
        leaves += [(f"linear_acceleration.{a}", "<f8", 1) for a in "xyz"]
        leaves += [(f"angular_velocity.{a}", "<f8", 1) for a in "xyz"]
        if self.config.orientation:
            leaves += [(f"orientation.{a}", "<f8", 1) for a in "xyzw"]
        return leaves

    def covariances(self) -> tuple[F64, F64, F64]:
        """Row-major 3x3 covariances (9,) of orientation, angular velocity, linear acceleration."""
        sig_a, sig_g = self.sigmas
        orient = np.zeros(9)
        if not self.config.orientation:
            orient[0] = -1.0  # REP 145 / sensor_msgs: orientation not provided
        return orient, (np.eye(3) * sig_g**2).ravel(), (np.eye(3) * sig_a**2).ravel()

    def template(self, store: MessageStore) -> Any:
        """An Imu message with this sensor's constant fields (frame, covariances)."""
        orient, cov_g, cov_a = self.covariances()
        V = store.types["geometry_msgs/msg/Vector3"]
        Q = store.types["geometry_msgs/msg/Quaternion"]
        return store.new(
            "sensor_msgs/msg/Imu",
            header=store.header(0, self.config.frame),
            orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=orient,
            angular_velocity=V(x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=cov_g,
            linear_acceleration=V(x=0.0, y=0.0, z=0.0),
            linear_acceleration_covariance=cov_a,
        )

    def kalibr(self) -> dict[str, Any]:
        """Kalibr ``imu.yaml`` content (noise densities, random walks, rate, topic)."""
        c = self.config
        return {
            "rostopic": c.topic,
            "update_rate": float(c.rate),
            "accelerometer_noise_density": float(c.accelerometer_noise_density),
            "accelerometer_random_walk": float(c.accelerometer_random_walk),
            "gyroscope_noise_density": float(c.gyroscope_noise_density),
            "gyroscope_random_walk": float(c.gyroscope_random_walk),
            "T_i_b": np.linalg.inv(c.pose.matrix()).tolist(),
        }

    def close(self, ctx: SimContext) -> None:
        if self._fh is not None and not self._fh.closed:
            self._fh.close()
        if ctx.files is None:
            return
        path = ctx.files.path(f"calib/{self._file_stem(ctx)}.yaml")
        with path.open("w", encoding="utf-8") as fh:
            fh.write(
                f"# Kalibr IMU configuration of sensor '{self.config.name}' (written by roslan)\n"
            )
            yaml.safe_dump(self.kalibr(), fh, sort_keys=False, default_flow_style=None)
