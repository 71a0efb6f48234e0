"""``roslan preview OUTDIR -o preview.mp4 [--gif]``: one synchronized video of a run.

Four panels share one clock (trajectory time): the latest camera frame, the event
frame of the last ``--window-ms`` (default 20 ms) over the grayscale image, the latest
LiDAR scan from above (colour = height), and a trajectory inset (top view and height
against time) with the current position; a header shows the time. Panels are composed
with NumPy/OpenCV and streamed to ffmpeg (the imageio-ffmpeg wheel carries it) one
frame at a time, so memory does not grow with the run's length; matplotlib draws only
the inset's static background, once. The video appears under its final name only when
complete.

MP4 is H.264 (yuv420p) at ``--fps`` (default 30); ``--speed`` plays faster or slower
than real time. ``--gif`` writes an animated GIF at half size and at most 12 fps
(ffmpeg palette: it buffers the frames of that one file while encoding).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.plots.media import RunMedia, render_events
from roslan.plots.raster import (
    BACKGROUND_RGB,
    bev_image,
    fit_into,
    label,
    placeholder,
)
from roslan.plots.trajectory import TrajectorySamples
from roslan.rundir.readers import LidarScan

__all__ = ["PreviewInfo", "make_preview"]

U8 = NDArray[np.uint8]
COMMAND = "roslan preview"
GIF_MAX_FPS = 12.0


@dataclass(frozen=True, slots=True)
class PreviewInfo:
    """What :func:`make_preview` wrote: the file, its frame count, rate and size (w, h)."""

    path: Path
    frames: int
    fps: float
    size: tuple[int, int]


class _TrajectoryInset:
    """The trajectory panel: a matplotlib background drawn once, and the pixel position
    of every dense sample in it, so each frame only draws a dot (OpenCV)."""

    def __init__(self, s: TrajectorySamples, width: int, height: int) -> None:
        from roslan.plots.style import figure, style

        d = s.dense
        self.t = d.t
        with style():
            fig = figure(width / 100.0, height / 100.0)
            fig.set_dpi(100)
            fig.set_layout_engine("constrained")
            top, side = fig.subplots(1, 2)
            top.plot(d.gaps[:, 0], d.gaps[:, 1], color="tab:blue", linewidth=1.6)
            top.plot(0, 0, "*", color="gold", mec="k", ms=10)
            top.plot(d.gaps[0, 0], d.gaps[0, 1], "ko", ms=4)
            top.set_aspect("equal", adjustable="datalim")
            top.set_xlabel("x_F [m]")
            top.set_ylabel("y_F [m]")
            top.set_title("top view (frame F)", fontsize=9)
            side.plot(d.t, d.gaps[:, 2], color="tab:blue", linewidth=1.6)
            side.axvline(s.touchdown, color="0.4", linestyle="-.", linewidth=0.9)
            side.set_xlabel("t [s]")
            side.set_ylabel("height z_F [m]")
            side.set_title("height vs time", fontsize=9)
            fig.canvas.draw()
            buf = np.asarray(fig.canvas.buffer_rgba())[:, :, :3]
            self.background = np.ascontiguousarray(fit_into(buf, width, height, (255, 255, 255)))
            sy, sx = height / buf.shape[0], width / buf.shape[1]
            self.px_top = self._pixels(top, d.gaps[:, :2], buf.shape[0], sx, sy)
            self.px_side = self._pixels(
                side, np.column_stack([d.t, d.gaps[:, 2]]), buf.shape[0], sx, sy
            )

    @staticmethod
    def _pixels(ax: Any, xy: NDArray[np.float64], fig_h: int, sx: float, sy: float) -> Any:
        disp = ax.transData.transform(xy)
        return np.column_stack([disp[:, 0] * sx, (fig_h - disp[:, 1]) * sy])

    def frame(self, t_s: float) -> U8:
        import cv2

        img = self.background.copy()
        i = min(int(np.searchsorted(self.t, t_s)), self.t.shape[0] - 1)
        for px in (self.px_top, self.px_side):
            c = (round(float(px[i, 0])), round(float(px[i, 1])))
            cv2.circle(img, c, 6, (220, 30, 30), -1, cv2.LINE_AA)
            cv2.circle(img, c, 6, (0, 0, 0), 1, cv2.LINE_AA)
        return img


class _LidarPanel:
    """Bird's-eye rasters of the latest scan; the extent and colour range are fixed over
    the whole video (from the middle scan) so colours do not flicker."""

    def __init__(self, media: RunMedia, width: int, height: int) -> None:
        assert media.lidar is not None
        self.seq = media.lidar
        self.size = min(width, height)
        self.w, self.h = width, height
        mid = self.seq.read(len(self.seq) // 2)
        xyz = mid.xyz if mid.xyz.shape[0] else np.zeros((1, 3))
        r = np.linalg.norm(xyz[:, :2], axis=1)
        self.extent = float(max(np.percentile(r, 95) * 1.05, 2.0))
        lo, hi = np.percentile(xyz[:, 2], [2, 98])
        self.vmin, self.vmax = float(lo), float(max(hi, lo + 0.1))
        self._cache: tuple[int, U8] | None = None

    def frame(self, t_ns: int) -> U8:
        i = self.seq.index_at(t_ns)
        if self._cache is None or self._cache[0] != i:
            scan: LidarScan = self.seq.read(i)
            bev = bev_image(
                scan.xyz,
                scan.xyz[:, 2],
                self.size,
                self.extent,
                vmin=self.vmin,
                vmax=self.vmax,
                rings=_ring_step(self.extent),
            )
            img = fit_into(bev, self.w, self.h)
            label(img, f"LiDAR '{self.seq.name}' from above, colour = height", (6, 6))
            label(
                img,
                f"scan t = {scan.t_ns * 1e-9:.2f} s, rings every {_ring_step(self.extent):g} m",
                (6, self.h - 26),
            )
            self._cache = (i, img)
        return self._cache[1].copy()


def _ring_step(extent: float) -> float:
    for step in (1.0, 2.0, 5.0, 10.0, 20.0, 50.0):
        if extent / step <= 6:
            return step
    return 100.0


class _ImagePanel:
    def __init__(self, media: RunMedia, width: int, height: int) -> None:
        assert media.camera is not None
        self.seq = media.camera
        self.w, self.h = width, height
        self._cache: tuple[int, U8] | None = None

    def frame(self, t_ns: int) -> U8:
        i = self.seq.index_at(t_ns)
        if self._cache is None or self._cache[0] != i:
            img = fit_into(self.seq.read(i), self.w, self.h)
            label(img, f"camera '{self.seq.name}'  frame t = {self.seq.t_ns[i] * 1e-9:.2f} s")
            self._cache = (i, img)
        return self._cache[1].copy()


def make_preview(
    outdir: Path,
    out: Path | None = None,
    *,
    gif: bool | None = None,
    fps: float = 30.0,
    speed: float = 1.0,
    window_ms: float = 20.0,
    panel_width: int = 480,
    progress: bool = False,
) -> PreviewInfo:
    """Write the synchronized preview video of the run in ``outdir``.

    Args:
        out: MP4 or GIF path (default ``OUTDIR/preview.mp4`` / ``.gif``).
        gif: GIF instead of MP4 (default: from ``out``'s suffix).
        fps: video frame rate (GIF: at most 12).
        speed: trajectory seconds per video second (1 = real time).
        window_ms: event accumulation window, ms.
        panel_width: width of each of the 2 x 2 panels, px (GIF: half).
    """
    import imageio_ffmpeg

    outdir = Path(outdir)
    if not outdir.is_dir():
        msg = f"{COMMAND}: {outdir} is not a directory (give a roslan simulate OUTDIR)"
        raise PlotError(msg)
    _check_rates(fps, speed, window_ms)
    out, gif = _output_path(outdir, out, gif)
    if gif:
        fps = min(fps, GIF_MAX_FPS)
        panel_width //= 2
    pw = max(16 * round(panel_width / 16), 64)
    ph = 16 * round(pw * 0.75 / 16)
    hdr = 32 if not gif else 24
    W, H = 2 * pw, 2 * ph + hdr

    media = RunMedia.open(outdir, COMMAND)
    try:
        if (
            media.traj is None
            and media.camera is None
            and media.events is None
            and media.lidar is None
        ):
            msg = (
                f"{COMMAND}: {outdir} has nothing to show (no trajectory.csv, images, events "
                "or LiDAR scans): give a roslan simulate OUTDIR"
            )
            raise PlotError(msg)
        duration_ns = media.duration_ns()
        step_ns = speed * 1e9 / fps
        n = math.floor(duration_ns / step_ns + 1e-9) + 1
        window_ns = round(window_ms * 1e6)
        inset = _TrajectoryInset(media.traj, pw, ph) if media.traj is not None else None
        lidar = _LidarPanel(media, pw, ph) if media.lidar is not None else None
        camera = _ImagePanel(media, pw, ph) if media.camera is not None else None
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(f".{out.stem}.part{out.suffix}")
        writer = imageio_ffmpeg.write_frames(str(tmp), (W, H), fps=fps, **_writer_options(gif))
        writer.send(None)
        try:
            canvas = np.empty((H, W, 3), np.uint8)
            for k in range(n):
                t_ns = round(k * step_ns)
                canvas[:] = BACKGROUND_RGB
                _header(canvas[:hdr], t_ns, duration_ns, speed, outdir.name)
                body = canvas[hdr:]
                body[:ph, :pw] = (
                    camera.frame(t_ns)
                    if camera is not None
                    else placeholder(pw, ph, "no camera configured")
                )
                body[:ph, pw:] = _events_frame(media, t_ns, window_ns, pw, ph)
                body[ph:, :pw] = (
                    lidar.frame(t_ns)
                    if lidar is not None
                    else placeholder(pw, ph, "no LiDAR configured")
                )
                body[ph:, pw:] = (
                    inset.frame(t_ns * 1e-9)
                    if inset is not None
                    else placeholder(pw, ph, "no trajectory.csv")
                )
                writer.send(np.ascontiguousarray(canvas))
                if progress and (k % 30 == 0 or k == n - 1):
                    _frame_progress(k, n)
            writer.close()
            if progress and sys.stderr.isatty():
                print(file=sys.stderr)  # end the line the counter overwrote
            os.replace(tmp, out)
        except BaseException:
            writer.close()
            tmp.unlink(missing_ok=True)
            raise
    finally:
        media.close()
    return PreviewInfo(out, n, fps, (W, H))


def _frame_progress(k: int, n: int) -> None:
    """``frame k+1/n`` on stderr: rewritten in place on a terminal, one line each
    elsewhere (a log, a pipe, a notebook)."""
    if sys.stderr.isatty():
        print(f"\rframe {k + 1}/{n}", end="", file=sys.stderr, flush=True)
    else:
        print(f"frame {k + 1}/{n}", file=sys.stderr, flush=True)


def _check_rates(fps: float, speed: float, window_ms: float) -> None:
    """Refuse a frame rate, speed or event window out of range (or not finite)."""
    for name, value, lo, hi in (
        ("--fps", fps, 0.0, 240.0),
        ("--speed", speed, 0.0, 1000.0),
        ("--window-ms", window_ms, 0.0, 1000.0),
    ):
        if not (math.isfinite(value) and lo < value <= hi):
            msg = f"{COMMAND}: {name} = {value}: must be in ({lo:g}, {hi:g}]"
            raise PlotError(msg)


def _output_path(outdir: Path, out: Path | None, gif: bool | None) -> tuple[Path, bool]:
    """(video path, whether it is a GIF): ``gif`` defaults to ``out``'s suffix, ``out`` to
    ``OUTDIR/preview.mp4`` / ``.gif``; a GIF always gets the ``.gif`` suffix."""
    if gif is None:
        gif = out is not None and Path(out).suffix.lower() == ".gif"
    if out is None:
        out = outdir / ("preview.gif" if gif else "preview.mp4")
    out = Path(out)
    if gif and out.suffix.lower() != ".gif":
        out = out.with_suffix(".gif")
    return out, gif


def _writer_options(gif: bool) -> dict[str, Any]:
    """imageio-ffmpeg options: a 192-colour palette GIF or an H.264 MP4."""
    kwargs: dict[str, Any] = {"macro_block_size": 16, "ffmpeg_log_level": "error"}
    if gif:
        kwargs |= {
            "codec": "gif",
            "pix_fmt_out": "pal8",
            "macro_block_size": 1,
            "output_params": [
                "-filter_complex",
                "split[a][b];[a]palettegen=max_colors=192[p];"
                "[b][p]paletteuse=dither=bayer:bayer_scale=4",
            ],
        }
    else:
        kwargs |= {"codec": "libx264", "pix_fmt_out": "yuv420p", "quality": 7}
    return kwargs


def _events_frame(media: RunMedia, t_ns: int, window_ns: int, pw: int, ph: int) -> U8:
    if media.events is None:
        return placeholder(pw, ph, "no event camera configured")
    img, count = render_events(media, t_ns - window_ns, t_ns)
    panel = fit_into(img, pw, ph)
    label(panel, f"events, last {window_ns / 1e6:g} ms: {count:,}  (blue ON, red OFF)")
    return panel


def _header(strip: U8, t_ns: int, duration_ns: int, speed: float, name: str) -> None:
    import cv2

    h, w = strip.shape[:2]
    strip[:] = (0, 0, 0)
    frac = min(max(t_ns / duration_ns, 0.0), 1.0) if duration_ns > 0 else 1.0
    strip[h - 3 :, : round(w * frac)] = (80, 160, 255)  # progress bar
    scale = 0.55 if h >= 30 else 0.42
    text = f"t = {t_ns * 1e-9:7.3f} s / {duration_ns * 1e-9:.3f} s"
    cv2.putText(
        strip, text, (8, h - 10), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA
    )
    right = f"{name}   x{speed:g} speed"
    (tw, _), _ = cv2.getTextSize(right, cv2.FONT_HERSHEY_SIMPLEX, scale * 0.85, 1)
    cv2.putText(
        strip,
        right,
        (w - tw - 8, h - 10),
        cv2.FONT_HERSHEY_SIMPLEX,
        scale * 0.85,
        (190, 190, 190),
        1,
        cv2.LINE_AA,
    )
