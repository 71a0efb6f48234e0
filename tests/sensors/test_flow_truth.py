"""DSEC flow maps are the true displacement over ``flow_interval``, checked against a
reference built independently from the run's files (tests/helpers/flow_reference.py:
depth.h5, groundtruth.txt, calib/, OpenCV's lens model, ray casting of the scene's boxes),
with occluded pixels invalid and every interval inside the run.

One short landing with flapping (1.2 s) past a pillar in front of a wall, three small
event cameras: ``dvs`` pinhole, ``flow_interval: 0.04``; ``dvs2`` with barrel distortion,
``flow_interval: 0.1`` (DSEC's); ``dvs3`` pitched up to the sky, ``flow_sky: valid``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flow_reference import (
    Box,
    FlowRun,
    first_hit_depth,
    forward_rows,
    hidden_at_t1,
    load_flow_run,
    on_boxes,
    read_flow_png,
    reference_flow,
)
from pipeline_helpers import tree_bytes
from roslan.config.sim import SimConfig
from roslan.errors import ConfigError

PILLAR: Box = ((0.8, 0.3, 0.0), (1.0, 0.5, 3.0))
WALL: Box = ((2.9, -4.0, 0.0), (3.1, 4.0, 3.0))
BOXES = [PILLAR, WALL]

SCENE = """name: pillar_and_wall
objects:
  - name: floor
    primitive: {type: box, size: [12.0, 12.0, 0.1]}
    pose: {position: [0, 0, -0.05]}
    material: {color: [0.5, 0.5, 0.45]}
  - name: wall
    primitive: {type: box, size: [0.2, 8.0, 3.0]}
    pose: {position: [3.0, 0, 1.5]}
    material: {color: [0.7, 0.6, 0.5]}
  - name: pillar
    primitive: {type: box, size: [0.2, 0.2, 3.0]}
    pose: {position: [0.9, 0.4, 1.5]}
    material: {color: [0.3, 0.4, 0.8]}
