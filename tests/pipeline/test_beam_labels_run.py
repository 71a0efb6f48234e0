"""output.labels through a whole run for the beam sensors and /objects, judged by readers
nobody here wrote: rosbags and ROS 1's own rosbag read the PointCloud2 label field and the
Detection3DArray, trimesh's closest points on the exported scene/ models (GLB + poses.yaml)
place every labelled point on its instance's object, plain numpy reads the SemanticKITTI
export; a run without labels keeps its scans as they were."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
import yaml
from rosbags.highlevel import AnyReader
from scipy.spatial.transform import Rotation, Slerp

from label_helpers import mesh_distance
from pipeline_helpers import SHORT_TRAJECTORY
from roslan.cli import main
from roslan.config.sim import SimConfig
from roslan.pipeline import run_simulation

SCENE = """\
name: labelled
objects:
  - {name: floor, primitive: {type: box, size: [40, 40, 0.2]}, pose: {position: [0, 0, -0.1]},
     class: ground}
  - {name: crate_a, primitive: {type: box, size: [1, 1, 1]}, pose: {position: [3, 0, 0.5]},
     class: crate}
  - {name: crate_b, primitive: {type: box, size: [1, 2, 1.5]},
     pose: {position: [-2.5, 2.5, 0.75], rpy: [0, 0, 0.4]}, class: crate}
  - {name: drum, primitive: {type: cylinder, radius: 0.4, height: 1.2},
     pose: {position: [1, -3, 0.6]}, class: barrel}
  - {name: wall, primitive: {type: box, size: [0.2, 40, 4]}, pose: {position: [8, 0, 2]}}
"""

SENSORS: list[dict[str, Any]] = [
    {"type": "lidar", "name": "velodyne", "preset": "custom", "rate": 10.0,
     "elevations_deg": [-30.0, -15.0, -8.0, -3.0, 0.0, 4.0], "azimuth_steps": 300,
     "noise_sigma": 0.0, "pose": {"position": [0.0, 0.0, 0.08]}},
    {"type": "laser", "name": "laser", "rate": 10.0, "angle_increment": 0.02,
     "pose": {"rpy": [0.0, 0.3, 0.0]}},
    {"type": "sonar", "name": "sonar", "rate": 10.0, "axis": [0.0, 0.0, -1.0], "rings": 2},
    {"type": "altimeter", "name": "altimeter", "rate": 20.0},
]  # fmt: skip


def _config(scene: Path, labels: bool) -> SimConfig:
    return SimConfig.model_validate(
        {
            "trajectory": SHORT_TRAJECTORY,
            "scene": str(scene),
            "sensors": SENSORS,
            "output": {"ground_truth_rate": 100.0, "labels": labels, "workers": 0},
            "seed": 4,
        }
    )


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("labels")
    scene = root / "labelled.yaml"
    scene.write_text(SCENE, encoding="utf-8")
    on, off = root / "on", root / "off"
    run_simulation(_config(scene, True), on, quiet=True, overview=False)
    run_simulation(_config(scene, False), off, quiet=True, overview=False)
    return on, off


def _scans(out: Path) -> list[dict[str, np.ndarray]]:
    files = sorted((out / "lidar" / "velodyne").glob("*.npz"))
    assert files
    out_list = []
    for f in files:
        with np.load(f) as z:
            out_list.append({k: z[k] for k in z.files})
    return out_list


def _bag_messages(path: Path, topic: str) -> list[Any]:
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            return []
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]


def _instances(out: Path) -> dict[int, dict[str, Any]]:
    """Instance id -> its object and class, from `roslan scene info --json` of the exported
    scene (an independent path: the exported scene.yaml loaded back)."""
    from roslan.scene import load_scene
    from roslan.scene.instances import labels_document

    doc = labels_document(load_scene(out / "scene" / "scene.yaml"))
    return {i["id"]: i for i in doc["instances"]}


def test_npz_and_both_bags_carry_the_same_labels(runs: tuple[Path, Path]) -> None:
    on, _ = runs
    scans = _scans(on)
    for bag in (on / "landing.bag", on / "landing_ros2"):
        clouds = _bag_messages(bag, "/velodyne_points")
        assert len(clouds) == len(scans)
        for msg, scan in zip(clouds, scans, strict=True):
            fields = {f.name: (f.offset, f.datatype) for f in msg.fields}
            assert fields["label"] == (22, 6)  # uint32 after XYZIRT
            assert msg.point_step == 26
            dt = np.dtype({"names": ["x", "label"], "formats": ["<f4", "<u4"],
                           "offsets": [0, 22], "itemsize": 26})  # fmt: skip
            cloud = np.frombuffer(bytes(msg.data), dtype=dt)
            assert scan["label"].dtype == np.uint32
            np.testing.assert_array_equal(cloud["label"], scan["label"])
            np.testing.assert_array_equal(cloud["x"], scan["x"])
    # the labelled classes and instances are those of the scene's table
    inst = _instances(on)
    lab = np.concatenate([s["label"] for s in scans])
    ids = np.unique(lab >> 16).tolist()
    assert set(ids) - {0} <= set(inst)
    assert {inst[i]["object"] for i in ids if i} >= {"floor", "crate_a"}
    for i in ids:
        if i:
            cls = np.unique(lab[(lab >> 16) == i] & 0xFFFF)
            assert cls.tolist() == [inst[i]["class_id"]]


def _world_triangles(out: Path) -> dict[str, np.ndarray]:
    """Each object's world triangles from the exported GLB models and poses.yaml."""
    poses = yaml.safe_load((out / "scene" / "poses.yaml").read_text(encoding="utf-8"))
    rows = poses["objects"] if isinstance(poses, dict) else poses
    tris = {}
    for p in rows:
        mesh = trimesh.load(out / "scene" / p["model"], force="mesh")
        v = np.asarray(mesh.vertices) * np.asarray(p["scale"])
        R = Rotation.from_quat(p["quaternion_xyzw"]).as_matrix()
        tris[p["name"]] = (v @ R.T + np.asarray(p["position"]))[np.asarray(mesh.faces)]
    return tris


