"""The event camera's time-parallel chains (roslan.sensors.cameras.event_chains): rendered
in this process or by render helper processes, in time order they are the instants and
the pixels of the plain serial sampler, exactly."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import psutil  # type: ignore[import-untyped]
import pytest

from event_helpers import event_camera_and_context
from roslan.errors import SensorError
from roslan.events.sampling import AdaptiveSampler
from roslan.sensors.base import sample_times_ns
from roslan.sensors.cameras import EventCamera
from roslan.sensors.cameras.event_chains import ChainFarm, chain_starts, render_chain


def _sampler(sensor: Any, ctx: Any) -> tuple[AdaptiveSampler, np.ndarray]:
    """The camera's sampler as its stream builds it (forced: camera_info and GT stamps)."""
    c = sensor.config
    end = int(ctx.trajectory.duration_ns)
    info = sample_times_ns(c.rate, end)
    gt = sample_times_ns(c.ground_truth_rate or c.rate, end) if c.optic_flow else info[:0]
    forced = np.union1d(info, gt)
    return AdaptiveSampler(c.sampling, c.adaptive_lambda, c.min_rate, c.max_rate, end, forced), gt


def _serial(sensor: Any, ctx: Any, sampler: AdaptiveSampler) -> list[tuple[int, np.ndarray, float]]:
    """Reference: one sequence of renders, each step lambda / max |flow| of its depth,
    as ESIM's adaptive sampler is defined (no chains); (t, luminance, max |flow|)."""
    out = []
    t: int | None = 0
    while t is not None:
        lum, depth, v, w = sensor.render(ctx, t, need_depth=True)
        speed = sensor.camera.max_flow_speed(depth, v, w)
        out.append((t, lum, speed))
        t = sampler.next_ns(t, speed)
    return out


def test_chains_in_order_are_the_serial_instants(tmp_path: Path) -> None:
    sensor, ctx = event_camera_and_context(tmp_path, 1)
    sampler, gt = _sampler(sensor, ctx)
    ref = _serial(sensor, ctx, sampler)
    starts = chain_starts(sampler)
    assert starts[0] == 0
    assert starts[1:] == sampler.forced.tolist()
    chains = [
        render_chain(sensor, ctx, sampler, frozenset(gt.tolist()), a, b)
        for a, b in zip(starts, [*starts[1:], None], strict=True)
    ]
    # each chain begins at its forced instant and stays before the next one
    for chain, a, b in zip(chains, starts, [*starts[1:], None], strict=True):
        assert chain[0].t == a
        assert b is None or chain[-1].t < b
    assert max(len(c) for c in chains) > 2  # the adaptive steps inside a chain are exercised
    got = [inst for chain in chains for inst in chain]
    assert [i.t for i in got] == [t for t, _, _ in ref]
    assert all(np.array_equal(i.lum, lum) for i, (_, lum, _) in zip(got, ref, strict=True))
    assert got[-1].t == int(ctx.trajectory.duration_ns)  # the end is always sampled
    # capped: lambda / max |flow| is shorter than 1 / max_rate (300 Hz)
    want = [s > 0 and sampler.lam / s * 1e9 < sampler.min_dt_ns for _, _, s in ref]
    assert [i.capped for i in got] == want
    assert 0 < sum(want) < len(want)


def _helpers() -> list[psutil.Process]:
    out = []
    for p in psutil.Process().children(recursive=True):
        try:
            if "event_chains" in " ".join(p.cmdline()) and p.status() != "zombie":
                out.append(p)
        except psutil.Error:
            continue
    return out


@pytest.mark.parametrize("over", [{}, {"optic_flow": True, "depthmap": True}])
def test_render_helpers_give_the_same_instants(tmp_path: Path, over: dict[str, Any]) -> None:
    """Two helper processes render every chain (this process only waits): the same
    instants, pixels, ground-truth flow and depth as one process; no helper is left."""
    sensor, ctx = event_camera_and_context(tmp_path, 1, **over)
    sampler, gt = _sampler(sensor, ctx)
    with ChainFarm(sensor, ctx, sampler, gt, 0) as farm:
        ref = list(farm.instants())
    assert farm.rendered_here == len(chain_starts(sampler))
    with ChainFarm(sensor, ctx, sampler, gt, 2, render_here=False) as farm:
        assert len(_helpers()) == 2
        got = list(farm.instants())
    assert farm.rendered_here == 0
    assert _helpers() == []
    assert [i.t for i in got] == [i.t for i in ref]
    for a, b in zip(got, ref, strict=True):
        assert np.array_equal(a.lum, b.lum)
        assert a.capped == b.capped
        for x, y in ((a.flow, b.flow), (a.depth, b.depth)):
            assert (x is None) == (y is None)
            assert x is None or np.array_equal(x, y, equal_nan=True)
    if over:  # ground truth comes back at ground-truth instants only
        gt_set = set(gt.tolist())
        assert {i.t for i in got if i.flow is not None} == gt_set
        assert {i.t for i in got if i.depth is not None} == gt_set


class FailingInHelperCamera(EventCamera):
    """Renders fail in a render helper process (which imports this class by name)."""

    def render(self, ctx: Any, t_ns: int, *, need_depth: bool, **kw: Any) -> Any:
        if "event_chains" in " ".join(psutil.Process().cmdline()):
            raise SensorError(f"lens cracked at {t_ns} ns")
        return super().render(ctx, t_ns, need_depth=need_depth, **kw)


def test_an_error_in_a_helper_is_raised_here_with_its_traceback(tmp_path: Path) -> None:
    """A sensor error inside a helper comes back as the same exception type and message,
    with the helper's traceback attached; no helper is left."""
    sensor, ctx = event_camera_and_context(tmp_path, 1)
    failing = FailingInHelperCamera(sensor.config)
    sampler, gt = _sampler(failing, ctx)
    with (
        pytest.raises(SensorError, match=r"lens cracked at \d+ ns") as info,
        ChainFarm(failing, ctx, sampler, gt, 1, render_here=False) as farm,
    ):
        list(farm.instants())
    cause = str(info.value.__cause__)
    assert "in the render helper process" in cause
    assert "raise SensorError" in cause
    assert _helpers() == []
