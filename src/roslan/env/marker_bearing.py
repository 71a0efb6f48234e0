"""Find the landing marker in a step's events: its bearing and, from its known size, the
camera's height above it.

The warehouse's helipad-style marker (``roslan.scene.textures.landing_marker``: a white
ring and a checker ring of 16 sectors around an H, on dark grey, 1.6 m square) has the
scene's highest-contrast edges: a moving camera's events pile up on them while the
concrete around gives a sparse speckle. Its geometry is known (:data:`RING_EDGES`), so a
candidate is verified by it, and its apparent size measures the range, as in the
classic onboard landing-pad detectors that find concentric rings of known radii and take
the height from their size (Lange, Suenderhauf and Protzel, "A vision based onboard
approach for landing and position control of an autonomous multirotor UAV in GPS-denied
environments", ICAR 2009).

Each step (only its last ``WINDOW_NS`` of events: a sliding camera smears the edges over
a whole step):

1. **Candidates.** The events are counted per pixel (at most ``MAX_COUNT`` each) and a
   matched filter of the white ring (+1 on the ring, -1 on the dark annuli beside it)
   is correlated with the image at scales ``SCALE_STEP`` apart over the heights
   ``HEIGHT_BAND`` times the caller's estimate (the height estimate need not be right),
   on an image binned so that the ring is about ``RING_PX`` px in radius; each scale's
   peak is a candidate.
2. **Fit.** The events within the white ring's band around a candidate are fitted with a
   circle (Kasa's algebraic least squares, twice, the band re-centred on the fit): the
   centre to a fraction of a pixel and the ring's radius ``r`` (px).
3. **Verification by the marker's geometry.** Around the fitted centre the events' radial
   density (events per pixel of circumference, over the part of each circle inside the
   image, relative to the image's mean event density) is scored at scales near
   ``r / RING_RADIUS``: both edges of the white ring (radii 0.528 and 0.592 m) and the
   checker ring's inner edge (0.656 m, on half its sectors) must be dense, and the dark
   annuli inside the white ring (0.44-0.51 m: nothing but the H's corners at 0.41 m) and
   between it and the checker ring (0.61-0.645 m) sparse: ``score = min(edge densities)
   / (1 + mean dark density)``. A circle in the floor's speckle, the marker's square,
   one checker sector, the H or a plain ring fail; the best candidate over
   ``MIN_SCORE`` is the marker, and the camera's height above it ``h_cam = f *
   RING_RADIUS / r`` (a pinhole camera looking down; a tilt of 0.15 rad changes it by
   1 %).

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

__all__ = ["RING_EDGES", "RING_RADIUS", "MarkerDetector", "MarkerFix"]

F64 = NDArray[np.float64]

RING_EDGES = (0.528, 0.592)
"""m: the inner and outer edge of the marker's white ring (0.66 and 0.74 of the 0.8 m
half-size of ``landing_marker``)."""
RING_RADIUS = 0.5 * (RING_EDGES[0] + RING_EDGES[1])
"""m: the white ring's mid radius, the radius its circle fit measures."""
CHECKER_INNER = 0.656
"""m: the inner edge of the checker ring (its white sectors: half the circle)."""
DARK_ANNULI = ((0.44, 0.51), (0.61, 0.645))
"""m: the annuli without edges inside the white ring (the H's corners end at 0.41 m) and
between it and the checker ring (from 0.656 m)."""


@dataclass(frozen=True)
class MarkerFix:
    """A marker found in one step: its centre ``u, v`` (ideal pixels), the white ring's
    radius (px), the camera's height above the marker from it (m) and the geometry
    score."""

    u: float
    v: float
    radius: float
    height: float
    score: float
    t_ns: int = 0
    """The mean time of the events it was found in (ns; 0 without times)."""


