"""Camera throughput: one 640x480 rgb8 frame of the warehouse (plumb_bob distortion,
noise-free, sRGB encoding and sensor_msgs/Image packing included), frames/s at 346x260
mono8, and the ratio to a bare moderngl draw + readback of the same scene.

The bare baseline is a minimal moderngl program on the same context: one VBO of all
scene triangles (no index buffer, no culling), a constant-colour shader, no MSAA, an
RGBA8 target and a uint8 RGB readback, at the camera's render size and pose.

Before/after in one run: every variant is timed in interleaved rounds (the machine is
shared). "before" draws every face (``Renderer.cull_back_faces = False``, the third
pass), "after" skips the back faces of closed solids (the default); the number of
message bytes culling changes (coplanar ties only) is printed first. Reported: best wall
time of one frame, and process CPU time per frame (all threads, llvmpipe's included)
averaged over the runs.

Image quality of the render plans: ``bench_camera.py psnr`` compares the 640x480 rgb8
plumb_bob frame at several plan scales with a reference (2x focal length, 4x MSAA, 2x2
sub-pixel samples per output pixel through the exact lens model), PSNR of the 8-bit
sRGB images over the whole image, the centre (< 120 px from the principal point) and
the periphery (> 250 px).

Run by hand: ``.venv/bin/python benchmarks/bench_camera.py [ROUNDS | psnr]``
(``ROSLAN_MSAA_SAMPLES=4`` for MSAA on llvmpipe).
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable

import cv2
import numpy as np

from roslan.io.messages import Flavor, MessageStore
from roslan.render.gl import create_context, get_renderer, projection_from_K
from roslan.scene import load_scene
from roslan.sensors.cameras import T_LINK_OPTICAL, Camera, CameraConfig


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


class _Timer:
    """Best and median wall time and mean process CPU time per call, over interleaved
    rounds."""

    def __init__(self) -> None:
        self.walls: dict[str, list[float]] = {}
        self.cpu: dict[str, list[float]] = {}

    def run(self, name: str, f: Callable[[], object], n: int = 10) -> None:
        f()
        c0 = time.process_time()
        walls = self.walls.setdefault(name, [])
        for _ in range(n):
            t = time.perf_counter()
            f()
            walls.append(time.perf_counter() - t)
        self.cpu.setdefault(name, []).append((time.process_time() - c0) / n)

    def best(self, name: str) -> float:
        return min(self.walls[name])

    def ms(self, name: str) -> str:
        cpu = sum(self.cpu[name]) / len(self.cpu[name])
        med = float(np.median(self.walls[name]))
        return (
            f"{self.best(name) * 1e3:5.1f} ms, median {med * 1e3:5.1f} ms (cpu {cpu * 1e3:5.1f} ms)"
        )


def _camera(w: int, h: int, enc: str, dist: bool) -> Camera:
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
    return Camera(cfg)


def _psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    d = (a.astype(np.float64) - b.astype(np.float64))[mask] ** 2
    return 10.0 * math.log10(255.0**2 / float(d.mean()))


def quality() -> None:
    """PSNR of the 640x480 plumb_bob frame per plan scale (see the module docstring)."""
    scene = load_scene("warehouse")
    r = get_renderer(scene)
    cam = _camera(640, 480, "rgb8", True)
    cam._plans(_Ctx(r))  # type: ignore[arg-type]
    e = cam._eyes[0]
    m = e.model
    T_wb = np.eye(4)
    T_wb[:3, 3] = np.asarray(scene.goal_position) + np.array([-6.0, 1.0, 3.0])
    c, s = np.cos(0.35), np.sin(0.35)
    T_wb[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    T = T_wb @ T_LINK_OPTICAL
    u, v = np.meshgrid(np.arange(640.0), np.arange(480.0))
    ref_plan = m.render_plan(r.max_size, scale=2.0)
    hi = r.render(T, ref_plan.K, ref_plan.width, ref_plan.height, depth=False, samples=4).color
    acc = np.zeros((480, 640, 3), np.float32)
    for du in (-0.25, 0.25):
        for dv in (-0.25, 0.25):
            xy = m.undistort_normalized(np.stack([(u + du).ravel(), (v + dv).ravel()], 1))
            mx = ref_plan.K[0, 0] * xy[:, 0] + ref_plan.K[0, 2]
            my = ref_plan.K[1, 1] * xy[:, 1] + ref_plan.K[1, 2]
            acc += cv2.remap(
                hi,
                mx.astype(np.float32).reshape(480, 640),
                my.astype(np.float32).reshape(480, 640),
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_REPLICATE,
            )
    ref = cam.finish_image(acc * np.float32(0.25), np.random.default_rng(0))
    rad = np.hypot(u - m.cx, v - m.cy)
    regions = {"all": rad >= 0, "centre": rad < 120, "periphery": rad > 250}
    print(f"PSNR vs reference (load average {os.getloadavg()[0]:.2f}):")
    for scale in (1.0, 0.9, None, 0.7):
        e.plan = m.render_plan(r.max_size, scale=scale)
        img = cam.finish_image(cam.render_linear(r, e, T_wb[None]), np.random.default_rng(0))
        db = ", ".join(f"{k} {_psnr(img, ref, mk):.2f} dB" for k, mk in regions.items())
        label = "auto" if scale is None else f"{scale}"
        f = e.plan.K[0, 0] / m.fx
        print(f"  scale {label} ({f:.3f}, {e.plan.width}x{e.plan.height}): {db}")


def main() -> None:
    if sys.argv[1:] == ["psnr"]:
        quality()
        return
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
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
    T = T_wb @ T_LINK_OPTICAL
    bare_draw = _Bare(scene)
    load0 = os.getloadavg()[0]
    print(
        f"scene warehouse: {scene.n_triangles} triangles, {r.n_clusters} culling clusters; "
        f"{r.ctx.info['GL_RENDERER']}; MSAA samples {r.samples}; "
        f"LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', '-')}; {rounds} rounds"
    )
    rng = np.random.default_rng(0)
    timer = _Timer()
    # name, call, back-face culling (before: the third pass, every face drawn)
    cases: list[tuple[str, Callable[[], object], bool]] = []

    def frame(cam: Camera, enc: str) -> Callable[[], bytes]:
        """One frame (Camera.render_linear + finish_image), as wire bytes."""
        e = cam._eyes[0]

        def f() -> bytes:
            img = cam.finish_image(cam.render_linear(r, e, T_wb[None]), rng)
            return store.image("c_optical", 1, img, enc)

        return f

    cam = _camera(640, 480, "rgb8", True)
    cam._plans(_Ctx(r))  # type: ignore[arg-type]
    p = cam._eyes[0].plan
    assert p is not None
    size = f"{p.width}x{p.height}"
    big = _camera(640, 480, "rgb8", True)
    big._plans(_Ctx(r))  # type: ignore[arg-type]
    big._eyes[0].plan = big._eyes[0].model.render_plan(r.max_size, scale=1.0)
    f640 = "640x480 rgb8 plumb_bob frame"
    small = _camera(346, 260, "mono8", False)
    small._plans(_Ctx(r))  # type: ignore[arg-type]
    q = small._eyes[0].plan
    assert q is not None
    for label, cull in (("before", False), ("after", True)):
        cases += [
            (f"{f640}, {label}", frame(cam, "rgb8"), cull),
            (f"{f640}, {label}, render_scale 1.0 (805x605)", frame(big, "rgb8"), cull),
            (
                f"  Renderer.render(color) {size}, {label}",
                lambda: r.render(T, p.K, p.width, p.height, color=True, depth=False),
                cull,
            ),
            (f"346x260 mono8 frame, {label}", frame(small, "mono8"), cull),
        ]
        for dep in (False, True):
            cases.append(
                (
                    f"  Renderer.render(luminance{', depth' if dep else ''}) 346x260, {label}",
                    lambda dep=dep: r.render(
                        T, q.K, 346, 260, color=False, depth=dep, luminance=True
                    ),
                    cull,
                )
            )
    cases += [
        (
            f"  bare moderngl draw+readback {size}",
            lambda: bare_draw(T, p.K, p.width, p.height, 80.0),
            True,
        ),
        ("  bare moderngl draw+readback 346x260", lambda: bare_draw(T, q.K, 346, 260, 80.0), True),
    ]

    # culling settles only coplanar ties: count the message bytes it changes
    for name, fr in ((f640, frame(cam, "rgb8")), ("346x260 mono8 frame", frame(small, "mono8"))):
        imgs = {}
        for cull in (False, True):
            r.cull_back_faces = cull
            imgs[cull] = np.frombuffer(fr(), np.uint8)
        n = int(np.count_nonzero(imgs[False] != imgs[True]))
        print(f"{name}: {n} of {imgs[True].size} message bytes changed by culling")
    for _ in range(rounds):
        for name, f, cull in cases:
            r.cull_back_faces = cull
            timer.run(name, f)
    r.cull_back_faces = True
    print(
        f"render plan {size}, f {p.K[0, 0]:.1f}; load average {load0:.2f} at start, "
        f"{os.getloadavg()[0]:.2f} at end"
    )
    for name, _, _ in cases:
        print(f"{name}: {timer.ms(name)}")
    a, b = f"{f640}, after", f"{f640}, before"
    bare = f"  bare moderngl draw+readback {size}"
    m = timer.best("346x260 mono8 frame, after")
    m_bare = timer.best("  bare moderngl draw+readback 346x260")
    print(
        f"ratios: 640x480 frame after/before {timer.best(a) / timer.best(b):.2f}; "
        f"frame/bare {timer.best(a) / timer.best(bare):.2f}; 346x260 mono8 frame/bare "
        f"{m / m_bare:.2f}; 346x260 mono8 {1 / m:.0f} frames/s"
    )


if __name__ == "__main__":
    main()
