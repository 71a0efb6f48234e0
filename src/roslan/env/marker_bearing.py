"""Find the landing marker in a step's events and give its bearing.

The warehouse's helipad-style marker (``roslan.scene.textures.landing_marker``: a white
ring and a checker ring of 16 sectors around an H, on dark grey, 1.6 m square) has the
scene's highest-contrast edges: a moving camera's events pile up on them while the
concrete around gives a sparse speckle. Each step the events are counted in 2x2-binned
pixels, the bins with at least ``MIN_COUNT`` events kept, and a circle Hough transform
(OpenCV's ``HOUGH_GRADIENT``) looks for the rings (radii between ``RING_RADII``, m,
scaled by the camera's estimated height); the strongest circle is the marker if it lies
within the gate of where the navigation filter predicts it, and the policy fuses it only
when two consecutive steps agree (a circle in the floor's speckle does not persist).
Concentric landing-pad rings found by a Hough transform are the classic onboard
landing-pad detector (Lange,
Suenderhauf and Protzel, "A vision based onboard approach for landing and position
control of an autonomous multirotor UAV in GPS-denied environments", ICAR 2009).

The marker's pixel, undistorted (the events are moved to their ideal positions first),
is a bearing: a unit ray in the camera. With the attitude estimate it is a ray in the
world; with the camera's height above the marker it is the marker's offset, so the
horizontal gaps: ``x = h_cam tan(bearing)``. The bearing and the height gap's tau thus
give the horizontal gaps' tau (``tau_x = x / x'``), which the policy couples to the
height gap's (Lee, "Guiding movement by coupling taus", Ecological Psychology 10, 1998).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["MarkerDetector", "MarkerFix"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class MarkerFix:
    """A marker found in one step: its centre ``u, v`` (ideal pixels) and radius (px)."""

    u: float
    v: float
    radius: float


class MarkerDetector:
    """Circle detection of the landing marker's rings (module docstring).

    Args:
        width, height: the event camera's resolution, px.
        focal: its focal length, px.
    """

    RING_RADII = (0.42, 0.72)
    """m: around the marker's white ring (0.53-0.59 m), wide for the height's error (the
    1.6 m square's inscribed circle, 0.8 m, stays out of the search)."""
    MIN_COUNT = 4
    """Events per 2x2 bin (one step) that make an edge pixel."""

    def __init__(self, width: int, height: int, focal: float) -> None:
        self.w, self.h = int(width) // 2, int(height) // 2
        self.focal = float(focal)
        self.tries = 0
        self.found = 0

    def visible(self, u: float, v: float, h_cam: float, margin: float = 0.0) -> bool:
        """Whether a marker centred at pixel ``u, v`` seen from ``h_cam`` m is whole enough
        in the view to be found: the inner ring's radius under 60 % of the image's height,
        the centre inside the image or within 30 % of that radius (plus ``margin`` px,
        the prediction's uncertainty) from it."""
        if not (h_cam > 0.2 and math.isfinite(u) and math.isfinite(v)):
            return False
        r = self.focal * self.RING_RADII[0] / h_cam
        m = 0.3 * r + margin
        return r < 1.2 * self.h and -m <= u < 2 * self.w + m and -m <= v < 2 * self.h + m

    def find(
        self,
        x: NDArray[Any],
        y: NDArray[Any],
        h_cam: float,
        predicted: tuple[float, float],
        gate: float,
    ) -> MarkerFix | None:
        """The marker in the events ``x, y`` (ideal pixels) seen from ``h_cam`` m, within
        ``gate`` px of ``predicted``; None if not found."""
        import cv2

        if len(x) < 200:
            return None
        self.tries += 1
        bx = np.clip((np.asarray(x, dtype=np.float64) * 0.5).astype(np.int64), 0, self.w - 1)
        by = np.clip((np.asarray(y, dtype=np.float64) * 0.5).astype(np.int64), 0, self.h - 1)
        counts = np.bincount(by * self.w + bx, minlength=self.w * self.h).reshape(self.h, self.w)
        edges = np.where(counts >= self.MIN_COUNT, 255, 0).astype(np.uint8)
        img = cv2.GaussianBlur(cv2.dilate(edges, np.ones((3, 3), np.uint8)), (0, 0), 1.5)
        f = 0.5 * self.focal / h_cam
        lo, hi = int(f * self.RING_RADII[0]), int(f * self.RING_RADII[1]) + 1
        circles = cv2.HoughCircles(
            img, cv2.HOUGH_GRADIENT, dp=1, minDist=4, param1=100, param2=20,
            minRadius=max(lo, 3), maxRadius=max(hi, 5),
        )  # fmt: skip
        if circles is None:
            return None
        c = np.asarray(circles[0][0], dtype=np.float64)  # the strongest
        u, v = 2.0 * c[0] + 0.5, 2.0 * c[1] + 0.5
        if math.hypot(u - predicted[0], v - predicted[1]) > gate:
            return None
        self.found += 1
        return MarkerFix(float(u), float(v), float(2.0 * c[2]))
