# ruff: noqa: B023  (closures are timed inside the loop that defines them)
"""Camera throughput: one 640x480 rgb8 frame of the warehouse (plumb_bob distortion,
noise-free, sRGB encoding and sensor_msgs/Image packing included), frames/s at 346x260
mono8, and the ratio to a bare moderngl draw + readback of the same scene.

The bare baseline is a minimal moderngl program on the same context: one VBO of all
scene triangles (no index buffer, no culling), a constant-colour shader, no MSAA, an
RGBA8 target and a uint8 RGB readback, at the camera's render size and pose.

Run by hand: ``.venv/bin/python benchmarks/bench_camera.py`` (``ROSLAN_MSAA_SAMPLES=4``
for MSAA on llvmpipe).
"""

from __future__ import annotations

import os
import time

import numpy as np

from roslan.io.messages import Flavor, MessageStore
from roslan.render.gl import create_context, get_renderer, projection_from_K
from roslan.scene import load_scene
from roslan.sensors.camera import Camera, CameraConfig, _image, _pose_matrices  # noqa: F401
from roslan.sensors.camera_model import T_LINK_OPTICAL


class _Bare:
    """Minimal moderngl draw + readback of the scene (see the module docstring)."""

    def __init__(self, scene: object) -> None:
        ctx = self.ctx = create_context()
        tri = scene.triangles  # type: ignore[attr-defined]
        pos = np.ascontiguousarray(tri[0][tri[1]].reshape(-1, 3), dtype=np.float32)
        self.prog = ctx.program(
            vertex_shader="#version 410\nuniform mat4 m;\nin vec3 p;\n"
            "void main() { gl_Position = m * vec4(p, 1.0); }",
            fragment_shader="#version 410\nout vec4 c;\nvoid main() { c = vec4(0.5); }",
        )
        self.vao = ctx.vertex_array(self.prog, [(ctx.buffer(pos.tobytes()), "3f", "p")])
        self.fbo: dict[tuple[int, int], object] = {}

    def __call__(self, T: np.ndarray, K: np.ndarray, w: int, h: int, far: float) -> np.ndarray:
        ctx = self.ctx
        fbo = self.fbo.get((w, h))
        if fbo is None:
            fbo = ctx.framebuffer([ctx.renderbuffer((w, h))], ctx.depth_renderbuffer((w, h)))
            self.fbo[(w, h)] = fbo
        fbo.use()  # type: ignore[attr-defined]
        ctx.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)  # type: ignore[attr-defined]
        ctx.enable_only(ctx.DEPTH_TEST)
        M = projection_from_K(K, w, h, 0.01, far) @ np.linalg.inv(T)
        self.prog["m"].write(np.ascontiguousarray(M.T, dtype=np.float32).tobytes())
        self.vao.render()
        out = np.empty((h, w, 3), np.uint8)
        fbo.read_into(out, components=3)  # type: ignore[attr-defined]
        return out


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
    bare_draw = _Bare(scene)
    print(
        f"scene warehouse: {scene.n_triangles} triangles, {r.n_clusters} culling clusters; "
        f"{r.ctx.info['GL_RENDERER']}; MSAA samples {r.samples}; "
        f"load average {os.getloadavg()[0]:.2f}"
    )
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

        mono = enc == "mono8"

        def render_only() -> None:
            r.render(
                T, plan.K, plan.width, plan.height, color=not mono, depth=False, luminance=mono
            )

        def bare() -> None:
            bare_draw(T, plan.K, plan.width, plan.height, 80.0)

        n = 30
        t_frame = _time(frame, n)
        t_render = _time(render_only, n)
        t_bare = _time(bare, n)
        print(
            f"{w}x{h} {enc}{' plumb_bob' if dist else ''} (render {plan.width}x{plan.height}): "
            f"{t_frame * 1e3:.1f} ms/frame ({1 / t_frame:.0f} frames/s), of which "
            f"Renderer.render {t_render * 1e3:.1f} ms; bare moderngl draw+readback "
            f"{t_bare * 1e3:.1f} ms; ratio frame/bare {t_frame / t_bare:.2f}"
        )


if __name__ == "__main__":
    main()
