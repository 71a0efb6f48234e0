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

Both are encoded to 8 bits (no noise) and compared per 60-row band: the shift (of the
linear images, before the 8-bit rounding), the gradient energy of the default over the
reference's (1.0 = the same blur) and the RMS difference (DN). The shift is measured two
ways:

* ``LS``: the least-squares translation (:func:`ls_shift`: Gauss-Newton on
  ``a(x) = b(x - d)``, cubic resampling; a direction the band's content does not
  determine, e.g. along a lone straight edge or on a flat band, counts as 0);
* ``PC``: ``cv2.phaseCorrelate`` (Hanning window), the issue's first estimator. Its
  sub-pixel peak (a weighted centroid of the whitened correlation) is biased on bands
  that a few long, blurred edges dominate (the marker seen from under a metre): ``--check``
  moves each reference band by known sub-pixel shifts (Lanczos resampling) and prints
  both estimators' errors.

Printed per band: shift p95 over the frames (LS, and PC), gradient energy median (p95),
RMS p95; and the worst band (the largest shift and RMS p95, the median farthest from 1,
the largest p95). ``--png`` writes a picture of the worst frame: default, reference and
their difference, with the band lines.

    PYTHONPATH=src python benchmarks/bench_shutter_accuracy.py [--png docs/img/x.png]
        [--frames N] [--pitch P ...] [--frequency F] [--reference-samples N] [--check]
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

from roslan.cli.simulate import load_config
from roslan.render.gl import get_renderer
from roslan.scene import load_scene
from roslan.sensors.cameras import Camera
from roslan.sensors.cameras.shutter import render_rolling, shutter_plan
from roslan.trajectory import TauTrajectory
from roslan.vehicle import base_link_trajectory
from shutter_setup import BenchCtx, body_poses

try:
    from roslan.sensors.cameras.row_exposure import RENDER_SAMPLES as CAMERA_SAMPLES
except ImportError:  # code without the row formation: the renderer's own samples
    CAMERA_SAMPLES = None

RATE = 10.0  # frames per trajectory second
BAND = 60  # rows per band
REFERENCE_SAMPLES = 64
PITCHES = (0.035, 0.12)  # the default job's flapping, the stronger flapping
LS_FLOOR = 2e-3
"""A direction counts as determined where its mean squared gradient exceeds
``(LS_FLOOR * max)^2`` per px (0.5 DN/px on an image whose largest value is 255 DN)."""


def default_frame(cam: Camera, ctx: BenchCtx, t: int, exposure: float) -> np.ndarray:
    """The camera's own image formation of the frame stamped ``t`` (linear)."""
    e = cam._eyes[0]
    if hasattr(cam, "frame_linear"):
        return np.array(cam.frame_linear(ctx, ctx.renderer(), e, t, exposure))  # type: ignore[arg-type]
    plan, T_wb = cam.eye_poses(ctx, e, t, exposure)  # type: ignore[arg-type]
    return np.array(cam.render_linear(ctx.renderer(), e, T_wb, plan))


def reference_frame(
    cam: Camera, ctx: BenchCtx, t: int, exposure: float, samples: int | None
) -> np.ndarray:
    """64 renders over the window (``samples`` MSAA samples each; None: the renderer's),
    rows weighted by their own exposure window."""
    c, e = cam.config, cam._eyes[0]
    assert e.plan is not None
    plan = shutter_plan(t, exposure, c.readout_time, REFERENCE_SAMPLES, e.model.height)
    T_opt = body_poses(ctx.trajectory, plan.instants_ns) @ cam._T_body_sensor @ e.T_sensor_optical
    out = np.empty((e.model.height, e.model.width), np.float32)
    if samples is None:
        return render_rolling(ctx.renderer(), e.plan, T_opt, plan, out, True, c.near_clip)
    return render_rolling(
        ctx.renderer(), e.plan, T_opt, plan, out, True, c.near_clip, samples=samples
    )


