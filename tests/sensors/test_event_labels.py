"""Event-camera labels: events/label against an independent trimesh ray cast of the
exported scene at each event's pixel and time, tracks.npy against DSEC-Det's dtype and
the APS instance images, and the noise class of the generator's noise events."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import h5py
import numpy as np
import pytest
import trimesh
import yaml

from roslan.config.sim import SimConfig
from roslan.events.model import EventGenerator
from roslan.frames import rpy_to_matrix
from roslan.pipeline.run import run_simulation
from roslan.scene.classes import NOISE_CLASS_ID

DSEC_DET = np.dtype(
    [("t", "<u8"), ("x", "<f4"), ("y", "<f4"), ("w", "<f4"), ("h", "<f4"),
     ("class_id", "u1"), ("class_confidence", "<f4"), ("track_id", "<u4")]
)  # fmt: skip

JOB: dict[str, Any] = {
    "scene": "warehouse",
    "trajectory": {
        "k": 0.5,
        "initial": {"position": [-1.0, 0.5, 1.5], "rpy": [0.0, 0.0, 0.2], "descent_rate": 5.0},
        "hold": 0.0,
    },
    "output": {
        "labels": True,
        "workers": 0,
        "formats": ["ros1", "ros2"],
        "ground_truth_rate": 1000.0,
    },
    "sensors": [
        {
            "type": "event_camera",
            "name": "dvs",
            "rate": 20.0,
            "resolution": [64, 48],
            "distortion_model": "radtan",
            "distortion_coeffs": [-0.15, 0.03, 0.0, 0.0],
            "min_rate": 100.0,
            "max_rate": 300.0,
            "shot_noise_rate": 1.0,
            "leak_rate": 0.5,
            "write_txt": False,
        }
    ],
}


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("event_labels") / "out"
    run_simulation(SimConfig.model_validate(JOB), out, quiet=True, overview=False)
    return out


def _world(run: Path) -> tuple[trimesh.Trimesh, np.ndarray]:
    poses = yaml.safe_load((run / "scene" / "poses.yaml").read_text())
    meshes, owner = [], []
    for o in poses["objects"]:
        m = trimesh.load(run / "scene" / o["model"], force="mesh", process=False)
        T = np.eye(4)
        T[:3, :3] = rpy_to_matrix(np.asarray(o["rpy"], float)) * np.asarray(
            o.get("scale", [1, 1, 1]), float
        )
        T[:3, 3] = o["position"]
        m.apply_transform(T)
        meshes.append(m)
        owner += [o["name"]] * len(m.faces)
    return trimesh.util.concatenate(meshes), np.asarray(owner)


def _poses(run: Path, t: np.ndarray) -> np.ndarray:
    """(N, 4, 4) T_world_optical at times t (s): groundtruth.txt (1 kHz) interpolated."""
    gt = np.loadtxt(run / "groundtruth.txt")
    i = np.clip(np.searchsorted(gt[:, 0], t) - 1, 0, len(gt) - 2)
    a = ((t - gt[i, 0]) / (gt[i + 1, 0] - gt[i, 0]))[:, None]
    p = (1 - a) * gt[i, 1:4] + a * gt[i + 1, 1:4]
    q = (1 - a) * gt[i, 4:8] + a * gt[i + 1, 4:8]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    T = np.zeros((len(t), 4, 4))
    for k in range(len(t)):
        T[k] = trimesh.transformations.quaternion_matrix([q[k, 3], *q[k, :3]])
    T[:, :3, 3] = p
    link_optical = np.array([[0, 0, 1, 0], [-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 0, 1.0]])
    return T @ link_optical


def test_signal_events_carry_what_an_independent_ray_cast_sees(run: Path) -> None:
    with h5py.File(run / "events.h5") as f:
        t_ns = f["events/t_ns"][:] if "t_ns" in f["events"] else f["events/t"][:] * 1000
        x, y, label = f["events/x"][:], f["events/y"][:], f["events/label"][:]
        assert label.dtype == np.uint32
        assert label.shape == f["events/t"].shape
    cls, inst = label & 0xFFFF, label >> 16
    assert np.all(inst[cls == NOISE_CLASS_ID] == 0)
    signal = np.flatnonzero(cls != NOISE_CLASS_ID)
    rng = np.random.default_rng(1)
    pick = rng.choice(signal, size=min(400, signal.size), replace=False)
    instances = {i["id"]: i for i in json.loads((run / "instances.json").read_text())}
    calib = yaml.safe_load((run / "calib" / "dvs.yaml").read_text())
    K = np.array(calib["camera_matrix"]["data"]).reshape(3, 3)
    D = np.array(calib["distortion_coefficients"]["data"])
    mesh, owner = _world(run)
    T = _poses(run, t_ns[pick] * 1e-9)
    offsets = np.array([[0, 0], [0.45, 0], [-0.45, 0], [0, 0.45], [0, -0.45]])
    ok = np.zeros(pick.size, bool)
    for off in offsets:
        uv = np.stack([x[pick], y[pick]], 1).astype(np.float64) + off
        xy = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, D).reshape(-1, 2)
        d = np.einsum("nij,nj->ni", T[:, :3, :3], np.column_stack([xy, np.ones(len(xy))]))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        tri, ray, loc = mesh.ray.intersects_id(
            T[:, :3, 3], d, multiple_hits=False, return_locations=True
        )
        for r, f_, p in zip(ray, tri, loc, strict=True):
            i = int(inst[pick[r]])
            if i == 0 or ok[r]:
                continue
            b = instances[i]["box3d"]
            local = (p - np.asarray(b["center"])) @ rpy_to_matrix(np.asarray(b["rpy"]))
            inside = np.all(np.abs(local) <= np.asarray(b["size"]) / 2 + 0.01)
            ok[r] = owner[f_] == instances[i]["object"] and bool(inside)
    assert ok.mean() >= 0.95, ok.mean()


def test_tracks_are_dsec_det_boxes_of_the_aps_instance_images(run: Path) -> None:
    tracks = np.load(run / "tracks.npy")
    assert tracks.dtype == DSEC_DET
    lines = (run / "images.txt").read_text().split()
    stamps_us = [round(float(s) * 1e6) for s in lines[0::2]]
    assert len(stamps_us) > 5
    assert set(np.unique(tracks["t"]).tolist()) <= set(stamps_us)
    for k, t_us in enumerate(stamps_us):
        inst = cv2.imread(str(run / "instance" / f"{k:08d}.png"), cv2.IMREAD_UNCHANGED)
        rows = tracks[tracks["t"] == t_us]
        assert sorted(rows["track_id"].tolist()) == sorted(np.unique(inst[inst > 0]).tolist())
        for r in rows:
            ys, xs = np.nonzero(inst == r["track_id"])
            box = [xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1]
            assert [r["x"], r["y"], r["w"], r["h"]] == box
            assert r["class_confidence"] == 1.0


def _tight_boxes(inst: np.ndarray) -> list[tuple[float, float, float, float, int]]:
    """Per instance id of ``inst`` (ascending): its tight box's centre and size, its id."""
    out = []
    for k in np.unique(inst[inst > 0]).tolist():
        ys, xs = np.nonzero(inst == k)
        w, h = xs.max() - xs.min() + 1, ys.max() - ys.min() + 1
        out.append((xs.min() + w / 2, ys.min() + h / 2, float(w), float(h), k))
    return out