class MarkerDetector:
    """Detection of the landing marker in events (module docstring).

    Args:
        width, height: the event camera's resolution, px.
        focal: its focal length, px.
    """

    MAX_COUNT = 3
    """Events per pixel beyond which a pixel counts no more in the matched filter."""
    RING_PX = 20.0
    """px: the ring's radius in the binned image the matched filter runs on."""
    SCALE_STEP = 1.12
    """Ratio of consecutive scales of the matched filter."""
    HEIGHT_BAND = (0.6, 1.7)
    """The heights searched, as multiples of the caller's height estimate."""
    MIN_SCORE = 2.5
    """The geometry score a candidate needs to be the marker."""
    MIN_VISIBLE = 0.4
    """The part of the white ring that must lie inside the image."""
    MAX_EVENTS = 12000
    """Events the verification reads (an even stride beyond)."""
    WINDOW_NS = 8_000_000
    """ns: only the step's last events are read: a sliding camera smears an edge over
    the whole step (2.5 m/s at 2 m: 5 px in 20 ms)."""

    def __init__(self, width: int, height: int, focal: float) -> None:
        self.W, self.H = int(width), int(height)
        self.w, self.h = self.W // 2, self.H // 2
        self.focal = float(focal)
        self.tries = 0
        self.found = 0
        n = 96
        a = np.arange(n) * (2.0 * math.pi / n)
        self._cos, self._sin = np.cos(a), np.sin(a)

    def visible(self, u: float, v: float, h_cam: float, margin: float = 0.0) -> bool:
        """Whether a marker centred at pixel ``u, v`` seen from ``h_cam`` m may be in the
        view: the centre inside the image or within the ring's radius (plus ``margin`` px,
        the prediction's uncertainty) of it, and the ring not much larger than the
        image."""
        if not (h_cam > 0.2 and math.isfinite(u) and math.isfinite(v)):
            return False
        r = self.focal * RING_RADIUS / h_cam
        m = r + margin
        return r < 1.6 * self.H and -m <= u < self.W + m and -m <= v < self.H + m

    def _visible_fraction(self, cu: float, cv: float, radii: F64) -> F64:
        """(len(radii),) the part of each circle about ``cu, cv`` inside the image."""
        x = cu + radii[:, None] * self._cos[None, :]
        y = cv + radii[:, None] * self._sin[None, :]
        inside = (x >= 0) & (x < self.W) & (y >= 0) & (y < self.H)
        return np.asarray(inside.mean(axis=1), dtype=np.float64)

    def score(self, x: F64, y: F64, cu: float, cv: float, scales: F64) -> tuple[F64, F64]:
        """The geometry score (module docstring) of a marker centred at ``cu, cv`` at each
        scale in ``scales`` (px per m), and the white ring's visible fraction there."""
        r_max = float(scales.max()) * DARK_ANNULI[1][1] + 3.0
        nb = int(r_max) + 2
        d = np.hypot(x - cu, y - cv)
        counts = np.bincount(np.minimum(d, nb - 1).astype(np.int64), minlength=nb)[:nb]
        radii = np.arange(nb, dtype=np.float64) + 0.5
        frac = self._visible_fraction(cu, cv, radii)
        bg = len(x) / float(self.W * self.H)  # events per px^2
        with np.errstate(divide="ignore", invalid="ignore"):
            dens = counts / (2.0 * math.pi * radii * np.maximum(frac, 1e-3) * bg)
        dens[frac < 0.1] = np.nan
        # a 3-px running maximum: an edge blurred over a pixel or two, a centre off by one
        pad = np.concatenate([[np.nan], dens, [np.nan]])
        peak = np.fmax(np.fmax(pad[:-2], pad[1:-1]), pad[2:])  # fmax: nan only if all are

        def at(r: F64, arr: F64) -> F64:
            i = np.clip(np.round(r - 0.5).astype(np.int64), 0, nb - 1)
            return arr[i]

        e0, e1 = at(scales * RING_EDGES[0], peak), at(scales * RING_EDGES[1], peak)
        # the checker ring's inner edge: on half the sectors
        e2 = 2.0 * at(scales * CHECKER_INNER, peak)
        dark = []
        for lo, hi in DARK_ANNULI:
            steps = np.linspace(0.0, 1.0, 5)
            rr = scales[:, None] * (lo + (hi - lo) * steps[None, :])
            vals = at(rr, dens)
            ok = np.isfinite(vals)
            with np.errstate(invalid="ignore", divide="ignore"):
                dark.append(np.where(ok, vals, 0.0).sum(axis=1) / ok.sum(axis=1))
        dark_mean = 0.5 * (dark[0] + dark[1])
        s = np.minimum(np.minimum(e0, e1), e2) / (1.0 + dark_mean)
        vis = at(scales * RING_RADIUS, frac)
        return np.nan_to_num(s, nan=0.0), vis

    def _fit(self, x: F64, y: F64, cu: float, cv: float, r: float) -> tuple[float, float, float]:
        """Circle fit (Kasa's algebraic least squares) of the events within the white
        ring's band around ``cu, cv, r``; twice, the band re-centred."""
        half = 0.5 * (RING_EDGES[1] - RING_EDGES[0]) / RING_RADIUS + 0.06
        for _ in range(2):
            d = np.hypot(x - cu, y - cv)
            sel = np.abs(d - r) < half * r
            if int(sel.sum()) < 30:
                break
            xs, ys = x[sel], y[sel]
            A = np.stack([xs, ys, np.ones_like(xs)], axis=1)
            b = xs * xs + ys * ys
            sol, *_ = np.linalg.lstsq(A, b, rcond=None)
            cu, cv = 0.5 * sol[0], 0.5 * sol[1]
            rr = float(sol[2] + cu * cu + cv * cv)
            if rr <= 1.0:
                break
            r = math.sqrt(rr)
        return float(cu), float(cv), float(r)

    def _kernel(self, r: float) -> NDArray[np.float32]:
        """The matched filter of the white ring of radius ``r`` px: +1 on the ring, -1 on
        the dark annuli (each normalised to unit sum), 0 elsewhere."""
        n = math.ceil(r * DARK_ANNULI[1][1] / RING_RADIUS) + 1
        g = np.arange(-n, n + 1, dtype=np.float64)
        m = np.hypot(g[None, :], g[:, None]) * (RING_RADIUS / r)  # in metres of the marker
        pos = (m >= RING_EDGES[0] - 0.013) & (m <= RING_EDGES[1] + 0.013)
        neg = ((m >= DARK_ANNULI[0][0]) & (m <= DARK_ANNULI[0][1])) | (
            (m >= DARK_ANNULI[1][0]) & (m <= DARK_ANNULI[1][1])
        )
        k = pos / max(int(pos.sum()), 1) - neg / max(int(neg.sum()), 1)
        return np.asarray(k, dtype=np.float32)

    def _candidates(
        self, img: NDArray[np.float32], scales: F64
    ) -> list[tuple[float, float, float]]:
        """(u, v, scale) candidates: the matched filter's peak at each scale, on an image
        binned so that the ring's radius is about ``RING_PX`` px."""
        import cv2

        out = []
        for s in scales:
            r_full = s * RING_RADIUS
            b = max(1, round(r_full / self.RING_PX))
            if b > 1:
                small = cv2.resize(img, (self.W // b, self.H // b), interpolation=cv2.INTER_AREA)
            else:
                small = img
            # padded by most of the ring: a centre just outside the image is found too
            pad = int(0.7 * r_full / b) + 1
            big = cv2.copyMakeBorder(small, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
            resp = cv2.filter2D(big, -1, self._kernel(r_full / b), borderType=cv2.BORDER_CONSTANT)
            j = int(np.argmax(resp))
            cy, cx = divmod(j, resp.shape[1])
            out.append((b * (cx - pad + 0.5), b * (cy - pad + 0.5), float(s)))
        return out

    def find(
        self,
        x: NDArray[Any],
        y: NDArray[Any],
        h_cam: float,
        predicted: tuple[float, float] | None = None,
        gate: float = math.inf,
        t: NDArray[Any] | None = None,
        band: tuple[float, float] | None = None,
    ) -> MarkerFix | None:
        """The marker in the events ``x, y`` (ideal pixels; times ``t`` ns, if given: the
        last :attr:`WINDOW_NS` are read), the camera's height estimated at ``h_cam`` m
        (searched within ``band``, default :attr:`HEIGHT_BAND`, times it), within ``gate``
        px of ``predicted``; None if not found."""
        xf = np.asarray(x, dtype=np.float64)
        yf = np.asarray(y, dtype=np.float64)
        t_mean = 0
        if t is not None and len(xf):
            tt = np.asarray(t, dtype=np.int64)
            keep = tt >= int(tt[-1]) - self.WINDOW_NS
            xf, yf, tt = xf[keep], yf[keep], tt[keep]
            t_mean = int(tt[0]) + int(np.mean(tt - tt[0]))
        if len(xf) < 200 or not (h_cam > 0.1 and math.isfinite(h_cam)):
            return None
        self.tries += 1
        ix = np.clip(xf.astype(np.int64), 0, self.W - 1)
        iy = np.clip(yf.astype(np.int64), 0, self.H - 1)
        counts = np.bincount(iy * self.W + ix, minlength=self.W * self.H)
        img = np.minimum(counts, self.MAX_COUNT).astype(np.float32).reshape(self.H, self.W)
        lo_b, hi_b = band if band is not None else self.HEIGHT_BAND
        s_lo, s_hi = self.focal / (hi_b * h_cam), self.focal / (lo_b * h_cam)  # px per m
        n_s = max(2, math.ceil(math.log(s_hi / s_lo) / math.log(self.SCALE_STEP)) + 1)
        cands = self._candidates(img, np.geomspace(s_lo, s_hi, n_s))
        if len(xf) > self.MAX_EVENTS:
            stride = -(-len(xf) // self.MAX_EVENTS)
            xs, ys = xf[::stride], yf[::stride]
        else:
            xs, ys = xf, yf
        best: tuple[float, float, float, float] | None = None
        for cu0, cv0, s0 in cands:
            # the circle fit first: the filter's peak is a binned pixel, the edges are thin
            cu, cv, r = self._fit(xs, ys, cu0, cv0, s0 * RING_RADIUS)
            if not (0.85 * s0 < r / RING_RADIUS < 1.15 * s0):
                continue
            if predicted is not None and math.hypot(cu - predicted[0], cv - predicted[1]) > gate:
                continue
            scales = (r / RING_RADIUS) * np.geomspace(0.96, 1.04, 5)
            sc, vis = self.score(xs, ys, cu, cv, scales)
            sc = np.where(vis >= self.MIN_VISIBLE, sc, 0.0)
            j = int(np.argmax(sc))
            if sc[j] >= self.MIN_SCORE and (best is None or sc[j] > best[0]):
                best = (float(sc[j]), cu, cv, r)
        if best is None:
            return None
        sc_best, u, v, r = best
        self.found += 1
        return MarkerFix(u, v, r, self.focal * RING_RADIUS / r, sc_best, t_mean)
