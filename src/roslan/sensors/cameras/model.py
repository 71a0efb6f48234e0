"""Camera intrinsics and lens distortion.

:class:`CameraModel` is the pinhole ``K`` plus a distortion model in OpenCV's
conventions (pixel centres at integer coordinates):

* ``plumb_bob`` (ROS name; Kalibr calls it ``radtan``): ``k1 k2 p1 p2 [k3]``,
  ``cv2.projectPoints``;
* ``equidistant`` (fisheye): ``k1 k2 k3 k4``, ``cv2.fisheye.projectPoints``;
* ``none``: an ideal pinhole.

Distortion is applied exactly: :meth:`CameraModel.render_plan` inverts the lens
model for every output pixel (Newton iterations to 1e-12, verified by projecting
back with OpenCV), sizes a larger virtual pinhole image that contains every
undistorted ray (plus interpolation margin) and precomputes ``cv2.remap`` maps,
once per camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import SensorError
from roslan.frames import T_LINK_OPTICAL

if TYPE_CHECKING:
    from roslan.io.messages import MessageStore
    from roslan.sensors.base import SimContext

__all__ = [
    "DEFAULT_HFOV_DEG",
    "DEFAULT_RESOLUTION",
    "DISTORTION_MODELS",
    "RENDER_PIXELS_PER_OUTPUT",
    "T_LINK_OPTICAL",
    "CameraModel",
    "RenderPlan",
    "auto_render_scale",
    "pose_matrices",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

DISTORTION_MODELS = ("plumb_bob", "radtan", "equidistant", "fisheye", "none")
"""Accepted names; ``radtan`` = ``plumb_bob``, ``fisheye`` = ``equidistant``."""
_CANONICAL = {
    "plumb_bob": "plumb_bob",
    "radtan": "plumb_bob",
    "equidistant": "equidistant",
    "fisheye": "equidistant",
    "none": "none",
}
_N_COEFFS = {"plumb_bob": (4, 5), "equidistant": (4,), "none": (0,)}
_KALIBR_NAME = {"plumb_bob": "radtan", "equidistant": "equidistant", "none": "none"}


DEFAULT_RESOLUTION = (640, 480)
DEFAULT_HFOV_DEG = 90.0


RENDER_PIXELS_PER_OUTPUT = 1.0
"""Default pixel budget of a distorted camera's virtual pinhole render, in output pixels
(see :meth:`CameraModel.render_plan`)."""


def auto_render_scale(xy: F64, K: F64, n_out: int) -> float:
    """Focal-length scale of the virtual pinhole render: the largest ``s <= 1`` whose
    render (bounding box of the undistorted rays ``xy``, (N, 2) normalized, at focal
    lengths ``s * K``'s) has at most :data:`RENDER_PIXELS_PER_OUTPUT` * ``n_out``
    pixels. Rounded down to 1/64 so that nearby lenses share a value."""
    px = K[0, 0] * xy[:, 0] + K[0, 1] * xy[:, 1]
    py = K[1, 1] * xy[:, 1]
    area = float(np.ptp(px)) * float(np.ptp(py))  # render pixels at scale 1
    if area <= 0.0:
        return 1.0
    s = math.sqrt(RENDER_PIXELS_PER_OUTPUT * n_out / area)
    return min(1.0, math.floor(s * 64.0) / 64.0)


@dataclass(frozen=True)
class RenderPlan:
    """How to render a (distorted) camera: a virtual pinhole view, then a remap.

    Attributes:
        K: (3, 3) virtual pinhole intrinsics to render with.
        width, height: virtual image size (pixels).
        map1, map2: ``cv2.remap`` maps (fixed-point ``CV_16SC2`` + ``CV_16UC1``) from
            the output image into the virtual image, or None for an ideal pinhole (no
            remap needed: the virtual view is the output).
        mapx, mapy: the same maps as (H, W) float32 virtual pixel coordinates.
    """

    K: F64
    width: int
    height: int
    map1: Any = None
    map2: Any = None
    mapx: Any = None
    mapy: Any = None

    @property
    def identity(self) -> bool:
        return self.map1 is None


@dataclass(frozen=True, eq=False)
class CameraModel:
    """A calibrated camera.

    Attributes:
        width, height: image size (pixels).
        K: (3, 3) float64 camera matrix (fx, fy, cx, cy; OpenCV convention).
        D: (n,) float64 distortion coefficients of ``distortion_model``.
        distortion_model: ``plumb_bob`` (k1 k2 p1 p2 k3), ``equidistant`` (k1..k4) or ``none``.
        name: camera name (written to the calibration files).
        source: where it came from (file name or ``config``), for error messages.
    """

    width: int
    height: int
    K: F64
    D: F64 = field(default_factory=lambda: np.zeros(0))
    distortion_model: str = "none"
    name: str = "camera"
    source: str = "config"

    # ---------------------------------------------------------------- construct
    @classmethod
    def create(
        cls,
        width: int,
        height: int,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        distortion_model: str = "none",
        coeffs: Any = (),
        *,
        name: str = "camera",
        source: str = "config",
        keys: dict[str, str] | None = None,
    ) -> CameraModel:
        """Validated model. ``keys`` maps the parameter names (``fx``, ``cx``,
        ``distortion_model``, ``distortion_coeffs``, ``resolution``) to the key paths
        used in error messages (``camera_matrix.data[0]``...).

        Raises:
            SensorError: naming ``source``, the key, the value and what is allowed.
        """
        k = {
            "fx": "fx",
            "fy": "fy",
            "cx": "cx",
            "cy": "cy",
            "distortion_model": "distortion_model",
            "distortion_coeffs": "distortion_coeffs",
            "resolution": "resolution",
            **(keys or {}),
        }

        def bad(key: str, value: Any, allowed: str) -> SensorError:
            if isinstance(value, np.generic):
                value = value.item()
            return SensorError(f"{source}: {k[key]} = {value!r}: {allowed}")

        for n in (width, height):
            if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
                raise bad(
                    "resolution", [width, height], "must be two positive integers [width, height]"
                )
        from roslan.limits import MAX_FRAME_PIXELS

        if int(width) * int(height) > MAX_FRAME_PIXELS:
            raise bad(
                "resolution",
                [int(width), int(height)],
                f"at most {MAX_FRAME_PIXELS} pixels (e.g. 8192x8192)",
            )
        values = {"fx": fx, "fy": fy, "cx": cx, "cy": cy}
        for key, v in values.items():
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float, np.number))
                or not math.isfinite(v)
            ):
                raise bad(key, v, "must be a finite number")
        if fx <= 0:
            raise bad("fx", fx, "focal length must be > 0 (pixels)")
        if fy <= 0:
            raise bad("fy", fy, "focal length must be > 0 (pixels)")
        if not 0 <= cx <= width - 1:
            raise bad(
                "cx", cx, f"principal point must lie inside the image: 0 <= cx <= {width - 1}"
            )
        if not 0 <= cy <= height - 1:
            raise bad(
                "cy", cy, f"principal point must lie inside the image: 0 <= cy <= {height - 1}"
            )
        if not isinstance(distortion_model, str) or distortion_model not in _CANONICAL:
            raise bad(
                "distortion_model", distortion_model, f"allowed: {', '.join(DISTORTION_MODELS)}"
            )
        model = _CANONICAL[distortion_model]
        try:
            D = np.asarray(coeffs if coeffs is not None else (), dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise bad("distortion_coeffs", coeffs, "must be a list of numbers") from None
        if model == "none" and D.size and np.all(D == 0):
            D = np.zeros(0)
        allowed_n = _N_COEFFS[model]
        if D.size not in allowed_n:
            names = {
                "plumb_bob": "k1 k2 p1 p2 [k3]",
                "equidistant": "k1 k2 k3 k4",
                "none": "none (empty list)",
            }[model]
            raise bad(
                "distortion_coeffs",
                D.tolist(),
                f"{distortion_model} needs {' or '.join(map(str, allowed_n))} coefficients "
                f"({names}), got {D.size}",
            )
        if not np.all(np.isfinite(D)):
            raise bad("distortion_coeffs", D.tolist(), "must be finite numbers")
        if model == "plumb_bob" and D.size == 4:
            D = np.append(D, 0.0)
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)
        return cls(int(width), int(height), K, D, model, name, source)

    # ---------------------------------------------------------------- geometry
    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    @property
    def is_pinhole(self) -> bool:
        return self.distortion_model == "none" or not np.any(self.D)

    @property
    def D_opencv(self) -> F64:
        """Coefficients as OpenCV wants them (plumb_bob: 5, equidistant: 4, none: 0)."""
        return self.D.copy()

    def distort_normalized(self, xy: F64) -> F64:
        """Lens model on normalized pinhole coordinates (N, 2) -> distorted normalized (N, 2)."""
        x, y = xy[:, 0], xy[:, 1]
        if self.distortion_model == "plumb_bob":
            k1, k2, p1, p2, k3 = self.D
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
            return np.stack([xd, yd], axis=1)
        if self.distortion_model == "equidistant":
            k1, k2, k3, k4 = self.D
            r = np.hypot(x, y)
            th = np.arctan(r)
            t2 = th * th
            thd = th * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
            scale = np.where(r > 1e-12, thd / np.maximum(r, 1e-300), 1.0)
            return xy * scale[:, None]
        return xy.copy()

    def project(self, points_cam: F64) -> F64:
        """Pixels (N, 2) of optical-frame points (N, 3) (z > 0), OpenCV conventions."""
        p = np.asarray(points_cam, dtype=np.float64)
        xy = p[:, :2] / p[:, 2:3]
        d = self.distort_normalized(xy)
        return np.stack(
            [self.fx * d[:, 0] + self.K[0, 1] * d[:, 1] + self.cx, self.fy * d[:, 1] + self.cy], 1
        )

    def undistort_normalized(self, uv: F64) -> F64:
        """Exact inverse of the lens model: pixels (N, 2) -> normalized pinhole (N, 2)."""
        uv = np.asarray(uv, dtype=np.float64)
        yd = (uv[:, 1] - self.cy) / self.fy
        xd = (uv[:, 0] - self.cx - self.K[0, 1] * yd) / self.fx
        target = np.stack([xd, yd], axis=1)
        if self.is_pinhole:
            return target
        # Newton per point, 30 steps at most; a point whose step is exactly zero has reached
        # its fixed point (the same step forever), so it leaves the active set: the result
        # is what 30 full steps give, at the cost of the few steps that converge (~5)
        if self.distortion_model == "equidistant":
            k1, k2, k3, k4 = self.D
            thd = np.hypot(xd, yd)
            th = thd.copy()
            act = np.arange(th.shape[0])
            for _ in range(30):
                t = th[act]
                t2 = t * t
                f = t * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - thd[act]
                df = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
                new = t - f / np.where(np.abs(df) > 1e-12, df, 1e-12)
                moved = new != t
                th[act] = new
                act = act[moved]
                if act.size == 0:
                    break
            th = np.clip(th, 0.0, math.pi / 2 - 1e-6)
            scale = np.where(thd > 1e-12, np.tan(th) / np.maximum(thd, 1e-300), 1.0)
            return target * scale[:, None]
        # plumb_bob: Newton on the 2-D map, analytic Jacobian
        k1, k2, p1, p2, k3 = self.D
        xy = target.copy()
        act = np.arange(xy.shape[0])
        for _ in range(30):
            x, y = xy[act, 0], xy[act, 1]
            tx, ty = target[act, 0], target[act, 1]
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            drad = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d(radial)/d(r2)
            fx_ = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - tx
            fy_ = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - ty
            j11 = radial + 2 * x * x * drad + 2 * p1 * y + 6 * p2 * x
            j12 = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y
            j21 = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y
            j22 = radial + 2 * y * y * drad + 6 * p1 * y + 2 * p2 * x
            det = j11 * j22 - j12 * j21
            det = np.where(np.abs(det) > 1e-12, det, 1e-12)
            nx = x - (j22 * fx_ - j12 * fy_) / det
            ny = y - (-j21 * fx_ + j11 * fy_) / det
            moved = (nx != x) | (ny != y)
            xy[act, 0] = nx
            xy[act, 1] = ny
            act = act[moved]
            if act.size == 0:
                break
        return xy

    def render_plan(
        self, max_size: int | None = None, *, margin: int = 2, scale: float | None = None
    ) -> RenderPlan:
        """Virtual pinhole view covering every output pixel's ray, and remap maps.

        The virtual camera has focal lengths ``scale * (fx, fy)``; its size is the
        bounding box of all undistorted pixel rays plus ``margin`` pixels for bilinear
        interpolation. The maps are exact at any scale (geometry does not depend on
        it); the scale sets the sampling density. ``scale=1`` keeps the output's
        density at the image centre everywhere, which over-samples the periphery that a
        barrel lens compresses (640x480 with k1 = -0.2 needs an 805x605 render, 1.59x
        the pixels). ``None`` (default): :func:`auto_render_scale`, the largest scale
        <= 1 whose render has no more pixels than :data:`RENDER_PIXELS_PER_OUTPUT`
        times the output (0.8 for that lens: 645x485, the centre magnified 1.25x by
        the remap; docs/performance.md has the time and PSNR of each choice).

        Raises SensorError if the rays cannot be covered (field of view >= 180 deg, a
        non-invertible lens) or the virtual image exceeds ``max_size``.
        """
        if self.is_pinhole:
            if max_size is not None and max(self.width, self.height) > max_size:
                raise self._too_big(self.width, self.height, max_size)
            return RenderPlan(self.K.copy(), self.width, self.height)
        import cv2

        u, v = np.meshgrid(
            np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64)
        )
        uv = np.stack([u.ravel(), v.ravel()], axis=1)
        xy = self.undistort_normalized(uv)
        back = self.project(np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1))
        err = np.abs(back - uv).max(axis=1)
        if not np.all(np.isfinite(xy)) or float(err.max()) > 1e-3:
            bad = int(np.argmax(err))
            msg = (
                f"{self.source}: distortion_coeffs = {self.D.tolist()}: the "
                f"{self.distortion_model} lens model cannot be inverted at pixel "
                f"({uv[bad, 0]:.0f}, {uv[bad, 1]:.0f}) "
                "(field of view too wide or coefficients not monotonic)"
            )
            raise SensorError(msg)
        if scale is None:
            scale = auto_render_scale(xy, self.K, self.width * self.height)
        fx, fy = scale * self.fx, scale * self.fy
        s = scale * self.K[0, 1]
        # virtual pixel coordinates before choosing the principal point
        px = fx * xy[:, 0] + s * xy[:, 1]
        py = fy * xy[:, 1]
        x0 = math.floor(float(px.min())) - margin
        y0 = math.floor(float(py.min())) - margin
        W = math.ceil(float(px.max())) + margin - x0 + 1
        H = math.ceil(float(py.max())) + margin - y0 + 1
        if max_size is not None and max(W, H) > max_size:
            raise self._too_big(W, H, max_size)
        Kv = np.array([[fx, s, -x0], [0.0, fy, -y0], [0.0, 0.0, 1.0]])
        mapx = (px - x0).astype(np.float32).reshape(self.height, self.width)
        mapy = (py - y0).astype(np.float32).reshape(self.height, self.width)
        m1, m2 = cv2.convertMaps(mapx, mapy, cv2.CV_16SC2)
        return RenderPlan(Kv, int(W), int(H), m1, m2, mapx, mapy)

    def _too_big(self, W: int, H: int, max_size: int) -> SensorError:
        return SensorError(
            f"{self.source}: resolution = [{self.width}, {self.height}]: the camera needs a "
            f"{W}x{H} render, larger than the renderer's maximum {max_size}x{max_size}"
            + ("" if self.is_pinhole else " (the margin needed to undistort the lens included)")
        )

    # ---------------------------------------------------------------- files
    def camera_info(
        self, store: MessageStore, frame_id: str, stamp_ns: int, seq: int = 0, Tx: float = 0.0
    ) -> Any:
        """sensor_msgs/CameraInfo of this camera in ``store``'s flavour (R = identity, P
        from :meth:`projection_matrix` with ``Tx``), stamped ``stamp_ns`` (absolute ns)."""
        roi = store.new(
            "sensor_msgs/msg/RegionOfInterest",
            x_offset=0,
            y_offset=0,
            height=0,
            width=0,
            do_rectify=False,
        )
        arrays = {
            "d": np.asarray(self.ros_D(), dtype=np.float64),
            "k": self.K.ravel().astype(np.float64),
            "r": np.eye(3).ravel(),
            "p": self.projection_matrix(Tx).ravel(),
        }
        if store.is_ros1:
            arrays = {k.upper(): v for k, v in arrays.items()}
        return store.new(
            "sensor_msgs/msg/CameraInfo",
            header=store.header(stamp_ns, frame_id, seq),
            height=self.height,
            width=self.width,
            distortion_model=self.ros_distortion_model(),
            binning_x=0,
            binning_y=0,
            roi=roi,
            **arrays,
        )

    def projection_matrix(self, Tx: float = 0.0) -> F64:
        """ROS CameraInfo P (3, 4): K with ``P[0, 3] = Tx`` (-fx * baseline: right camera)."""
        P = np.zeros((3, 4))
        P[:, :3] = self.K
        P[0, 3] = Tx
        return P

    def ros_distortion_model(self) -> str:
        """``plumb_bob`` or ``equidistant`` (ROS names; a pinhole is plumb_bob with zeros)."""
        return "equidistant" if self.distortion_model == "equidistant" else "plumb_bob"

    def ros_D(self) -> list[float]:
        if self.distortion_model == "none":
            return [0.0] * 5
        return [float(x) for x in self.D]

    def to_camera_info_yaml(self, *, Tx: float = 0.0) -> dict[str, Any]:
        """camera_calibration_parsers YAML content (a dict ready for ``yaml.safe_dump``)."""
        D = self.ros_D()
        return {
            "image_width": self.width,
            "image_height": self.height,
            "camera_name": self.name,
            "camera_matrix": {"rows": 3, "cols": 3, "data": [float(x) for x in self.K.ravel()]},
            "distortion_model": self.ros_distortion_model(),
            "distortion_coefficients": {"rows": 1, "cols": len(D), "data": D},
            "rectification_matrix": {
                "rows": 3,
                "cols": 3,
                "data": [float(x) for x in np.eye(3).ravel()],
            },
            "projection_matrix": {
                "rows": 3,
                "cols": 4,
                "data": [float(x) for x in self.projection_matrix(Tx).ravel()],
            },
        }

    def to_kalibr(
        self,
        *,
        rostopic: str = "",
        T_cam_imu: F64 | None = None,
        T_cn_cnm1: F64 | None = None,
    ) -> dict[str, Any]:
        """One ``camN`` entry of a Kalibr camchain YAML."""
        D = [float(x) for x in self.D]
        if self.distortion_model == "plumb_bob" and D[4] == 0.0:
            D = D[:4]  # Kalibr's radtan has 4 coefficients
        out: dict[str, Any] = {
            "camera_model": "pinhole",
            "intrinsics": [self.fx, self.fy, self.cx, self.cy],
            "distortion_model": _KALIBR_NAME[self.distortion_model],
            "distortion_coeffs": D,
            "resolution": [self.width, self.height],
        }
        if rostopic:
            out["rostopic"] = rostopic
        if T_cam_imu is not None:
            out["T_cam_imu"] = [[float(x) for x in row] for row in T_cam_imu]
        if T_cn_cnm1 is not None:
            out["T_cn_cnm1"] = [[float(x) for x in row] for row in T_cn_cnm1]
        return out


def pose_matrices(ctx: SimContext, t_ns: NDArray[np.int64]) -> F64:
    """(N, 4, 4) ``T_world_body`` at trajectory times ``t_ns``."""
    st = ctx.trajectory.state(t_ns.astype(np.float64) * 1e-9)
    T = np.zeros((len(t_ns), 4, 4))
    T[:, :3, :3] = st.R_world_body
    T[:, :3, 3] = st.position
    T[:, 3, 3] = 1.0
    return T