"""

CAM: dict[str, Any] = {
    "type": "event_camera", "rate": 25.0, "resolution": [64, 48], "fx": 40.0,
    "max_rate": 150.0, "optic_flow": True, "depthmap": True, "pose": {"rpy": [0.0, 0.25, 0.0]},
}  # fmt: skip
CAMERAS: dict[str, tuple[str, dict[str, Any]]] = {
    "dvs": ("", {"flow_interval": 0.04}),
    "dvs2": (
        "dvs2",
        {"distortion_model": "plumb_bob", "distortion_coeffs": [-0.15, 0.02, 0.0, 0.0, 0.0]},
    ),
    "dvs3": (
        "dvs3",
        {"resolution": [32, 24], "fx": 20.0, "flow_interval": 0.04, "flow_sky": "valid",
         "pose": {"rpy": [0.0, -0.3, 0.0]}},
    ),
}  # fmt: skip


def _config(scene: Path) -> SimConfig:
    sensors = [
        {**CAM, "name": name, "topic": f"/{name}", **over} for name, (_, over) in CAMERAS.items()
    ]
    return SimConfig.model_validate(
        {
            # T = 1 s, 0.2 s hold; flapping at 6 Hz: several strokes inside each interval
            "trajectory": {
                "k": 0.5,
                "initial": {"position": [-1.0, 1.2, 1.0], "descent_rate": 2.0},
                "hold": 0.2,
                "flapping": {"frequency": 6.0, "heave": 0.05, "pitch": 0.15},
            },
            "sensors": sensors,
            # 100 Hz: every t0 and t1 (multiples of 40 ms, + 40 or 100 ms) is a row
            "output": {"ground_truth_rate": 100.0},
            "scene": str(scene),
            "seed": 5,
        }
    )


@pytest.fixture(scope="module")
def flow_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    """The landing simulated in one process and with two worker processes."""
    pytest.importorskip("roslan.render.gl")
    from roslan.pipeline import run_simulation

    tmp = tmp_path_factory.mktemp("flow")
    scene = tmp / "pillar.yaml"
    scene.write_text(SCENE, encoding="utf-8")
    outs = {}
    for workers in (0, 2):
        outs[workers] = tmp / f"w{workers}"
        run_simulation(_config(scene), outs[workers], quiet=True, workers=workers, overview=False)
    return outs


def _maps(run: FlowRun) -> list[tuple[int, int, Any, Any]]:
    """(t0 ns, t1 ns, flow, valid) of every flow map of the camera."""
    out = []
    for i, (a, b) in enumerate(forward_rows(run.folder)):
        flow, valid = read_flow_png(run.folder / "flow" / "forward" / f"{i:06d}.png")
        out.append(((a - run.start_us) * 1000, (b - run.start_us) * 1000, flow, valid))
    assert len(list((run.folder / "flow" / "forward").glob("*.png"))) == len(out)
    return out


@pytest.mark.parametrize("camera", ["dvs", "dvs2", "dvs3"])
def test_flow_is_the_true_displacement(flow_runs: dict[int, Path], camera: str) -> None:
    """Endpoint error against the independent reference, on valid pixels: median <= 0.05
    px, 95th percentile <= 0.3 px (the PNG's 1/128 px steps: <= 0.0055 px)."""
    folder, _ = CAMERAS[camera]
    run = load_flow_run(flow_runs[0], camera, folder)
    maps = _maps(run)
    assert len(maps) >= 20
    errors, n_valid, n_pixels, sky_valid = [], 0, 0, 0
    for t0, t1, flow, valid in maps:
        ref, _, _ = reference_flow(run, t0, t1)
        assert np.all(np.isfinite(ref[valid]))
        errors.append(np.hypot(*(flow[valid] - ref[valid]).T))
        n_valid += int(valid.sum())
        n_pixels += valid.size
        (k,) = np.flatnonzero(run.depth_t_ns == t0)
        sky_valid += int((valid & ~np.isfinite(run.depth[k])).sum())
    epe = np.concatenate(errors)
    assert float(np.median(epe)) <= 0.05
    assert float(np.percentile(epe, 95)) <= 0.3
    assert n_valid > 0.6 * n_pixels  # most pixels have ground truth
    if camera == "dvs3":  # pitched up, flow_sky: valid: sky pixels carry the rotation's flow
        assert sky_valid > 0.05 * n_pixels
    else:
        assert sky_valid == 0


def _occlusions(run: FlowRun, t0: int, t1: int, valid: Any) -> tuple[Any, Any]:
    """Pixels roslan marks occluded, and the reference's occluded ones: points on a
    surface at t0, in the image at t1, whose sight line at t1 passes through a box
    (``hidden``) and that lie 2 % behind the first surface on every ray of the 3x3 pixels
    around their t1 pixel (``behind_all``: roslan's documented rule, by ray casting)."""
    ref, P_w, C1 = reference_flow(run, t0, t1)
    H, W = valid.shape
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    p1 = np.stack([u + ref[..., 0], v + ref[..., 1]], -1)
    cand = (p1[..., 0] >= -0.5) & (p1[..., 0] < W - 0.5)
    cand &= (p1[..., 1] >= -0.5) & (p1[..., 1] < H - 0.5) & np.all(np.isfinite(P_w), -1)
    cand[cand] = on_boxes(P_w[cand], BOXES)
    hidden = np.zeros((H, W), bool)
    hidden[cand] = hidden_at_t1(C1, P_w[cand], BOXES)
    ys, xs = np.nonzero(hidden)
    (i1,) = np.flatnonzero(run.gt_t_ns == t1)
    T1 = run.gt_T_wb[i1] @ run.T_base_opt
    z1 = (P_w[ys, xs] - T1[:3, 3]) @ T1[:3, 2]
    deep = np.ones(ys.size, bool)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            q = np.stack(
                [
                    np.clip(np.rint(p1[ys, xs, 0]) + di, 0, W - 1),
                    np.clip(np.rint(p1[ys, xs, 1]) + dj, 0, H - 1),
                ],
                1,
            )
            deep &= z1 > first_hit_depth(run, T1, q, BOXES) * 1.02
    behind_all = np.zeros((H, W), bool)
    behind_all[ys[deep], xs[deep]] = True
    return cand & ~valid, behind_all


def test_occluded_pixels_are_invalid(flow_runs: dict[int, Path]) -> None:
    """The pillar passing in front of the wall: the pixels whose point is hidden at t1 are
    invalid, counted independently by ray casting the scene's boxes."""
    for camera in ("dvs", "dvs2"):  # pinhole; distorted (depth ray cast along each ray)
        folder, _ = CAMERAS[camera]
        run = load_flow_run(flow_runs[0], camera, folder)
        n_roslan = n_ref = n_diff = 0
        for t0, t1, _, valid in _maps(run):
            occluded, behind_all = _occlusions(run, t0, t1, valid)
            n_roslan += int(occluded.sum())
            n_ref += int(behind_all.sum())
            n_diff += int((occluded ^ behind_all).sum())
        assert n_ref >= 150, camera
        assert n_roslan == n_ref, camera
        assert n_diff <= 2, camera


def test_every_interval_is_inside_the_run(flow_runs: dict[int, Path]) -> None:
    """Every forward_timestamps.txt row lies in [first event, last ground-truth sample];
    the maps are those of every ground-truth instant after the first event whose interval
    ends by the end of the run; each spans flow_interval."""
    import h5py

    out = flow_runs[0]
    gt_last_us = round(np.loadtxt(out / "groundtruth.txt")[-1, 0] * 1e6)
    for camera, (folder, over) in CAMERAS.items():
        run = load_flow_run(out, camera, folder)
        rows = forward_rows(run.folder) - run.start_us
        with h5py.File(run.folder / "events.h5", "r") as f:
            t_ev = f["events/t"]
            first_ev = int(t_ev[0])
        assert rows.shape[0] >= 10
        assert rows[0, 0] >= first_ev
        assert rows[-1, 1] <= gt_last_us
        interval_us = round(over.get("flow_interval", 0.1) * 1e6)
        np.testing.assert_array_equal(rows[:, 1] - rows[:, 0], interval_us)
        period = 40_000  # the 25 Hz ground-truth instants
        expect = np.arange(0, gt_last_us - interval_us + 1, period)
        expect = expect[expect >= first_ev]
        np.testing.assert_array_equal(rows[:, 0], expect)


def test_outputs_identical_for_any_worker_count(flow_runs: dict[int, Path]) -> None:
    ref = tree_bytes(flow_runs[0])
    got = tree_bytes(flow_runs[2])
    assert {"flow/forward_timestamps.txt", "dvs2/flow/forward/000000.png"} <= set(ref)
    assert got.keys() == ref.keys()
    assert [k for k in ref if got[k] != ref[k]] == []


def test_run_readme_states_the_flow_settings(flow_runs: dict[int, Path]) -> None:
    text = (flow_runs[0] / "README.md").read_text()
    assert "flow_interval" in text
    assert "0.04 s" in text
    assert "distorted" in text
    assert "`flow_sky: invalid`" in text
    assert "px/s" in text  # the bag's optic_flow, defined beside the PNGs


@pytest.mark.parametrize(
    ("key", "value", "says"),
    [
        ("flow_interval", 0, "greater than 0"),
        ("flow_interval", 0.1000005, "whole number of microseconds"),
        ("flow_interval", 100.0, "less than or equal to 60"),
        ("flow_sky", "maybe", "'valid' or 'invalid'"),
    ],
)
def test_flow_keys_are_validated(tmp_path: Path, key: str, value: object, says: str) -> None:
    from roslan.config.base import load_yaml_model

    f = tmp_path / "cfg.yaml"
    f.write_text(
        "sensors:\n  - {type: event_camera, name: dvs, rate: 25, topic: /dvs, optic_flow: true, "
        f"{key}: {value!r}}}\n".replace("'", '"')
    )
    with pytest.raises(ConfigError) as err:
        load_yaml_model(SimConfig, f)
    msg = str(err.value)
    assert str(f) in msg
    assert key in msg
    assert says in msg


def test_render_helpers_give_the_same_ground_truth_depth(tmp_path: Path) -> None:
    """A distorted camera's ground-truth depth is ray cast along its output rays; a render
    helper process (its own ray caster) gives the same instants, depths and flow fields
    as this process, and the depth is the ray-cast one only at the truth instants."""
    pytest.importorskip("roslan.render.gl")
    from event_helpers import event_camera_and_context
    from roslan.events.sampling import AdaptiveSampler
    from roslan.sensors.base import sample_times_ns
    from roslan.sensors.cameras.event_chains import ChainFarm, chain_starts, render_chain
    from roslan.sensors.cameras.flow_truth import flow_end_times

    sensor, ctx = event_camera_and_context(
        tmp_path, 1, optic_flow=True, flow_interval=0.06, max_rate=100,
        distortion_model="plumb_bob", distortion_coeffs=[-0.2, 0.03, 0.0, 0.0, 0.0],
    )  # fmt: skip
    c = sensor.config
    end = int(ctx.trajectory.duration_ns)
    gt = sample_times_ns(c.rate, end)
    truth = np.union1d(gt, flow_end_times(gt, c.flow_interval_ns, end))
    assert truth.size > gt.size  # the intervals' ends are instants of their own
    sampler = AdaptiveSampler(c.sampling, c.adaptive_lambda, c.min_rate, c.max_rate, end, truth)
    starts = chain_starts(sampler)
    here = [
        inst
        for a, b in zip(starts, [*starts[1:], None], strict=True)
        for inst in render_chain(sensor, ctx, sampler, frozenset(truth.tolist()), a, b)
    ]
    with ChainFarm(sensor, ctx, sampler, truth, 1, render_here=False) as farm:
        helper = list(farm.instants())
    assert [i.t for i in helper] == [i.t for i in here]
    truth_set = set(truth.tolist())
    for a, b in zip(here, helper, strict=True):
        assert (a.depth is not None) == (a.t in truth_set)
        for x, y in ((a.lum, b.lum), (a.depth, b.depth), (a.flow, b.flow)):
            assert (x is None) == (y is None)
            if x is not None:
                np.testing.assert_array_equal(x, y)
    # ray cast: the depth of the surface on each pixel's own ray, not a remapped one
    inst = next(i for i in here if i.t in truth_set and i.t > 0)
    _, remapped, _, _ = sensor.render(ctx, inst.t, need_depth=True)
    assert inst.depth is not None
    assert remapped is not None
    differ = np.isfinite(inst.depth) & (inst.depth != remapped)
    assert differ.sum() > 0


def test_displacement_of_a_frontal_wall_in_closed_form() -> None:
    """Pinhole camera before a wall at z = 2 m: no motion, no flow; a sideways step of
    the camera by b moves every pixel by -f b / z; a nearer surface at t1 hides the
    points behind it (invalid), a farther one does not; sky invalid unless flow_sky."""
    from roslan.sensors.cameras.flow_truth import displacement_flow
    from roslan.sensors.cameras.model import CameraModel

    K = np.array([[50.0, 0.0, 15.5], [0.0, 50.0, 11.5], [0.0, 0.0, 1.0]])
    model = CameraModel(32, 24, K)
    u, v = np.meshgrid(np.arange(32.0), np.arange(24.0))
    rays = ((u - 15.5) / 50.0, (v - 11.5) / 50.0)
    wall = np.full((24, 32), 2.0, np.float32)
    still = displacement_flow(model, rays, wall, wall, np.eye(4))
    np.testing.assert_allclose(still, 0.0, atol=1e-12)
    T = np.eye(4)
    T[0, 3] = -0.04  # the camera moved 4 cm to +x: points move by -50 * 0.04 / 2 = -1 px
    flow = displacement_flow(model, rays, wall, wall, T)
    ok = np.isfinite(flow[..., 0])
    np.testing.assert_allclose(flow[ok], np.broadcast_to([-1.0, 0.0], flow[ok].shape), atol=1e-9)
    assert ok[:, 1:].all()
    assert not ok[:, 0].any()  # the first column leaves the image
    near = wall.copy()
    near[5:10, 5:10] = 1.0  # something 1 m away at t1
    far = wall.copy()
    far[5:10, 5:10] = 2.03  # 1.5 % farther: within the tolerance, still visible
    hidden = ~np.isfinite(displacement_flow(model, rays, wall, near, T)[..., 0]) & ok
    # hidden: the points (x, y) whose 3x3 pixels around (x - 1, y) are all on the patch
    expect = np.zeros((24, 32), bool)
    expect[6:9, 7:10] = True
    np.testing.assert_array_equal(hidden, expect)
    np.testing.assert_array_equal(displacement_flow(model, rays, wall, far, T), flow)
    sky = wall.copy()
    sky[:, :4] = np.inf
    assert np.isnan(displacement_flow(model, rays, sky, sky, T)[:, :4]).all()
    rot = displacement_flow(model, rays, sky, sky, T, sky_valid=True)
    np.testing.assert_allclose(rot[:, :4], 0.0, atol=1e-12)  # translation: nothing at infinity
