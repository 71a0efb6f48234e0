"""What a run writes about itself: its README.md describes every file and folder at the
OUTDIR root, PLAYBACK.md names the layouts and only the bags written, and the Foxglove
layout's 3D panel shows only topics of types that panel draws."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from pipeline_helpers import short_config
from roslan.rundir.layouts import FOXGLOVE_3D_TYPES

# the default job's sensor types, tiny (images of a few dozen pixels, slow rates)
SENSORS: list[dict[str, Any]] = [
    {"type": "imu", "name": "imu", "rate": 100.0},
    {"type": "event_camera", "name": "dvs", "rate": 10.0, "resolution": [48, 36],
     "max_rate": 40.0, "min_rate": 20.0, "pose": {"position": [0.1, 0.0, 0.0], "rpy": [0, 0.5, 0]}},
    {"type": "camera", "name": "camera", "rate": 5.0, "resolution": [64, 48], "fx": 40.0,
     "pose": {"position": [0.1, 0.0, 0.0], "rpy": [0.0, 0.5, 0.0]}},
    {"type": "lidar", "name": "velodyne", "preset": "vlp16", "rate": 5.0},
    {"type": "sonar", "name": "sonar", "rate": 10.0, "axis": [0, 0, -1]},
    {"type": "altimeter", "name": "altimeter", "rate": 10.0,
     "pose": {"position": [0.03, 0.0, -0.03]}},
]  # fmt: skip


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("roslan.render.gl")
    from roslan.pipeline.run import run_simulation

    out = tmp_path_factory.mktemp("readme") / "out"
    run_simulation(short_config(scene="warehouse", sensors=SENSORS), out, quiet=True)
    return out


def _described(readme: str) -> set[str]:
    """The names the README's table rows describe (``name`` or ``name/``)."""
    return {m.group(1).rstrip("/") for m in re.finditer(r"^\| `([^`]+)` \|", readme, re.M)}


def test_run_readme_describes_every_file(run: Path) -> None:
    readme = (run / "README.md").read_text(encoding="utf-8")
    described = _described(readme)
    present = {p.name for p in run.iterdir() if not p.name.startswith(".")}
    # the default job's files, among them the ones the README used to omit
    assert {"overview.png", "summary.json", "trajectory.png", "README.md", "images"} <= present
    assert present - described == set(), readme
    assert described - present == set()  # nothing described that is not there


def test_playback_names_the_layouts_and_foxglove_draws_its_topics(run: Path) -> None:
    text = (run / "PLAYBACK.md").read_text(encoding="utf-8")
    for name in ("landing.rviz", "landing.foxglove.json", "landing.bag", "landing_ros2"):
        assert name in text, name
        assert (run / name).exists(), name
    types = {t: e["type"] for t, e in json.loads((run / "run.json").read_text())["topics"].items()}
    fox = json.loads((run / "landing.foxglove.json").read_text())
    shown = fox["configById"]["3D!scene"]["topics"]
    assert "/ground_truth/pose" in shown  # the trajectory
    assert {"/scene", "/velodyne_points"} <= set(shown)
    assert {types[t].replace("/msg/", "/") for t in shown} <= FOXGLOVE_3D_TYPES
    assert "/ground_truth/odometry" not in shown  # a type the 3D panel does not draw


def test_playback_says_what_ros2_playback_needs(run: Path) -> None:
    """PLAYBACK.md names the MCAP storage plugin and, for the event topics (the types in
    run.json), a dvs_msgs package whose messages are the ones the MCAP file's schema
    defines."""
    from mcap.reader import make_reader

    text = (run / "PLAYBACK.md").read_text(encoding="utf-8")
    assert "ros-<distro>-rosbag2-storage-mcap" in text
    types = {t: e["type"] for t, e in json.loads((run / "run.json").read_text())["topics"].items()}
    events = [t for t, ty in types.items() if ty == "dvs_msgs/msg/EventArray"]
    assert events == ["/dvs/events"]
    assert "The event topics (`/dvs/events`) hold `dvs_msgs/msg/EventArray`" in text
    block = re.search(
        r"# dvs_msgs/msg/Event.msg\n(.*?)# dvs_msgs/msg/EventArray.msg\n(.*?)```", text, re.S
    )
    assert block is not None
    with (run / "landing_ros2" / "landing_ros2.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    schema = next(s for s in summary.schemas.values() if s.name == "dvs_msgs/msg/EventArray")
    parts = schema.data.decode().split("=" * 80 + "\n")
    defined = {p.split("\n", 1)[0][len("MSG: ") :]: p.split("\n", 1)[1] for p in parts[1:]}
    assert block.group(1).strip() == defined["dvs_msgs/Event"].strip()
    assert block.group(2).strip() == parts[0].strip().replace("dvs_msgs/Event[]", "Event[]")


def test_trajectory_png_row_says_what_the_figure_shows(run: Path) -> None:
    """The figure is the 3-D path and the six gaps (write_trajectory_plot), no rates or
    accelerations."""
    readme = (run / "README.md").read_text(encoding="utf-8")
    row = next(ln for ln in readme.splitlines() if ln.startswith("| `trajectory.png` |"))
    assert "3-D path in the goal frame F" in row
    assert "six gaps (x, y, z in m; roll, pitch, yaw in rad)" in row
    assert "acceleration" not in row
    assert "rates" not in row


def test_ros2_only_run_names_only_what_it_wrote(tmp_path: Path) -> None:
    from roslan.pipeline.run import run_simulation

    out = tmp_path / "out"
    run_simulation(short_config(), out, quiet=True, formats=["ros2"], overview=False)
    playback = (out / "PLAYBACK.md").read_text(encoding="utf-8")
    assert "landing.bag" not in playback
    assert not re.search(r"\brosbag\b", playback)  # (rosbag2 is ROS 2's)
    assert "landing.rviz" not in playback
    assert "rosbag2-storage-mcap" in playback
    assert "dvs_msgs" not in playback  # no event camera
    assert not (out / "landing.rviz").exists()  # an RViz 1 layout plays a ROS 1 bag
    assert "landing_ros2/landing_ros2.mcap" in playback
    assert "landing.foxglove.json" in playback
    assert (out / "landing.foxglove.json").is_file()
    readme = (out / "README.md").read_text(encoding="utf-8")
    assert "landing.rviz" not in readme
    assert {p.name for p in out.iterdir()} <= _described(readme)
