"""Event frames on a bag topic, so bag viewers show the events as an image.

RViz and Foxglove cannot draw ``dvs_msgs/EventArray``; rpg_dvs_ros' ``dvs_renderer``
node does it live. ``<topic>/event_image`` (``sensor_msgs/Image``, ``rgb8``, the event
camera's ``event_image: true``, the default) carries the same picture in the bag: at each
``camera_info`` instant t, the events of ``(t - event_image_window, t]`` on white, ON blue
(0, 0, 255) and OFF red (255, 0, 0), the later event winning where a pixel has both, in
the optical frame. Sparse frames: a few kB each after bag compression.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from roslan.events.model import EventBatch

__all__ = ["OFF_RGB", "ON_RGB", "RecentEvents"]

ON_RGB = (0, 0, 255)
OFF_RGB = (255, 0, 0)


class RecentEvents:
    """The events of the last ``window_ns`` (memory: one window of events)."""

    def __init__(self, width: int, height: int, window_ns: int) -> None:
        self.width = width
        self.height = height
        self.window_ns = max(1, int(window_ns))
        self._batches: list[EventBatch] = []

    def add(self, batch: EventBatch, t_ns: int) -> None:
        """Append the events of the frame at ``t_ns``; forget those older than the window."""
        if batch.size:
            self._batches.append(batch)
        cut = t_ns - self.window_ns
        self._batches = [b for b in self._batches if int(b.t[-1]) > cut]

    def frame(self, t_ns: int) -> NDArray[np.uint8]:
        """(H, W, 3) rgb8 picture of the events in ``(t_ns - window, t_ns]``."""
        img = np.full((self.height, self.width, 3), 255, np.uint8)
        if not self._batches:
            return img
        ev = EventBatch.concatenate(self._batches)
        sel = (ev.t > t_ns - self.window_ns) & (ev.t <= t_ns)
        x, y, p = ev.x[sel], ev.y[sel], np.asarray(ev.p[sel]) > 0
        colors = np.where(p[:, None], np.array(ON_RGB, np.uint8), np.array(OFF_RGB, np.uint8))
        img[y, x] = colors  # time order: the last event of a pixel wins
        return img