def test_every_labelled_point_lies_on_its_instance_mesh(runs: tuple[Path, Path]) -> None:
    on, _ = runs
    gt = np.loadtxt(on / "groundtruth.txt")
    slerp = Slerp(gt[:, 0], Rotation.from_quat(gt[:, 4:8]))
    ext = yaml.safe_load((on / "calib" / "extrinsics.yaml").read_text(encoding="utf-8"))
    T_bs = np.asarray(ext["sensors"]["velodyne"]["T_base_link_sensor"])
    tris = _world_triangles(on)
    inst = _instances(on)
    checked = 0
    for scan in _scans(on)[::3]:
        t = scan["stamp"] * 1e-9 + scan["time"].astype(np.float64)
        R_wb = slerp(t).as_matrix()
        p_wb = np.stack([np.interp(t, gt[:, 0], gt[:, k]) for k in (1, 2, 3)], axis=1)
        xyz = np.stack([scan["x"], scan["y"], scan["z"]], axis=1).astype(np.float64)
        p_b = xyz @ T_bs[:3, :3].T + T_bs[:3, 3]
        world = np.einsum("nij,nj->ni", R_wb, p_b) + p_wb
        iid = scan["label"] >> 16
        for i in np.unique(iid).tolist():
            sel = iid == i
            obj = inst[i]["object"] if i else "wall"  # the one object without a class
            d = mesh_distance(tris[obj], world[sel])
            assert d.max() < 0.01, (obj, float(d.max()))
            checked += int(sel.sum())
    assert checked > 1000


def test_labels_off_keeps_the_scans_and_adds_nothing(runs: tuple[Path, Path]) -> None:
    on, off = runs
    for a, b in zip(_scans(on), _scans(off), strict=True):
        assert "label" not in b
        assert sorted(a) == sorted([*b, "label"])
        for k in b:
            assert a[k].tobytes() == b[k].tobytes(), k
    for name in ("laser_laser", "range_sonar", "range_altimeter"):
        assert (on / f"{name}.txt").read_bytes() == (off / f"{name}.txt").read_bytes()
        assert (on / f"{name}_labels.txt").is_file()
        assert not (off / f"{name}_labels.txt").exists()
    clouds = _bag_messages(off / "landing_ros2", "/velodyne_points")
    assert [f.name for f in clouds[0].fields] == ["x", "y", "z", "intensity", "ring", "time"]
    assert _bag_messages(off / "landing_ros2", "/objects") == []