def test_aps_label_topics_decode_in_both_bags(run: Path) -> None:
    from rosbags.highlevel import AnyReader

    instances = {i["id"]: i["class_id"] for i in json.loads((run / "instances.json").read_text())}
    n_aps = len((run / "images.txt").read_text().split()) // 2
    for bag in (run / "landing.bag", run / "landing_ros2"):
        with AnyReader([bag]) as reader:
            conns = [c for c in reader.connections if c.topic.startswith("/dvs/")]
            types = {c.topic: c.msgtype for c in conns}
            assert types["/dvs/detections"] == "vision_msgs/msg/Detection2DArray"
            assert types["/dvs/instance"] == types["/dvs/semantic"] == "sensor_msgs/msg/Image"
            seen = {"/dvs/instance": 0, "/dvs/semantic": 0, "/dvs/detections": 0}
            for conn, _, raw in reader.messages(connections=conns):
                if conn.topic not in seen:
                    continue
                msg = reader.deserialize(raw, conn.msgtype)
                k = seen[conn.topic]
                seen[conn.topic] += 1
                folder = "semantic" if conn.topic == "/dvs/semantic" else "instance"
                png = cv2.imread(str(run / folder / f"{k:08d}.png"), cv2.IMREAD_UNCHANGED)
                assert msg.header.frame_id.endswith("_optical")
                if conn.topic != "/dvs/detections":
                    assert msg.encoding == "mono16"
                    img = np.frombuffer(msg.data, "<u2").reshape(msg.height, msg.width)
                    np.testing.assert_array_equal(img, png)
                    continue
                hyps = [x.results[0] for x in msg.detections]
                cls = [int(r.id if hasattr(r, "id") else r.hypothesis.class_id) for r in hyps]
                got = [
                    (x.bbox.center.x, x.bbox.center.y) if hasattr(x.bbox.center, "x")
                    else (x.bbox.center.position.x, x.bbox.center.position.y)
                    for x in msg.detections
                ]  # fmt: skip
                sizes = [(x.bbox.size_x, x.bbox.size_y) for x in msg.detections]
                want = _tight_boxes(png)
                assert got == [(b[0], b[1]) for b in want]
                assert sizes == [(b[2], b[3]) for b in want]
                assert cls == [instances[b[4]] for b in want]
            assert seen == dict.fromkeys(seen, n_aps), seen


