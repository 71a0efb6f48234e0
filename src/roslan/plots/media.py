"""What a run recorded, found once: the trajectory, camera frames, the event stream,
LiDAR scans. Each is optional (None when the run had no such sensor); the overview
and the preview video draw a placeholder panel for what is absent."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from roslan.errors import PlotError
from roslan.plots.raster import event_frame
from roslan.plots.trajectory import TrajectorySamples, load_samples
from roslan.rundir.events import EventSource, open_events
from roslan.rundir.readers import (
    ImageSequence,
    LidarSequence,
    find_images,
    find_lidar,
    sensor_configs,
)

__all__ = ["RunMedia", "render_events"]

U8 = NDArray[np.uint8]


@dataclass
class RunMedia:
    """The optional inputs of the overview and the preview.

    Attributes:
        traj: trajectory samples (None if trajectory.csv is missing).
        camera: frames for the camera panel (a frame camera's, else the event camera's
            grayscale frames), or None.
        camera_is_aps: ``camera`` holds an event camera's grayscale (APS) frames.
        aps: grayscale frames under the event panel (the event camera's own frames
            when it writes them, else the camera's), or None.
        events: the event stream, or None.
        lidar: the first LiDAR's scans, or None.
        problems: one line per input that exists but could not be read.
    """

    traj: TrajectorySamples | None
    camera: ImageSequence | None
    aps: ImageSequence | None
    events: EventSource | None
    lidar: LidarSequence | None
    problems: list[str]
    camera_is_aps: bool = False

    @classmethod
    def open(cls, outdir: Path, command: str) -> RunMedia:
        problems: list[str] = []
        traj = None
        try:
            traj = load_samples(outdir, command)
        except PlotError as err:
            problems.append(str(err))
        event_names = [
            str(c.get("name")) for c in sensor_configs(outdir, "event_camera")
        ] or _calib_names(outdir, "event_camera")
        seqs: list[ImageSequence] = []
        try:
            seqs = find_images(outdir)
        except PlotError as err:
            problems.append(str(err))

        cams = [str(c.get("name")) for c in sensor_configs(outdir, "camera")] or _calib_names(
            outdir, "camera"
        )
        # the root listing is named "images" by its file; it is the first event camera's
        # APS when the events lie at the root too, else the one camera's
        root_events = (outdir / "events.txt").is_file() or (outdir / "events.h5").is_file()
        root = event_names[:1] if root_events else cams if len(cams) == 1 else []
        if root:
            seqs = [replace(s, name=root[0]) if s.name == "images" else s for s in seqs]

        def is_event_cam(s: ImageSequence) -> bool:
            return s.name in event_names or (root_events and s.name == "images")

        frame_seqs = [s for s in seqs if not is_event_cam(s)]
        aps_seqs = [s for s in seqs if is_event_cam(s)]
        camera = next(iter(frame_seqs + aps_seqs), None)
        camera_is_aps = camera is not None and not frame_seqs
        aps = next(iter(aps_seqs + frame_seqs), None)
        events = None
        try:
            events = open_events(outdir, command)
        except PlotError as err:
            if "add a sensor" not in str(err):
                problems.append(str(err))
        lidar = None
        try:
            lidar = find_lidar(outdir, command)[0]
        except PlotError as err:
            if "add a sensor" not in str(err):
                problems.append(str(err))
        return cls(traj, camera, aps, events, lidar, problems, camera_is_aps)

    def close(self) -> None:
        if self.events is not None:
            self.events.close()

    def duration_ns(self) -> int:
        """The span to show: the trajectory's, else the longest recorded stream's."""
        if self.traj is not None:
            return round(float(self.traj.dense.t[-1]) * 1e9)
        ends = [0]
        for s in (self.camera, self.lidar):
            if s is not None and len(s):
                ends.append(int(s.t_ns[-1]))
        return max(ends)


def render_events(
    media: RunMedia, t0_ns: int, t1_ns: int, background: U8 | None = None
) -> tuple[U8, int]:
    """The event frame of ``[t0_ns, t1_ns)`` over ``background`` (else the grayscale frame
    at ``t1_ns``). Returns (H, W, 3) uint8 at sensor resolution and the event count."""
    assert media.events is not None
    ev = media.events
    x, y, p = ev.window(t0_ns, t1_ns)
    if background is None and media.aps is not None:
        background = media.aps.read(media.aps.index_at(t1_ns))
    w, h = ev.width, ev.height
    if w is None or h is None:
        if background is not None:
            h, w = background.shape[:2]
        else:
            w = int(x.max(initial=0)) + 1
            h = int(y.max(initial=0)) + 1
        ev.width, ev.height = w, h
    return event_frame(x, y, p, w, h, background), int(x.shape[0])


def _calib_names(outdir: Path, sensor_type: str) -> list[str]:
    """Names of the sensors of a type from ``calib/extrinsics.yaml`` (a run without
    run.json yet: ``roslan simulate`` draws the overview before writing run.json)."""
    import yaml

    try:
        with (outdir / "calib" / "extrinsics.yaml").open(encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
    except (OSError, yaml.YAMLError):
        return []
    sensors = data.get("sensors") if isinstance(data, dict) else None
    if not isinstance(sensors, dict):
        return []
    return [
        str(name)
        for name, cfg in sensors.items()
        if isinstance(cfg, dict) and cfg.get("type") == sensor_type
    ]