def test_laser_and_range_label_files_follow_their_readings(runs: tuple[Path, Path]) -> None:
    on, _ = runs
    inst = _instances(on)
    for name in ("laser_laser", "range_sonar", "range_altimeter"):
        values = np.loadtxt(on / f"{name}.txt", ndmin=2)
        labels = np.loadtxt(on / f"{name}_labels.txt", ndmin=2, dtype=np.float64)
        assert labels.shape == values.shape
        np.testing.assert_array_equal(labels[:, 0], values[:, 0])
        lab = labels[:, 1:].astype(np.uint64)
        finite = np.isfinite(values[:, 1:])
        assert (lab[~finite] == 0).all()
        assert (lab[finite] != 0).any()
        for i in np.unique(lab >> 16).tolist():
            if i:
                assert np.unique(lab[(lab >> 16) == i] & 0xFFFF).tolist() == [inst[i]["class_id"]]
    readme = (on / "README.md").read_text(encoding="utf-8")
    assert "| `range_sonar_labels.txt` | `t label` of the range sensor `sonar` (" in readme
    assert "| `laser_laser_labels.txt` | `t l_0 .. l_n` of the laser `laser` (" in readme
    assert "`sonar_labels`" not in readme
    # the altimeter looks straight down at the labelled floor all the way
    alt = np.loadtxt(on / "range_altimeter_labels.txt", ndmin=2)[:, 1].astype(np.uint64)
    floor = next(i for i, v in inst.items() if v["object"] == "floor")
    alt_r = np.loadtxt(on / "range_altimeter.txt", ndmin=2)[:, 1]
    assert set((alt[np.isfinite(alt_r)] >> 16).tolist()) == {floor}


def test_objects_decode_in_both_bags(runs: tuple[Path, Path]) -> None:
    on, _ = runs
    inst = _instances(on)
    for bag, ros1 in ((on / "landing.bag", True), (on / "landing_ros2", False)):
        (msg,) = _bag_messages(bag, "/objects")
        assert msg.header.frame_id == "world"
        assert len(msg.detections) == len(inst)
        for det, (iid, row) in zip(msg.detections, sorted(inst.items()), strict=True):
            p = det.bbox.center.position
            np.testing.assert_allclose([p.x, p.y, p.z], row["box3d"]["center"], atol=1e-12)
            s = det.bbox.size
            np.testing.assert_allclose([s.x, s.y, s.z], row["box3d"]["size"], atol=1e-12)
            (hyp,) = det.results
            if ros1:
                assert hyp.id == row["class_id"]
            else:
                assert hyp.hypothesis.class_id == str(row["class_id"])
                assert det.id == str(iid)


_ROS1_READ = """
import json, sys, rosbag
from sensor_msgs import point_cloud2
out = {"labels": [], "objects": []}
with rosbag.Bag(sys.argv[1]) as bag:
    for topic, msg, t in bag.read_messages(topics=["/velodyne_points", "/objects"]):
        if topic == "/velodyne_points":
            out["labels"].append([p[0] for p in point_cloud2.read_points(msg, ["label"])])
        else:
            out["objects"] = [[d.results[0].id, d.bbox.size.x] for d in msg.detections]
print(json.dumps(out))
"""