@pytest.mark.ros1
def test_ros1_own_reader_decodes_the_aps_detections(run: Path) -> None:
    from tests.io.test_vision_msgs import ros1_detections

    row = ros1_detections(run / "landing.bag", "/dvs/detections")  # the last APS frame's
    assert row["type"] == "vision_msgs/Detection2DArray"
    n_aps = len((run / "images.txt").read_text().split()) // 2
    png = cv2.imread(str(run / "instance" / f"{n_aps - 1:08d}.png"), cv2.IMREAD_UNCHANGED)
    instances = {i["id"]: i["class_id"] for i in json.loads((run / "instances.json").read_text())}
    expected = [[cx, cy, 0.0, w, h, instances[k], 1.0] for cx, cy, w, h, k in _tight_boxes(png)]
    assert row["boxes"] == expected


def _params(**over: float) -> Any:
    from roslan.sensors.cameras.event_config import EventCameraConfig

    cfg = EventCameraConfig.model_validate({"name": "dvs", "rate": 10.0, "preset": "clean", **over})
    return cfg.model_params()


def test_noise_events_are_flagged_and_signal_events_are_not() -> None:
    # a static image: every event is shot noise or a leak event
    gen = EventGenerator(32, 24, _params(shot_noise_rate=20.0, leak_rate=5.0),
                         np.random.default_rng(0))  # fmt: skip
    gen.flag_noise = True
    img = np.full((24, 32), 0.3)
    n = 0
    for k in range(60):
        b = gen.update(img, (k + 1) * 5_000_000)
        assert gen.last_noise.shape == (b.size,)
        assert gen.last_noise.all()
        n += b.size
    assert n > 50
    # brightening and darkening without noise: no event is flagged
    gen = EventGenerator(32, 24, _params(), np.random.default_rng(0))
    gen.flag_noise = True
    m = 0
    for k in range(60):
        level = 0.2 + 0.15 * np.sin(k / 6.0) + 0.01 * np.arange(32)[None, :]
        b = gen.update(np.broadcast_to(level, (24, 32)), (k + 1) * 5_000_000)
        assert not gen.last_noise.any()
        m += b.size
    assert m > 50


def test_label_rate_must_be_positive() -> None:
    from roslan.config.base import validate_model
    from roslan.errors import ConfigError

    for bad in (0.0, -1.0):
        with pytest.raises(ConfigError, match=r"sensors\[0\]\.label_rate"):
            validate_model(
                SimConfig,
                {"sensors": [{"type": "event_camera", "name": "d", "rate": 10, "label_rate": bad}]},
            )


def test_dry_run_counts_the_aps_label_files(run: Path) -> None:
    from roslan.pipeline.estimate import estimate_run

    files = [
        p
        for p in run.rglob("*")
        if p.is_file()
        and (p.name in ("tracks.npy", "classes.json", "instances.json")
             or p.parent.name in ("instance", "semantic"))
    ]  # fmt: skip
    duration = json.loads((run / "run.json").read_text())["trajectory_duration_s"]
    est = estimate_run(SimConfig.model_validate(JOB), duration=duration)
    assert abs(est.label_files - len(files)) <= 0.1 * len(files), (est.label_files, len(files))
    actual = sum(p.stat().st_size for p in files)
    assert 0.5 * actual <= est.parts["labels"] <= 4.0 * actual
