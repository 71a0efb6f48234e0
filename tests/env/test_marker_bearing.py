"""The landing marker's detector (roslan.env.marker_bearing) on synthetic events: the
marker's own texture (``landing_marker``) drawn at a known centre and scale, events
where its brightness changes, a speckle of noise events and decoys (a plain ring of the
same size, a bright square): the centre and the height come back; decoys alone do not
make a marker."""

from __future__ import annotations

import numpy as np
import pytest

from roslan.env.marker_bearing import RING_RADIUS, MarkerDetector
from roslan.scene.textures import landing_marker

W, H, F = 346, 260, 216.0
SIZE = 1.6  # m: the marker's square (the warehouse's)


def _edges_of(img: np.ndarray) -> np.ndarray:
    """Pixels where the brightness steps (a moving camera's events pile up there)."""
    gy, gx = np.gradient(np.log(img + 0.05))
    return np.hypot(gx, gy) > 0.15


def _marker_image(cu: float, cv: float, h_cam: float) -> np.ndarray:
    """(H, W) brightness of the marker seen from ``h_cam`` m straight above, centred at
    pixel ``cu, cv``, on a mid-grey floor."""
    tex = landing_marker(512).mean(axis=2) / 255.0
    s = F / h_cam  # px per m
    vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
    mx, my = (uu + 0.5 - cu) / s, (vv + 0.5 - cv) / s  # m from the centre
    i = np.floor((0.5 + my / SIZE) * 512).astype(np.int64)
    j = np.floor((0.5 + mx / SIZE) * 512).astype(np.int64)
    inside = (i >= 0) & (i < 512) & (j >= 0) & (j < 512)
    img = np.full((H, W), 0.45)
    img[inside] = tex[i[inside], j[inside]]
    return img


def _events(edges: np.ndarray, rng: np.random.Generator, noise: int) -> tuple[np.ndarray, ...]:
    """Events: ~3 per edge pixel (Poisson) plus ``noise`` uniform speckle events."""
    vv, uu = np.nonzero(edges)
    n = rng.poisson(3.0, size=uu.size)
    x = np.repeat(uu, n).astype(np.float64)
    y = np.repeat(vv, n).astype(np.float64)
    x = np.concatenate([x, rng.integers(0, W, noise)])
    y = np.concatenate([y, rng.integers(0, H, noise)])
    return x, y


def _decoys() -> np.ndarray:
    """A plain bright ring of the white ring's size and a bright square, elsewhere."""
    vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
    img = np.full((H, W), 0.45)
    r = np.hypot(uu - 80.0, vv - 140.0)
    img[(r > 50.0) & (r < 58.0)] = 0.95
    img[(np.abs(uu - 260.0) < 45.0) & (np.abs(vv - 130.0) < 45.0)] = 0.95
    return img


@pytest.mark.parametrize(("cu", "cv", "h_cam"), [(173.0, 130.0, 1.5), (230.0, 100.0, 2.2)])
def test_finds_the_marker_and_its_height_beside_decoys(cu: float, cv: float, h_cam: float) -> None:
    rng = np.random.default_rng(7)
    img = _marker_image(cu, cv, h_cam)
    mask = _edges_of(img)
    # the decoys where the marker's square is not
    dec = _edges_of(_decoys())
    s = F / h_cam
    vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
    far = (np.abs(uu - cu) > 0.85 * s) | (np.abs(vv - cv) > 0.85 * s)
    x, y = _events(mask | (dec & far), rng, 15000)
    det = MarkerDetector(W, H, F)
    # the caller's height 25 % low (the divergence's scale early on)
    fix = det.find(x, y, 0.75 * h_cam)
    assert fix is not None
    assert abs(fix.u - cu) < 1.5, (fix, cu)
    assert abs(fix.v - cv) < 1.5, (fix, cv)
    assert abs(fix.height / h_cam - 1.0) < 0.03, (fix.height, h_cam)
    assert abs(fix.radius - s * RING_RADIUS) < 0.03 * s * RING_RADIUS


def test_decoys_alone_are_no_marker() -> None:
    rng = np.random.default_rng(3)
    x, y = _events(_edges_of(_decoys()), rng, 15000)
    det = MarkerDetector(W, H, F)
    for h in (1.0, 1.5, 2.0):
        assert det.find(x, y, h) is None


def test_only_the_last_events_of_a_step_are_read() -> None:
    """Events older than the window (here: a marker 40 px away) do not pull the fix."""
    rng = np.random.default_rng(5)
    x0, y0 = _events(_edges_of(_marker_image(133.0, 130.0, 1.5)), rng, 5000)
    x1, y1 = _events(_edges_of(_marker_image(173.0, 130.0, 1.5)), rng, 5000)
    t = np.concatenate([np.full(x0.size, 1_000_000), np.full(x1.size, 19_000_000)])
    det = MarkerDetector(W, H, F)
    fix = det.find(np.concatenate([x0, x1]), np.concatenate([y0, y1]), 1.5, t=t)
    assert fix is not None
    assert abs(fix.u - 173.0) < 1.5, fix
    assert fix.t_ns == 19_000_000
