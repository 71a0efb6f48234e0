"""``roslan plot shutter OUTDIR``: one frame-camera image beside the events of its
shutter window.

Left: the frame camera's image, blurred over its exposure and skewed by its rolling
shutter; right: the event camera's events of the same window (ON blue, OFF red) over
its APS frame nearest the stamp. The window is the frame's
``[t_start, t_start + readout_time * (H - 1) / H + E]`` (stamp in the middle,
docs/design.md §2), ``E`` from the camera's ``exposures.txt`` (else its
``exposure_time``) and ``readout_time`` from run.json. The frame: ``--time T`` (the one
nearest T s), else the one of the largest body pitch rate (``trajectory.csv``) in the
first 80 % of the flight, when the flapping shakes the camera most.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.plots.media import RunMedia, render_events
from roslan.plots.style import figure, save_figure, style
from roslan.rundir.readers import ImageSequence, load_trajectory_table, sensor_configs

__all__ = ["COMMAND", "ShutterPanels", "plot_shutter", "shutter_panels", "shutter_window"]

COMMAND = "roslan plot shutter"


def shutter_window(stamp_ns: int, exposure: float, readout: float, height: int) -> tuple[int, int]:
    """The shutter window ``[t0, t1)`` (ns) of the frame stamped ``stamp_ns``."""
    span = (readout * (height - 1) / height + exposure) * 1e9
    return round(stamp_ns - span / 2), round(stamp_ns + span / 2)


def _exposure(seq: ImageSequence, index: int, fallback: float) -> float:
    """Frame ``index``'s exposure from ``exposures.txt`` beside its listing."""
    path = seq.paths[0].parent.parent / "exposures.txt"
    if not path.is_file():
        return fallback
    try:
        data = np.atleast_2d(np.loadtxt(path, ndmin=2))
    except ValueError as err:
        msg = f"{COMMAND}: {path}: not a `t exposure` table ({err})"
        raise PlotError(msg) from None
    if data.shape[1] != 2 or index >= data.shape[0]:
        msg = f"{COMMAND}: {path}: expected {len(seq)} lines `t exposure`, got {data.shape}"
        raise PlotError(msg)
    return float(data[index, 1])


def _default_time(outdir: Path) -> float | None:
    """The instant of the largest |pitch rate| in the first 80 % of the flight."""
    try:
        table = load_trajectory_table(outdir, COMMAND)
    except PlotError:
        return None
    t = table.t
    keep = t <= 0.8 * float(t[-1])
    if not keep.any():
        return None
    q = np.abs(table.rates[keep, 4])
    return float(t[keep][int(np.argmax(q))])


@dataclass(frozen=True)
class ShutterPanels:
    """What the figure shows: the camera image, the event frame of its window, the
    events counted, the frame's stamp (ns), exposure and readout (s), the window (ns)."""

    image: NDArray[np.uint8]
    events: NDArray[np.uint8]
    count: int
    stamp_ns: int
    exposure: float
    readout: float
    window: tuple[int, int]


def shutter_panels(outdir: Path, time: float | None = None) -> ShutterPanels:
    """The panels of the frame nearest ``time`` (s; None: see the module docstring)."""
    media = RunMedia.open(outdir, COMMAND)
    try:
        cams = sensor_configs(outdir, "camera")
        seq = media.camera
        if media.events is None:
            msg = f"{COMMAND}: {outdir}: no events (add a `type: event_camera` sensor)"
            raise PlotError(msg)
        if not cams or seq is None or not len(seq) or media.camera_is_aps:
            msg = f"{COMMAND}: {outdir}: no frame-camera images (add a `type: camera` sensor)"
            raise PlotError(msg)
        cam = next((c for c in cams if c.get("name") == seq.name), cams[0])
        when = time if time is not None else _default_time(outdir)
        t_ns = int(seq.t_ns[len(seq) // 2]) if when is None else round(when * 1e9)
        index = seq.index_at(t_ns)
        stamp = int(seq.t_ns[index])
        img = seq.read(index)
        exposure = _exposure(seq, index, float(cam.get("exposure_time") or 0.0))
        readout = float(cam.get("readout_time") or 0.0)
        t0, t1 = shutter_window(stamp, exposure, readout, img.shape[0])
        t1 = max(t1, t0 + 1)
        background = media.aps.read(media.aps.index_at(stamp)) if media.aps else None
        events, count = render_events(media, t0, t1, background)
    finally:
        media.close()
    return ShutterPanels(img, events, count, stamp, exposure, readout, (t0, t1))


def plot_shutter(outdir: Path, output: Path | None = None, *, time: float | None = None) -> Path:
    """Draw the figure (see the module docstring); returns the PNG written."""
    outdir = Path(outdir)
    out = Path(output) if output is not None else outdir / "plots" / "shutter.png"
    return _draw(shutter_panels(outdir, time), out)


def _draw(p: ShutterPanels, out: Path) -> Path:
    img, events, count, stamp = p.image, p.events, p.count, p.stamp_ns
    exposure, readout, window = p.exposure, p.readout, p.window
    with style():
        h0, w0 = img.shape[:2]
        h1, w1 = events.shape[:2]
        width = 7.0
        height = width * max(h0 / w0, h1 / w1) / 2.0 + 0.45
        fig = figure(width, height)
        ax = fig.add_subplot(1, 2, 1)
        ax.imshow(img, cmap="gray" if img.ndim == 2 else None, vmin=0, vmax=255)
        shutter = "global shutter" if readout <= 0 else f"rolling, readout {readout * 1e3:g} ms"
        ax.set_title(
            f"camera, t = {stamp * 1e-9:.3f} s\nexposure {exposure * 1e3:.2f} ms, {shutter}",
            fontsize=8,
        )
        ax2 = fig.add_subplot(1, 2, 2)
        ax2.imshow(events)
        span = (window[1] - window[0]) * 1e-6
        ax2.set_title(
            f"events of the same {span:.2f} ms window\n{count} events (ON blue, OFF red)",
            fontsize=8,
        )
        for a in (ax, ax2):
            a.set_xticks([])
            a.set_yticks([])
            a.grid(False)
        return save_figure(fig, out)
