"""Gaps in a pose file: bridged by minimum-jerk motion before the splines are fitted.

An interval between two poses longer than :data:`GAP_FACTOR` times the file's median
interval (and at most ``trajectory.max_gap``, else the file is refused) is a gap: nothing
is known of the motion inside it. A global interpolating spline would cross it with a
swing driven by its continuity conditions, not by the data (a quintic through 100 Hz poses
across a 0.9 s gap: several cm and degrees off the true path, see
tests/trajectory/test_file_gaps.py). Instead each gap is filled, at the median interval,
with samples of the minimum-jerk path between its two poses (Flash & Hogan 1985: the
quintic whose position, velocity and acceleration match the motion on both sides), the
velocity and acceleration at each side taken from a least-squares quadratic through the
poses of the last :data:`FIT_WINDOW_S` before the gap (the first after it); orientation
likewise, as a rotation vector relative to the midway rotation between the gap's two
poses. The splines then pass through the poses and the bridge samples alike: across the
gap the path blends the motion of its two sides and leaves the straight line between its
poses only as far as that motion implies.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["FIT_WINDOW_S", "GAP_FACTOR", "bridge_gaps", "find_gaps"]

F64 = NDArray[np.float64]

GAP_FACTOR = 4.0
"""An interval longer than this times the median interval is a gap."""
FIT_WINDOW_S = 0.25
"""Poses within this time of a gap's side (at least 5 median intervals) give its velocity
and acceleration."""


def find_gaps(t: F64) -> NDArray[np.intp]:
    """Indices i of the gaps (t[i], t[i + 1]) of strictly increasing times ``t``."""
    dt = np.diff(t)
    if dt.size == 0:
        return np.zeros(0, dtype=np.intp)
    return np.flatnonzero(dt > GAP_FACTOR * float(np.median(dt)))


def _side(t: F64, y: F64, t0: float, y0: F64, chord: F64) -> tuple[F64, F64, F64]:
    """(value, velocity, acceleration) at ``t0`` from a least-squares polynomial through
    the samples (t, y) of one side: a quadratic from 3 samples on, a line from 2; a single
    sample moves with the chord velocity. The value is the pose itself."""
    n = t.size
    if n < 2:
        return y0, chord, np.zeros_like(y0)
    deg = min(2, n - 1)
    x = t - t0
    V = np.vander(x, deg + 1, increasing=True)  # columns 1, x, x^2
    coef, *_ = np.linalg.lstsq(V, y, rcond=None)
    acc = 2.0 * coef[2] if deg == 2 else np.zeros_like(y0)
    return y0, coef[1], acc


def _min_jerk(
    ta: float, tb: float, a: tuple[F64, F64, F64], b: tuple[F64, F64, F64], ts: F64
) -> F64:
    """The quintic through (value, velocity, acceleration) ``a`` at ``ta`` and ``b`` at
    ``tb``, at instants ``ts``: (M, 3)."""
    from scipy.interpolate import BPoly

    cols = []
    for i in range(a[0].shape[0]):
        ends = [[a[0][i], a[1][i], a[2][i]], [b[0][i], b[1][i], b[2][i]]]
        cols.append(BPoly.from_derivatives([ta, tb], ends)(ts))
    return np.column_stack(cols)


def bridge_gaps(t: F64, p: F64, q: F64) -> tuple[F64, F64, F64, list[tuple[float, float]]]:
    """Fill every gap of a pose file with minimum-jerk samples (see the module docstring).

    Args:
        t: (N,) strictly increasing times, s.
        p: (N, 3) positions.
        q: (N, 4) unit quaternions x, y, z, w.
    Returns:
        (t, p, q) with the bridge samples inserted in time order, and the gaps as
        (start, end) times.
    """
    from scipy.spatial.transform import Rotation

    gaps = find_gaps(t)
    if gaps.size == 0:
        return t, p, q, []
    step = float(np.median(np.diff(t)))
    window = max(FIT_WINDOW_S, 5.0 * step)
    bounds = np.concatenate([[-1], gaps, [t.size - 1]])  # segment k: bounds[k]+1 .. bounds[k+1]
    ts_all, p_all, q_all = [t], [p], [q]
    for k, i in enumerate(gaps.tolist()):
        ta, tb = float(t[i]), float(t[i + 1])
        lo, hi = int(bounds[k]) + 1, int(bounds[k + 2])  # this gap's two segments
        left = np.arange(lo, i + 1)
        left = left[t[left] >= ta - window]
        right = np.arange(i + 1, hi + 1)
        right = right[t[right] <= tb + window]
        m = math.ceil((tb - ta) / step)
        ts = ta + (tb - ta) * np.arange(1, m) / m
        chord = (p[i + 1] - p[i]) / (tb - ta)
        pa = _side(t[left], p[left], ta, p[i], chord)
        pb = _side(t[right], p[right], tb, p[i + 1], chord)
        Ra, Rb = Rotation.from_quat(q[i]), Rotation.from_quat(q[i + 1])
        Rm = Ra * Rotation.from_rotvec(0.5 * (Ra.inv() * Rb).as_rotvec())  # midway rotation
        phi_l = (Rm.inv() * Rotation.from_quat(q[left])).as_rotvec().reshape(-1, 3)
        phi_r = (Rm.inv() * Rotation.from_quat(q[right])).as_rotvec().reshape(-1, 3)
        turn = (phi_r[0] - phi_l[-1]) / (tb - ta)
        ra = _side(t[left], phi_l, ta, phi_l[-1], turn)
        rb = _side(t[right], phi_r, tb, phi_r[0], turn)
        ts_all.append(ts)
        p_all.append(_min_jerk(ta, tb, pa, pb, ts))
        q_all.append((Rm * Rotation.from_rotvec(_min_jerk(ta, tb, ra, rb, ts))).as_quat())
    t2 = np.concatenate(ts_all)
    order = np.argsort(t2, kind="stable")
    spans = [(float(t[i]), float(t[i + 1])) for i in gaps.tolist()]
    return t2[order], np.concatenate(p_all)[order], np.concatenate(q_all)[order], spans
