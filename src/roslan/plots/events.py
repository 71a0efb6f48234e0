"""``roslan plot events OUTDIR -o DIR``: event frames and the event rate.

Writes into DIR:

* ``event_frame_NN.png``: the events of one window (default 10 ms) drawn over the
  event camera's grayscale APS frame at that instant (or the run's first other image
  stream, or white): ON blue, OFF red, as the paper's Fig. 5a/c;
* ``event_frames.png``: those frames side by side with their times;
* ``event_rate.png``: ON and OFF events per second over the trajectory (10 ms bins).

Events come from ``events.h5`` (binary search per window) or ``events.txt`` (one
forward pass), so memory stays bounded by one window.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.plots.raster import event_frame
from roslan.plots.style import figure, save_figure, style
from roslan.rundir.events import EventSource, open_events
from roslan.rundir.readers import ImageSequence, find_images, sensor_configs

__all__ = ["event_rate", "plot_events"]

COMMAND = "roslan plot events"


def event_rate(
    src: EventSource, t0_ns: int, t1_ns: int, bin_ns: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Bin starts (N,) ns and ON / OFF counts (N,) per ``bin_ns`` bin over [t0, t1)."""
    starts = np.arange(t0_ns, t1_ns, bin_ns, dtype=np.int64)
    on = np.zeros(starts.size, np.int64)
    off = np.zeros(starts.size, np.int64)
    for i, a in enumerate(starts.tolist()):  # one window per bin: bounded memory
        _, _, p = src.window(a, a + bin_ns)
        on[i] = int(np.count_nonzero(p > 0))
        off[i] = int(p.size - on[i])
    return starts, on, off


def _background(seqs: list[ImageSequence], t_ns: int) -> NDArray[np.uint8] | None:
    if not seqs:
        return None
    seq = seqs[0]
    return seq.read(seq.index_at(t_ns))


def plot_events(
    outdir: Path,
    out: Path,
    *,
    window: float = 0.01,
    frames: int = 6,
    times: list[float] | None = None,
) -> list[Path]:
    """Draw the figures (see the module docstring); returns the files written."""
    outdir, out = Path(outdir), Path(out)
    if window <= 0 or not math.isfinite(window):
        msg = f"{COMMAND}: --window = {window}: must be a positive number of seconds"
        raise PlotError(msg)
    if frames < 1:
        msg = f"{COMMAND}: --frames = {frames}: must be >= 1"
        raise PlotError(msg)
    written: list[Path] = []
    names = [str(c.get("name")) for c in sensor_configs(outdir, "event_camera")]
    with open_events(outdir, COMMAND) as src:
        rng = src.time_range_ns()
        if rng is None:
            msg = f"{COMMAND}: {src.path} holds no events"
            raise PlotError(msg)
        width, height = src.width, src.height
        if width is None or height is None:
            # no metadata (events.txt without run.json): the extent of the events
            x, y, _ = src.window(rng[0], rng[1] + 1)
            width, height = int(x.max()) + 1, int(y.max()) + 1
        w_ns = round(window * 1e9)
        if times:
            starts = [round(t * 1e9) for t in times]
        else:
            span = max(rng[1] - rng[0] - w_ns, 0)
            starts = [rng[0] + round(span * (i + 0.5) / frames) for i in range(frames)]
        # the root images.txt is the first event camera's APS when events lie at the root
        # (named "images" while run.json is not written yet)
        root_aps = ["images"] if _root_has_events(outdir) else []
        seqs = find_images(outdir, prefer=[*names, *root_aps, "dvs", "aps"])
        out.mkdir(parents=True, exist_ok=True)
        imgs: list[tuple[int, NDArray[np.uint8], int]] = []
        for a in sorted(starts):
            x, y, p = src.window(a, a + w_ns)
            imgs.append(
                (
                    a,
                    event_frame(x, y, p, width, height, _background(seqs, a + w_ns // 2)),
                    int(p.size),
                )
            )
        import cv2

        for i, (_, img, _) in enumerate(imgs):
            path = out / f"event_frame_{i:02d}.png"
            cv2.imwrite(str(path), img[:, :, ::-1])
            written.append(path)
        with style():
            n = len(imgs)
            cols = min(n, 3)
            rows = math.ceil(n / cols)
            aspect = height / width
            fig = figure(3.2 * cols, 3.2 * rows * aspect + 0.5)
            for i, (a, img, count) in enumerate(imgs):
                ax = fig.add_subplot(rows, cols, i + 1)
                ax.imshow(img)
                ax.set_title(
                    f"t = {a * 1e-9:.3f} s, {window * 1e3:g} ms, {count} events", fontsize=8
                )
                ax.set_xlabel("u [px]", fontsize=7)
                ax.set_ylabel("v [px]", fontsize=7)
                ax.tick_params(labelsize=6)
                ax.grid(False)
            written.append(save_figure(fig, out / "event_frames.png"))
            bin_ns = 10_000_000
            b, on, off = event_rate(src, rng[0] - rng[0] % bin_ns, rng[1] + 1, bin_ns)
            fig = figure(7.0, 3.0)
            ax = fig.add_subplot(1, 1, 1)
            tt = b * 1e-9
            scale = 1e9 / bin_ns
            ax.bar(
                tt,
                on * scale,
                width=bin_ns * 1e-9,
                align="edge",
                color="tab:blue",
                label="ON",
                alpha=0.8,
            )
            ax.bar(
                tt,
                -off * scale,
                width=bin_ns * 1e-9,
                align="edge",
                color="tab:red",
                label="OFF",
                alpha=0.8,
            )
            ax.set_xlabel("trajectory time (s)")
            ax.set_ylabel("events / s (OFF negative)")
            ax.set_title(
                f"event rate, {bin_ns / 1e6:g} ms bins, {int(on.sum() + off.sum())} events"
            )
            ax.legend(loc="upper left")
            written.append(save_figure(fig, out / "event_rate.png"))
    return written


def _root_has_events(outdir: Path) -> bool:
    return (outdir / "events.txt").is_file() or (outdir / "events.h5").is_file()
