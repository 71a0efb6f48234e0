"""Third-party readers of an OUTDIR, shared by the bag tests and the closed-loop tests:
ROS 1's own ``rosbag`` (Debian's python3-rosbag, run by /usr/bin/python3), the reference
``mcap`` library and ``evlib``."""

from __future__ import annotations

import shutil
import subprocess
import textwrap
from pathlib import Path
from typing import Any

import pytest

__all__ = ["ROS1_SCRIPT", "evlib_events", "mcap_topic_counts", "ros1_topic_counts"]

ROS1_SCRIPT = textwrap.dedent(
    """
    import sys, rosbag, genpy
    counts = {}
    with rosbag.Bag(sys.argv[1]) as bag:
        info = bag.get_type_and_topic_info()
        for topic, msg, t in bag.read_messages():
            assert isinstance(msg, genpy.Message), type(msg)
            # deserialize fully: touch every slot
            msg._check_types()
            stamp = getattr(getattr(msg, "header", None), "stamp", None)
            if stamp is not None:
                assert stamp == t, (topic, stamp, t)
            counts[topic] = counts.get(topic, 0) + 1
    for topic in sorted(counts):
        print(topic, info.topics[topic].msg_type, counts[topic])
    """
)


def ros1_topic_counts(bag: Path, tmp_path: Path) -> dict[str, tuple[str, int]]:
    """topic -> (ROS 1 message type, messages) as ROS 1's rosbag reads ``bag`` (every
    message fully deserialized, header stamps checked); skips without python3-rosbag."""
    py = shutil.which("python3", path="/usr/bin")
    if py is None:
        pytest.skip("/usr/bin/python3 not found")
    probe = subprocess.run(
        [py, "-c", "import rosbag, sensor_msgs.msg, tf2_msgs.msg, nav_msgs.msg"],
        capture_output=True,
    )
    if probe.returncode != 0:
        pytest.skip(
            "Debian's python3-rosbag / message packages are not installed for /usr/bin/python3"
        )
    script = tmp_path / "read_ros1.py"
    script.write_text(ROS1_SCRIPT)
    proc = subprocess.run([py, str(script), str(bag)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return {
        line.split()[0]: (line.split()[1], int(line.split()[2]))
        for line in proc.stdout.splitlines()
    }


def mcap_topic_counts(ros2_folder: Path) -> dict[str, int]:
    """topic -> messages as the reference ``mcap`` library reads the ROS 2 bag's file."""
    from mcap.reader import make_reader

    counts: dict[str, int] = {}
    mcap = next(Path(ros2_folder).glob("*.mcap"))
    with mcap.open("rb") as fh:
        for _, channel, _ in make_reader(fh).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def evlib_events(path: Path) -> Any:
    """The events of ``path`` (events.h5 / events.txt) as evlib loads them (a polars
    DataFrame with ``x, y, t, polarity``); skips without evlib."""
    evlib = pytest.importorskip("evlib")
    return evlib.load_events(str(path)).collect()
