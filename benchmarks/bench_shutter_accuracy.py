"""Accuracy of the default camera's shutter against a 64-render reference (issue 49).

The default job's frame camera (640x480 mono8, plumb_bob lens, 10 ms rolling shutter,
auto-exposure 0.2-10 ms) at 10 Hz over the default landing, once with the default job's
flapping (pitch 0.035 rad at 4.5 Hz) and once with stronger flapping (pitch 0.12 rad).
Every frame is made twice at the exposure the metering pass gives it (the metering does
not depend on the shutter's sampling):

* ``default``: the camera's own image formation (``Camera.frame_linear``; on code without
  it, the banded renders of ``exposure_samples``);
* ``reference``: 64 renders spread over the shutter window, every row the average of the
  renders weighted by their overlap with its own exposure window
  (:func:`roslan.sensors.cameras.shutter.render_rolling`: renders only, no warping), at
  the MSAA samples of the camera's own renders
  (:data:`roslan.sensors.cameras.row_exposure.RENDER_SAMPLES`; ``--reference-samples``
  overrides it, e.g. 1 for the renderer's one sample per pixel and edge filter).

Both are encoded to 8 bits (no noise) and compared per 60-row band: the shift by phase
correlation (``cv2.phaseCorrelate``, Hanning window; of the linear images, before the
8-bit rounding), the gradient energy of the default over the reference's (1.0 = the same
blur) and the RMS difference (DN). Printed per band:
shift p95 over the frames, gradient energy median (p95), RMS p95; and the worst band
(the largest shift and RMS p95, the median farthest from 1, the largest p95). ``--png``
writes a picture of the worst frame: default, reference and their difference, with the
band lines.

    PYTHONPATH=src python benchmarks/bench_shutter_accuracy.py [--png docs/img/x.png]
        [--frames N] [--pitch P ...] [--reference-samples N]
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import cv2
import numpy as np

from roslan.cli.simulate import load_config
from roslan.render.gl import get_renderer
from roslan.scene import load_scene
from roslan.sensors.cameras import Camera
from roslan.sensors.cameras.shutter import render_rolling, shutter_plan
from roslan.trajectory import TauTrajectory
from roslan.vehicle import base_link_trajectory

try:
    from roslan.sensors.cameras.row_exposure import RENDER_SAMPLES as CAMERA_SAMPLES
except ImportError:  # code without the row formation: the renderer's own samples
    CAMERA_SAMPLES = None

RATE = 10.0  # frames per trajectory second
BAND = 60  # rows per band
REFERENCE_SAMPLES = 64
PITCHES = (0.035, 0.12)  # the default job's flapping, the stronger flapping


class _Ctx:
    def __init__(self, renderer: Any, trajectory: Any) -> None:
        self._r = renderer
        self.trajectory = trajectory

    def renderer(self) -> Any:
        return self._r


def _body_poses(traj: Any, t_ns: np.ndarray) -> np.ndarray:
    st = traj.state(t_ns.astype(np.float64) * 1e-9)
    T = np.zeros((len(t_ns), 4, 4))
    T[:, :3, :3] = st.R_world_body
    T[:, :3, 3] = st.position
    T[:, 3, 3] = 1.0
    return T


def default_frame(cam: Camera, ctx: _Ctx, t: int, exposure: float) -> np.ndarray:
    """The camera's own image formation of the frame stamped ``t`` (linear)."""
    e = cam._eyes[0]
    if hasattr(cam, "frame_linear"):
        return np.array(cam.frame_linear(ctx, ctx.renderer(), e, t, exposure))  # type: ignore[arg-type]
    plan, T_wb = cam.eye_poses(ctx, e, t, exposure)  # type: ignore[arg-type]
    return np.array(cam.render_linear(ctx.renderer(), e, T_wb, plan))


def reference_frame(
    cam: Camera, ctx: _Ctx, t: int, exposure: float, samples: int | None
) -> np.ndarray:
    """64 renders over the window (``samples`` MSAA samples each; None: the renderer's),
    rows weighted by their own exposure window."""
    c, e = cam.config, cam._eyes[0]
    assert e.plan is not None
    plan = shutter_plan(t, exposure, c.readout_time, REFERENCE_SAMPLES, e.model.height)
    T_opt = _body_poses(ctx.trajectory, plan.instants_ns) @ cam._T_body_sensor @ e.T_sensor_optical
    out = np.empty((e.model.height, e.model.width), np.float32)
    if samples is None:
        return render_rolling(ctx.renderer(), e.plan, T_opt, plan, out, True, c.near_clip)
    return render_rolling(
        ctx.renderer(), e.plan, T_opt, plan, out, True, c.near_clip, samples=samples
    )


