# ruff: noqa: B023  (closures are timed inside the loop that defines them)
"""Camera throughput: one 640x480 rgb8 frame of the warehouse (plumb_bob distortion,
noise-free, sRGB encoding and sensor_msgs/Image packing included), frames/s at 346x260
mono8, and the ratio to a bare moderngl draw + readback of the same scene.

Run by hand: ``.venv/bin/python benchmarks/bench_camera.py``.
"""

from __future__ import annotations

import time

import numpy as np

from roslan.io.messages import Flavor, MessageStore
from roslan.render.gl import get_renderer
from roslan.scene import load_scene
from roslan.sensors.camera import Camera, CameraConfig, _image, _pose_matrices  # noqa: F401
from roslan.sensors.camera_model import T_LINK_OPTICAL


class _Ctx:
    def __init__(self, r: object) -> None:
        self._r = r

    def renderer(self) -> object:
        return self._r


def _time(f, n: int) -> float:  # type: ignore[no-untyped-def]
    f()
    t = time.perf_counter()
    for _ in range(n):
        f()
    return (time.perf_counter() - t) / n


def main() -> None:
    scene = load_scene("warehouse")
    r = get_renderer(scene)
    store = MessageStore(Flavor.ROS1)
    goal = np.asarray(scene.goal_position)
    T_wb = np.eye(4)
    T_wb[:3, 3] = goal + np.array([-6.0, 1.0, 3.0])
    pitch = 0.35
    T_wb[:3, :3] = [
        [np.cos(pitch), 0, np.sin(pitch)],
        [0, 1, 0],
        [-np.sin(pitch), 0, np.cos(pitch)],
    ]
    print(f"scene warehouse: {scene.n_triangles} triangles, {r.n_clusters} culling clusters")
    for w, h, enc, dist in [(640, 480, "rgb8", True), (346, 260, "mono8", False)]:
        cfg = CameraConfig.model_validate(
            {
                "type": "camera",
                "name": "c",
                "rate": 30.0,
                "topic": "/c",
                "resolution": [w, h],
                "encoding": enc,
                **(
                    {"distortion_model": "plumb_bob", "distortion_coeffs": [-0.2, 0.05, 0, 0, 0]}
                    if dist
                    else {}
                ),
            }
        )
        cam = Camera(cfg)
        cam._plans(_Ctx(r))  # type: ignore[arg-type]
        e = cam._eyes[0]
        rng = np.random.default_rng(0)

        def frame() -> None:
            img = cam.finish_image(cam.render_linear(r, e, T_wb[None]), rng)
            store.serialize(_image(store, "c_optical", 1, 0, img, enc), "sensor_msgs/msg/Image")

        T = T_wb @ T_LINK_OPTICAL
        plan = e.plan
        assert plan is not None

        def bare() -> None:
            r.render(T, plan.K, plan.width, plan.height, color=True, depth=False)

        n = 30
        t_frame = _time(frame, n)
        t_bare = _time(bare, n)
        print(
            f"{w}x{h} {enc}{' plumb_bob' if dist else ''} (render {plan.width}x{plan.height}): "
            f"{t_frame * 1e3:.1f} ms/frame ({1 / t_frame:.0f} frames/s); bare draw+readback "
            f"{t_bare * 1e3:.1f} ms; ratio {t_frame / t_bare:.2f}"
        )


if __name__ == "__main__":
    main()