def ls_shift(a: np.ndarray, b: np.ndarray, iters: int = 5) -> tuple[float, float]:
    """``(dx, dy)`` (px) that moves image ``b`` onto ``a`` in the least-squares sense,
    ``a(x) ~ b(x - d)``: Gauss-Newton steps on ``b`` resampled (cubic) at ``x - d``, over
    the interior (3 px from the edges). Directions of the band's structure tensor with
    a mean squared gradient under :data:`LS_FLOOR` (of ``b``'s largest value, per px) are
    not determined by its content and are held at 0."""
    a, b = a.astype(np.float64), b.astype(np.float64)
    d = np.zeros(2)
    floor = (LS_FLOOR * max(float(np.abs(b).max()), 1e-12)) ** 2
    inner = (slice(3, -3), slice(3, -3))
    for _ in range(iters):
        M = np.array([[1.0, 0.0, d[0]], [0.0, 1.0, d[1]]])
        bs = cv2.warpAffine(
            b, M, (b.shape[1], b.shape[0]), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT
        )
        gy, gx = np.gradient(bs)
        A = np.stack([gx[inner].ravel(), gy[inner].ravel()], axis=1)
        r = (bs - a)[inner].ravel()
        N = A.T @ A / A.shape[0]
        lam, V = np.linalg.eigh(N)
        g = V.T @ (A.T @ r / A.shape[0])
        step = np.where(lam > floor, g / np.where(lam > floor, lam, 1.0), 0.0)
        d += V @ step
    return float(d[0]), float(d[1])


def _determined(b: np.ndarray) -> bool:
    """Whether ``b``'s content determines a shift in both directions (:func:`ls_shift`)."""
    gy, gx = np.gradient(b.astype(np.float64))
    A = np.stack([gx[3:-3, 3:-3].ravel(), gy[3:-3, 3:-3].ravel()], axis=1)
    floor = (LS_FLOOR * max(float(np.abs(b).max()), 1e-12)) ** 2
    return bool(np.linalg.eigvalsh(A.T @ A / A.shape[0])[0] > floor)