@pytest.mark.ros1
def test_ros1_own_reader_reads_labels_and_objects(runs: tuple[Path, Path]) -> None:
    py = shutil.which("python3", path="/usr/bin")
    probe = subprocess.run(
        [py or "/usr/bin/python3", "-c", "import rosbag, sensor_msgs.point_cloud2"],
        capture_output=True,
    )
    if py is None or probe.returncode != 0:
        pytest.skip("Debian's python3-rosbag is not installed for /usr/bin/python3")
    on, _ = runs
    proc = subprocess.run(
        [py, "-c", _ROS1_READ, str(on / "landing.bag")], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    scans = _scans(on)
    assert len(got["labels"]) == len(scans)
    for ros1, scan in zip(got["labels"], scans, strict=True):
        assert ros1 == scan["label"].tolist()
    inst = _instances(on)
    assert [o[0] for o in got["objects"]] == [inst[i]["class_id"] for i in sorted(inst)]


def test_semantickitti_export_reads_back_with_numpy(
    runs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    on, off = runs
    dest = tmp_path / "kitti"
    assert main(["export", "semantickitti", str(on), "-o", str(dest)]) == 0
    seq = dest / "sequences" / "00"
    scans = _scans(on)
    bins = sorted((seq / "velodyne").glob("*.bin"))
    labels = sorted((seq / "labels").glob("*.label"))
    assert [p.stem for p in bins] == [f"{i:06d}" for i in range(len(scans))]
    assert [p.stem for p in labels] == [p.stem for p in bins]
    for b, lab, scan in zip(bins, labels, scans, strict=True):
        pts = np.fromfile(b, dtype=np.float32).reshape(-1, 4)
        lbl = np.fromfile(lab, dtype=np.uint32)
        assert pts.shape[0] == lbl.shape[0] == scan["x"].shape[0]
        np.testing.assert_array_equal(pts[:, 0], scan["x"])
        np.testing.assert_array_equal(pts[:, 2], scan["z"])
        np.testing.assert_allclose(pts[:, 3], scan["intensity"] / 255.0, rtol=1e-6)
        assert (pts[:, 3] >= 0).all()
        assert (pts[:, 3] <= 1).all()
        np.testing.assert_array_equal(lbl, scan["label"])
    poses = np.loadtxt(seq / "poses.txt", ndmin=2)
    assert poses.shape == (len(scans), 12)
    np.testing.assert_array_equal(poses[0], np.eye(4)[:3].reshape(-1))
    times = np.loadtxt(seq / "times.txt", ndmin=1)
    np.testing.assert_allclose(times, [s["stamp"] * 1e-9 for s in scans], atol=1e-9)
    calib = dict(line.split(":", 1) for line in (seq / "calib.txt").read_text().splitlines())
    assert sorted(calib) == ["P0", "P1", "P2", "P3", "Tr"]
    assert all(len(v.split()) == 12 for v in calib.values())
    # the poses: the LiDAR's world pose at each stamp (groundtruth.txt, extrinsics),
    # relative to the first scan's
    gt = np.loadtxt(on / "groundtruth.txt")
    ext = yaml.safe_load((on / "calib" / "extrinsics.yaml").read_text(encoding="utf-8"))
    T_bs = np.asarray(ext["sensors"]["velodyne"]["T_base_link_sensor"])
    world = []
    for s in scans:
        row = np.flatnonzero(np.isclose(gt[:, 0], s["stamp"] * 1e-9, atol=1e-9, rtol=0))[0]
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(gt[row, 4:8]).as_matrix()
        T[:3, 3] = gt[row, 1:4]
        world.append(T @ T_bs)
    expected = [(np.linalg.inv(world[0]) @ T)[:3].reshape(-1) for T in world]
    np.testing.assert_allclose(poses, expected, atol=1e-9)
    capsys.readouterr()
    # existing DEST: refused without --overwrite, replaced with it
    assert main(["export", "semantickitti", str(on), "-o", str(dest)]) != 0
    assert "exists; pass --overwrite" in capsys.readouterr().err
    assert main(["export", "semantickitti", str(on), "-o", str(dest), "--overwrite"]) == 0
    # a folder that is not an export is never replaced
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    assert main(["export", "semantickitti", str(on), "-o", str(other), "--overwrite"]) != 0
    assert "not a roslan SemanticKITTI export" in capsys.readouterr().err
    assert (other / "keep.txt").read_text() == "mine"
    # a run without labels: a clear error, nothing written
    assert main(["export", "semantickitti", str(off), "-o", str(tmp_path / "none")]) != 0
    err = capsys.readouterr().err
    assert "no labelled LiDAR" in err
    assert "output.labels: true" in err
    assert not (tmp_path / "none").exists()
    assert (
        main(["export", "semantickitti", str(on), "--lidar", "nope", "-o", str(tmp_path / "n")])
        != 0
    )
    assert "'nope'" in capsys.readouterr().err


def test_dry_run_counts_the_label_files_and_their_disk(runs: tuple[Path, Path]) -> None:
    from roslan.pipeline.estimate import estimate_run

    on, _ = runs
    scene = on / "scene" / "scene.yaml"
    with_labels = estimate_run(_config(scene, True), duration=1.2)
    without = estimate_run(_config(scene, False), duration=1.2)
    extra = {k: v for k, v in with_labels.parts.items() if k not in without.parts}
    # (``labels``: classes.json and instances.json, the run's tables)
    assert set(extra) == {"labels", "lidar labels", "label text files (3)"}
    for bag in ("bag_ros1", "bag_ros2"):  # the clouds' label field and /objects
        assert with_labels.parts[bag] > without.parts[bag]
    # the text files' estimate against the files written (a planning figure: within 2x)
    written = sum(
        (on / f"{n}_labels.txt").stat().st_size
        for n in ("laser_laser", "range_sonar", "range_altimeter")
    )
    assert 0.5 < extra["label text files (3)"] / written < 2.0
    # the label arrays inside the scans: at most the estimate (0.3 bytes a point)
    import zipfile

    inside = 0
    for f in (on / "lidar" / "velodyne").glob("*.npz"):
        with zipfile.ZipFile(f) as zf:
            inside += zf.getinfo("label.npy").compress_size
    assert 0 < inside <= extra["lidar labels"]
    # a sensor that opts out is not counted
    opted = _config(scene, True).model_dump()
    for s in opted["sensors"]:
        s["labels"] = False
    est = estimate_run(SimConfig.model_validate(opted), duration=1.2)
    assert not {k for k in est.parts if "label" in k} - {"labels"}  # the tables remain
