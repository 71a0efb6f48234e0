"""Event representations of the observation against direct counts."""

from __future__ import annotations

import numpy as np

from roslan.env.observe import EventPacket, event_count_image, event_voxel_grid


def _events(n: int = 500) -> EventPacket:
    rng = np.random.default_rng(2)
    t = np.sort(rng.integers(1_000, 21_000_000, n)).astype(np.int64)
    x = rng.integers(0, 8, n).astype(np.int32)
    y = rng.integers(0, 5, n).astype(np.int32)
    p = np.where(rng.random(n) < 0.4, 1, -1).astype(np.int8)
    return EventPacket(x, y, t, p)


def test_count_image_counts_each_polarity_per_pixel() -> None:
    ev = _events()
    img = event_count_image(ev.x, ev.y, ev.p, (5, 8))
    assert img.shape == (2, 5, 8)
    assert img.dtype == np.float32
    for yy in range(5):
        for xx in range(8):
            here = (ev.x == xx) & (ev.y == yy)
            assert img[1, yy, xx] == np.sum(here & (ev.p > 0))
            assert img[0, yy, xx] == np.sum(here & (ev.p < 0))


def test_voxel_grid_keeps_each_pixels_polarity_sum_and_time_order() -> None:
    ev = _events()
    grid = event_voxel_grid(ev.x, ev.y, ev.t, ev.p, (5, 8), 4, (0, 21_000_000))
    assert grid.shape == (4, 5, 8)
    net = event_count_image(ev.x, ev.y, ev.p, (5, 8))
    np.testing.assert_allclose(grid.sum(axis=0), net[1] - net[0], atol=1e-4)
    # one event at the span's end lands wholly in the last bin
    one = event_voxel_grid(
        np.array([3]), np.array([2]), np.array([21_000_000]), np.array([1]), (5, 8), 4,
        (0, 21_000_000),
    )  # fmt: skip
    assert one[3, 2, 3] == 1.0
    assert one.sum() == 1.0


def test_event_packet_reads_like_a_mapping() -> None:
    ev = _events(10)
    assert len(ev) == 10
    np.testing.assert_array_equal(ev["x"], ev.x)
    np.testing.assert_array_equal(ev.get("t"), ev.t)
    assert ev.get("nope", 3) == 3
    assert len(EventPacket.empty()) == 0


def test_event_packets_compare_by_content() -> None:
    a, b = _events(20), _events(20)
    assert a == b
    assert a != EventPacket(a.x, a.y, a.t, -a.p)


def test_typed_taps_read_like_mappings_and_recode_polarity() -> None:
    """The event camera taps 1 ON / 0 OFF (as ESIM makes them); the step's packet holds
    +1 / -1; a measurement reads like the mapping it replaced and compares by content."""
    from roslan.sensors.measurements import EventSamples, ImuSamples

    t = np.array([5, 9], np.int64)
    a = ImuSamples(t, np.ones((2, 3)), np.zeros((2, 3)))
    assert a["t"] is t
    assert "acc" in a
    assert "points" not in a
    assert a.get("points") is None
    assert a == ImuSamples(t.copy(), np.ones((2, 3)), np.zeros((2, 3)))
    assert a != ImuSamples(t, np.ones((2, 3)), np.full((2, 3), 1e-9))
    x = np.array([1, 2, 3], np.uint16)
    taps = [EventSamples(x, x, np.array([1, 2, 3], np.int64), np.array([1, 0, 1], np.int8))]
    packet = EventPacket.of(taps)
    np.testing.assert_array_equal(packet.p, [1, -1, 1])
    np.testing.assert_array_equal(packet.x, [1, 2, 3])
    assert packet.x.dtype == np.int32
    assert len(EventPacket.of([])) == 0