def pc_shift(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """``(dx, dy)`` of :func:`ls_shift` by ``cv2.phaseCorrelate`` (Hanning window)."""
    win = cv2.createHanningWindow((a.shape[1], a.shape[0]), cv2.CV_64F)
    (dx, dy), _ = cv2.phaseCorrelate(b.astype(np.float64), a.astype(np.float64), win)
    return float(dx), float(dy)


def band_metrics(
    a: np.ndarray, b: np.ndarray, la: np.ndarray, lb: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per band of 8-bit images ``a`` (default) and ``b`` (reference): the shift (px) of
    their linear images ``la`` over ``lb`` by least squares and by phase correlation
    (before the 8-bit rounding, whose noise alone moves a phase correlation's peak by up
    to 0.4 px on bands that agree within 0.3 DN RMS), the gradient energy of ``a`` over
    ``b``'s, the RMS difference (DN)."""
    ls, pc, grads, rms = [], [], [], []
    for r0 in range(0, a.shape[0] - BAND + 1, BAND):
        x, y = a[r0 : r0 + BAND].astype(np.float64), b[r0 : r0 + BAND].astype(np.float64)
        lx, ly = la[r0 : r0 + BAND], lb[r0 : r0 + BAND]
        ls.append(float(np.hypot(*ls_shift(lx, ly))))
        pc.append(float(np.hypot(*pc_shift(lx, ly))))

        def energy(im: np.ndarray) -> float:
            gx, gy = np.diff(im, axis=1), np.diff(im, axis=0)
            return float((gx**2).sum() + (gy**2).sum())

        grads.append(energy(x) / max(energy(y), 1e-9))
        rms.append(float(np.sqrt(np.mean((x - y) ** 2))))
    return np.array(ls), np.array(pc), np.array(grads), np.array(rms)


def known_shift(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``img`` moved by ``(dx, dy)`` px, resampled by Lanczos (8x8 taps: not the cubic
    resampling :func:`ls_shift` fits with)."""
    M = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    size = (img.shape[1], img.shape[0])
    out: np.ndarray = cv2.warpAffine(
        img.astype(np.float64), M, size, flags=cv2.INTER_LANCZOS4, borderMode=cv2.BORDER_REFLECT
    )
    return out


def check_estimators(refs: list[np.ndarray], shifts: tuple[float, ...] = (0.1, 0.2)) -> None:
    """Both estimators' errors on reference bands moved by known shifts (``dy`` =
    ``shift``, ``dx`` = ``shift / 2``, :func:`known_shift`), the bands as
    :func:`band_metrics` takes them, over those whose content determines both directions:
    p95 and max over the bands of all frames."""
    err: dict[str, list[float]] = {"LS": [], "PC": []}
    for lb in refs:
        for sft in shifts:
            moved = known_shift(lb, 0.5 * sft, sft)
            for r0 in range(0, lb.shape[0] - BAND + 1, BAND):
                x, y = moved[r0 : r0 + BAND], lb[r0 : r0 + BAND]
                if not _determined(y):
                    continue
                for name, fn in (("LS", ls_shift), ("PC", pc_shift)):
                    dx, dy = fn(x, y)
                    err[name].append(float(np.hypot(dx - 0.5 * sft, dy - sft)))
    for name, e in err.items():
        print(
            f"estimator check {name}: error on known shifts {shifts} px, {len(e)} bands: "
            f"p95 {np.percentile(e, 95):.3f} px, max {max(e):.3f} px"
        )


def run(
    pitch: float,
    frames: int | None,
    png: str | None,
    samples: int | None = CAMERA_SAMPLES,
    frequency: float | None = None,
    check: bool = False,
) -> dict[str, float]:
    cfg, _ = load_config(None)
    flap = {"pitch": pitch} | ({} if frequency is None else {"frequency": frequency})
    tcfg = cfg.trajectory.model_copy(
        update={"flapping": cfg.trajectory.flapping.model_copy(update=flap)}
    )
    cam_cfg = next(s for s in cfg.sensors if s.type == "camera")
    traj = TauTrajectory(base_link_trajectory(tcfg, cfg.vehicle), warn=False)
    ctx = BenchCtx(get_renderer(load_scene(cfg.scene, seed=cfg.seed)), traj)
    cam = Camera(type(cam_cfg).model_validate(cam_cfg.model_dump(mode="python") | {"rate": RATE}))
    cam._plans(ctx)  # type: ignore[arg-type]
    stamps = cam._stamps(round(traj.T * 1e9))
    if frames is not None:
        stamps = stamps[np.linspace(0, stamps.size - 1, frames).round().astype(int)]
    ex = cam.exposures(ctx, stamps)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    S, P, G, Q = [], [], [], []
    refs: list[np.ndarray] = []
    worst: tuple[float, np.ndarray, np.ndarray, float] | None = None
    c0 = time.process_time()
    for t, x in zip(stamps.tolist(), ex.tolist(), strict=True):
        la = default_frame(cam, ctx, t, x)
        lb = reference_frame(cam, ctx, t, x, samples).copy()
        a = cam.finish_image(la.copy(), rng, x)
        b = cam.finish_image(lb.copy(), rng, x)
        s, p, g, q = band_metrics(a, b, la, lb)
        S.append(s)
        P.append(p)
        if check:
            refs.append(lb)
        G.append(g)
        Q.append(q)
        if worst is None or q.max() > worst[0]:
            worst = (float(q.max()), a, b, t * 1e-9)
    S_, P_, G_, Q_ = np.array(S), np.array(P), np.array(G), np.array(Q)
    print(
        f"\nflapping pitch {pitch} rad at {tcfg.flapping.frequency} Hz: {len(stamps)} frames "
        f"at {RATE:g} Hz, exposures {ex.min() * 1e3:.2f}-{ex.max() * 1e3:.2f} ms "
        f"(median {np.median(ex) * 1e3:.2f}); reference MSAA samples "
        f"{'renderer default' if samples is None else samples}; "
        f"{time.process_time() - c0:.1f} CPU-s"
    )
    print("| band (rows) | shift p95, LS (PC) (px) | gradient energy median (p95) | RMS p95 (DN) |")
    print("|---|---|---|---|")
    for k in range(S_.shape[1]):
        print(
            f"| {k * BAND}-{(k + 1) * BAND - 1} | {np.percentile(S_[:, k], 95):.2f} "
            f"({np.percentile(P_[:, k], 95):.2f}) | "
            f"{np.median(G_[:, k]):.3f}x ({np.percentile(G_[:, k], 95):.2f}x) | "
            f"{np.percentile(Q_[:, k], 95):.2f} |"
        )
    med = np.median(G_, axis=0)
    res = {
        "shift_p95": float(np.percentile(S_, 95, axis=0).max()),
        "shift_pc_p95": float(np.percentile(P_, 95, axis=0).max()),
        "grad_median": float(med[np.argmax(np.abs(med - 1.0))]),
        "grad_p95": float(np.percentile(G_, 95, axis=0).max()),
        "rms_p95": float(np.percentile(Q_, 95, axis=0).max()),
    }
    print(
        f"| **worst band** | **{res['shift_p95']:.2f}** ({res['shift_pc_p95']:.2f}) | "
        f"**{res['grad_median']:.3f}x** "
        f"({res['grad_p95']:.2f}x) | **{res['rms_p95']:.2f}** |"
    )
    if check:
        check_estimators(refs)
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
    ap.add_argument(
        "--frequency", type=float, default=None, help="flapping frequency, Hz (default: the job's)"
    )
    ap.add_argument("--check", action="store_true", help="both shift estimators on known shifts")
    args = ap.parse_args()
    for i, p in enumerate(args.pitch):
        last = i == len(args.pitch) - 1
        png = args.png if last else None
        run(p, args.frames, png, args.reference_samples, args.frequency, args.check)


if __name__ == "__main__":
    main()