def band_metrics(
    a: np.ndarray, b: np.ndarray, la: np.ndarray, lb: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per band of 8-bit images ``a`` (default) and ``b`` (reference): the shift (px) of
    their linear images ``la`` over ``lb`` (before the 8-bit rounding, whose noise alone
    moves a phase correlation's peak by up to 0.4 px on bands that agree within 0.3 DN
    RMS), the gradient energy of ``a`` over ``b``'s, the RMS difference (DN)."""
    shifts, grads, rms = [], [], []
    win = cv2.createHanningWindow((a.shape[1], BAND), cv2.CV_64F)
    for r0 in range(0, a.shape[0] - BAND + 1, BAND):
        x, y = a[r0 : r0 + BAND].astype(np.float64), b[r0 : r0 + BAND].astype(np.float64)
        lx = la[r0 : r0 + BAND].astype(np.float64)
        ly = lb[r0 : r0 + BAND].astype(np.float64)
        (dx, dy), _ = cv2.phaseCorrelate(ly, lx, win)
        shifts.append(float(np.hypot(dx, dy)))

        def energy(im: np.ndarray) -> float:
            gx, gy = np.diff(im, axis=1), np.diff(im, axis=0)
            return float((gx**2).sum() + (gy**2).sum())

        grads.append(energy(x) / max(energy(y), 1e-9))
        rms.append(float(np.sqrt(np.mean((x - y) ** 2))))
    return np.array(shifts), np.array(grads), np.array(rms)


def run(
    pitch: float, frames: int | None, png: str | None, samples: int | None = CAMERA_SAMPLES
) -> dict[str, float]:
    cfg, _ = load_config(None)
    tcfg = cfg.trajectory.model_copy(
        update={"flapping": cfg.trajectory.flapping.model_copy(update={"pitch": pitch})}
    )
    cam_cfg = next(s for s in cfg.sensors if s.type == "camera")
    traj = TauTrajectory(base_link_trajectory(tcfg, cfg.vehicle), warn=False)
    ctx = _Ctx(get_renderer(load_scene(cfg.scene, seed=cfg.seed)), traj)
    cam = Camera(type(cam_cfg).model_validate(cam_cfg.model_dump(mode="python") | {"rate": RATE}))
    cam._plans(ctx)  # type: ignore[arg-type]
    stamps = cam._stamps(round(traj.T * 1e9))
    if frames is not None:
        stamps = stamps[np.linspace(0, stamps.size - 1, frames).round().astype(int)]
    ex = cam.exposures(ctx, stamps)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    S, G, Q = [], [], []
    worst: tuple[float, np.ndarray, np.ndarray, float] | None = None
    c0 = time.process_time()
    for t, x in zip(stamps.tolist(), ex.tolist(), strict=True):
        la = default_frame(cam, ctx, t, x)
        lb = reference_frame(cam, ctx, t, x, samples).copy()
        a = cam.finish_image(la.copy(), rng, x)
        b = cam.finish_image(lb.copy(), rng, x)
        s, g, q = band_metrics(a, b, la, lb)
        S.append(s)
        G.append(g)
        Q.append(q)
        if worst is None or q.max() > worst[0]:
            worst = (float(q.max()), a, b, t * 1e-9)
    S_, G_, Q_ = np.array(S), np.array(G), np.array(Q)
    print(
        f"\nflapping pitch {pitch} rad at {tcfg.flapping.frequency} Hz: {len(stamps)} frames "
        f"at {RATE:g} Hz, exposures {ex.min() * 1e3:.2f}-{ex.max() * 1e3:.2f} ms "
        f"(median {np.median(ex) * 1e3:.2f}); reference MSAA samples "
        f"{'renderer default' if samples is None else samples}; "
        f"{time.process_time() - c0:.1f} CPU-s"
    )
    print("| band (rows) | shift p95 (px) | gradient energy median (p95) | RMS p95 (DN) |")
    print("|---|---|---|---|")
    for k in range(S_.shape[1]):
        print(
            f"| {k * BAND}-{(k + 1) * BAND - 1} | {np.percentile(S_[:, k], 95):.2f} | "
            f"{np.median(G_[:, k]):.3f}x ({np.percentile(G_[:, k], 95):.2f}x) | "
            f"{np.percentile(Q_[:, k], 95):.2f} |"
        )
    med = np.median(G_, axis=0)
    res = {
        "shift_p95": float(np.percentile(S_, 95, axis=0).max()),
        "grad_median": float(med[np.argmax(np.abs(med - 1.0))]),
        "grad_p95": float(np.percentile(G_, 95, axis=0).max()),
        "rms_p95": float(np.percentile(Q_, 95, axis=0).max()),
    }
    print(
        f"| **worst band** | **{res['shift_p95']:.2f}** | **{res['grad_median']:.3f}x** "
        f"({res['grad_p95']:.2f}x) | **{res['rms_p95']:.2f}** |"
    )
    if png is not None and worst is not None:
        _picture(png, pitch, *worst[1:])
    return res


def _picture(path: str, pitch: float, a: np.ndarray, b: np.ndarray, t: float) -> None:
    """Default | reference | difference (x8, grey = 0) of one frame, band lines in red."""
    diff = np.clip(128.0 + 8.0 * (a.astype(np.float64) - b), 0, 255).astype(np.uint8)
    row = np.concatenate([a, np.full((a.shape[0], 6), 255, np.uint8), b, diff[:, :0]], axis=1)
    row = np.concatenate([row, np.full((a.shape[0], 6), 255, np.uint8), diff], axis=1)
    img = cv2.cvtColor(row, cv2.COLOR_GRAY2BGR)
    for r in range(BAND, a.shape[0], BAND):
        img[r, :, :] = (0, 0, 200)
    img = cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2), interpolation=cv2.INTER_AREA)
    head = np.full((22, img.shape[1], 3), 255, np.uint8)
    text = (
        f"pitch {pitch} rad, t = {t:.2f} s: default | 64-render reference | "
        "difference x8 (grey = 0); red: 60-row bands"
    )
    cv2.putText(head, text, (4, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.imwrite(path, np.concatenate([head, img], axis=0), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=None, help="frames per landing (default all)")
    ap.add_argument("--pitch", type=float, nargs="*", default=list(PITCHES))
    ap.add_argument("--png", default=None, help="picture of the strongest landing's worst frame")
    ap.add_argument(
        "--reference-samples",
        type=int,
        default=CAMERA_SAMPLES,
        help="MSAA samples of the reference's renders (default: the camera's own)",
    )
    args = ap.parse_args()
    for i, p in enumerate(args.pitch):
        last = i == len(args.pitch) - 1
        run(p, args.frames, args.png if last else None, args.reference_samples)


if __name__ == "__main__":
    main()
