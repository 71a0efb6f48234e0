"""A Rerun recording of one run (``roslan view OUTDIR``).

Everything is logged on one timeline, ``trajectory_time`` (seconds since the trajectory
start, the clock of the dataset text files). Entities:

* ``world/scene``: the scene mesh, static: the triangles of the bags' ``/scene`` marker
  (:func:`roslan.scene.markers.scene_mesh` of ``OUTDIR/scene/scene.yaml``), shaded colours;
* ``world/trajectory``: the whole path of base_link, static;
* ``world/base_link``: the vehicle pose over time (``/ground_truth/pose``) and its axes;
* ``world/base_link/<sensor>``: every sensor of the run, placed by the bag's
  ``/tf_static`` in the frame of its messages: a camera is a pinhole (its
  ``camera_info``) with its frames (``.../image``, JPEG-compressed; depth maps as depth
  images), an event camera also gets ``.../events``: ON (blue) / OFF (red) event frames
  accumulated over ``event_window_ms`` (default 10 ms) every window; a LiDAR its scans
  (points in its frame, coloured by intensity); an IMU the series ``.../accel`` and
  ``.../gyro``; a range sensor ``.../range``.

Inputs: the ROS 2 bag (else the ROS 1 bag) for poses, transforms, images, scans and
series, the event files (``events.h5``/``events.txt``) for the events (decoding every
``dvs_msgs/Event`` through the bag's generic deserializer would be far slower), and
``run.json`` for which sensor published which topic.

Saved recordings are reproducible: the same OUTDIR gives the same file, byte for byte.
Every chunk, row id and chunk id depends on the run alone, and the two parts rerun-sdk
stamps itself (the store-info message's row id, the order of the footer manifest's
schema) are made canonical after the file is written.
"""

from __future__ import annotations

import json
import warnings
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RoslanError
from roslan.view.rrd_file import canonicalize_envelope

__all__ = ["TIMELINE", "ViewError", "build_recording"]

TIMELINE = "trajectory_time"
F64 = NDArray[np.float64]


class ViewError(RoslanError):
    """``roslan view`` cannot build the recording (missing input, missing extra)."""


def _quat_matrix(q: F64) -> F64:
    x, y, z, w = (float(v) for v in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _static_tree(msg: Any) -> dict[str, tuple[str, F64]]:
    """child frame -> (parent, 4x4 T_parent_child) of a tf2_msgs/TFMessage."""
    out: dict[str, tuple[str, F64]] = {}
    for t in msg.transforms:
        T = np.eye(4)
        r, p = t.transform.rotation, t.transform.translation
        T[:3, :3] = _quat_matrix(np.array([r.x, r.y, r.z, r.w]))
        T[:3, 3] = (p.x, p.y, p.z)
        out[t.child_frame_id] = (t.header.frame_id, T)
    return out


def _T_base(tree: dict[str, tuple[str, F64]], frame: str, base: str = "base_link") -> F64:
    T = np.eye(4)
    seen = 0
    while frame != base and frame in tree and seen < 64:
        parent, T_pc = tree[frame]
        T = T_pc @ T
        frame = parent
        seen += 1
    return T


def _bag_paths(outdir: Path) -> list[Path]:
    for name in ("landing_ros2", "landing.bag"):
        if (outdir / name).exists():
            return [outdir / name]
    msg = (
        f"roslan view: {outdir} has no bag (landing_ros2/ or landing.bag); "
        "simulate with output.formats [ros1] or [ros2]"
    )
    raise ViewError(msg)


class _Logger:
    """Collects what is logged as columns (series) and logs the rest at once."""

    def __init__(self, rr: Any, start_ns: int, event_window_ms: float) -> None:
        self.rr = rr
        self.start_ns = start_ns
        self.window_ns = max(1, round(event_window_ms * 1e6))
        self.series: dict[str, tuple[list[float], list[list[float]]]] = defaultdict(
            lambda: ([], [])
        )
        self.static_done: set[str] = set()
        self.pose_t: list[float] = []
        self.pose: list[list[float]] = []

    def at(self, stamp_ns: int) -> None:
        self.rr.set_time(TIMELINE, duration=(stamp_ns - self.start_ns) * 1e-9)

    def add_series(self, path: str, stamp_ns: int, values: list[float]) -> None:
        t, v = self.series[path]
        t.append((stamp_ns - self.start_ns) * 1e-9)
        v.append(values)

    def flush_series(self) -> None:
        rr = self.rr
        for path, (t, v) in self.series.items():
            rr.send_columns(
                path,
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(t))],
                columns=rr.Scalars.columns(scalars=np.asarray(v, dtype=np.float64)),
            )
        if self.pose_t:
            p = np.asarray(self.pose)
            rr.send_columns(
                "world/base_link",
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(self.pose_t))],
                columns=rr.Transform3D.columns(translation=p[:, :3], quaternion=p[:, 3:]),
            )
            rr.log(
                "world/trajectory",
                rr.LineStrips3D([p[:, :3]], colors=[[255, 200, 0]], radii=[0.01]),
                static=True,
            )


def _image_array(msg: Any) -> NDArray[Any]:
    data = np.asarray(msg.data, dtype=np.uint8)
    enc = msg.encoding
    dt = {"32FC1": np.float32, "32FC2": np.float32, "16UC1": np.uint16}.get(enc, np.uint8)
    ch = {"rgb8": 3, "bgr8": 3, "32FC2": 2}.get(enc, 1)
    row = data.reshape(msg.height, msg.step)[:, : msg.width * ch * np.dtype(dt).itemsize]
    img = np.ascontiguousarray(row).view(dt).reshape(msg.height, msg.width, ch)
    if enc == "bgr8":
        img = img[..., ::-1]
    return img[..., 0] if ch == 1 else img


def _log_image(log: _Logger, entity: str, msg: Any) -> None:
    """An image message as ``<entity>/image`` (JPEG) or ``<entity>/depth``."""
    import cv2

    rr = log.rr
    img = _image_array(msg)
    if msg.encoding in ("32FC1", "16UC1"):
        depth = img.astype(np.float32)
        if msg.encoding == "16UC1":
            depth = depth / 1000.0
        mm = np.where(np.isfinite(depth), np.clip(depth * 1000.0, 0, 65535), 0).astype(np.uint16)
        rr.log(f"{entity}/depth", rr.DepthImage(mm, meter=1000.0))
        return
    if msg.encoding == "32FC2":
        return  # optic flow: in the files (DSEC layout), not drawn here
    bgr = img if img.ndim == 2 else img[..., ::-1]
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 80])
    if ok:
        rr.log(f"{entity}/image", rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"))


def _cloud_points(msg: Any) -> tuple[F64, F64 | None]:
    types = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
    fields = {f.name: (f.offset, types.get(f.datatype, "u1")) for f in msg.fields}
    endian = ">" if msg.is_bigendian else "<"
    names = [n for n in ("x", "y", "z", "intensity") if n in fields]
    dtype = np.dtype(
        {
            "names": names,
            "formats": [endian + fields[n][1] for n in names],
            "offsets": [fields[n][0] for n in names],
            "itemsize": msg.point_step,
        }
    )
    n = msg.width * msg.height
    arr = np.frombuffer(np.asarray(msg.data, np.uint8).tobytes(), dtype=dtype, count=n)
    xyz = np.stack([arr["x"], arr["y"], arr["z"]], axis=1).astype(np.float64)
    ok = np.all(np.isfinite(xyz), axis=1)
    inten = arr["intensity"].astype(np.float64)[ok] if "intensity" in names else None
    return xyz[ok], inten


def _log_cloud(log: _Logger, entity: str, msg: Any) -> None:
    xyz, inten = _cloud_points(msg)
    colors = None
    if inten is not None and inten.size:
        v = np.clip(inten / max(float(np.percentile(inten, 99)), 1e-9), 0, 1)
        colors = (np.stack([v, 0.4 + 0.6 * v, 1.0 - v], axis=1) * 255).astype(np.uint8)
    log.rr.log(
        f"{entity}/scan",
        log.rr.Points3D(xyz.astype(np.float32), colors=colors, radii=[0.02]),
    )


def _log_laser(log: _Logger, entity: str, msg: Any) -> None:
    r = np.asarray(msg.ranges, dtype=np.float64)
    a = msg.angle_min + msg.angle_increment * np.arange(r.size)
    ok = np.isfinite(r) & (r > 0)
    pts = np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)], axis=1)[ok]
    log.rr.log(f"{entity}/scan", log.rr.Points3D(pts.astype(np.float32), radii=[0.02]))


def _handlers(log: _Logger) -> dict[str, Callable[[str, int, Any], None]]:
    def imu(entity: str, stamp: int, m: Any) -> None:
        a, g = m.linear_acceleration, m.angular_velocity
        log.add_series(f"{entity}/accel", stamp, [a.x, a.y, a.z])
        log.add_series(f"{entity}/gyro", stamp, [g.x, g.y, g.z])

    def rng(entity: str, stamp: int, m: Any) -> None:
        log.add_series(f"{entity}/range", stamp, [m.range if np.isfinite(m.range) else np.nan])

    def info(entity: str, stamp: int, m: Any) -> None:
        if entity in log.static_done:
            return
        log.static_done.add(entity)
        K = np.asarray(m.k if hasattr(m, "k") else m.K, dtype=np.float64).reshape(3, 3)
        log.rr.log(
            entity,
            log.rr.Pinhole(
                image_from_camera=K,
                resolution=[m.width, m.height],
                camera_xyz=log.rr.ViewCoordinates.RDF,
                image_plane_distance=0.3,
            ),
            static=True,
        )

    def pose(entity: str, stamp: int, m: Any) -> None:
        p, q = m.pose.position, m.pose.orientation
        log.pose_t.append((stamp - log.start_ns) * 1e-9)
        log.pose.append([p.x, p.y, p.z, q.x, q.y, q.z, q.w])

    def per_message(fn: Callable[[_Logger, str, Any], None]) -> Callable[[str, int, Any], None]:
        def go(entity: str, stamp: int, m: Any) -> None:
            log.at(stamp)
            fn(log, entity, m)

        return go

    return {
        "sensor_msgs/msg/Imu": imu,
        "sensor_msgs/msg/Range": rng,
        "sensor_msgs/msg/CameraInfo": info,
        "sensor_msgs/msg/Image": per_message(_log_image),
        "sensor_msgs/msg/PointCloud2": per_message(_log_cloud),
        "sensor_msgs/msg/LaserScan": per_message(_log_laser),
        "geometry_msgs/msg/PoseStamped": pose,
    }


def _log_events(log: _Logger, outdir: Path, name: str, entity: str, root: str | None) -> bool:
    from roslan.plots.raster import event_frame
    from roslan.rundir.calibration import camera_folder
    from roslan.rundir.events import EventSource

    folder = outdir / camera_folder(root, name)
    path = next((folder / f for f in ("events.h5", "events.txt") if (folder / f).is_file()), None)
    if path is None:
        return False
    run = json.loads((outdir / "run.json").read_text())
    end_ns = round(float(run["trajectory_duration_s"]) * 1e9)
    import cv2

    rr = log.rr
    with EventSource(path, None, None) as src:
        w, h = src.width, src.height
        if w is None or h is None:
            return False
        for t0 in range(0, end_ns, log.window_ns):
            x, y, p = src.window(t0, t0 + log.window_ns)
            rgb = event_frame(x, y, p, w, h)  # the plots' picture: ON blue, OFF red on white
            # lossless; sparse frames compress well
            ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
            if ok:
                rr.set_time(TIMELINE, duration=(t0 + log.window_ns) * 1e-9)
                rr.log(
                    f"{entity}/events",
                    rr.EncodedImage(contents=buf.tobytes(), media_type="image/png"),
                )
    return True


_NO_TICK_S = 10.0**9  # the batcher's clock never flushes
_ROW_ID = "rerun.controls.RowId"


def _tuids(col: Any) -> NDArray[np.uint64]:
    """(n, 2) big-endian (time_ns, inc) of a FixedSizeBinary(16) TUID column."""
    buf = col.buffers()[1]
    raw = np.frombuffer(buf, dtype=">u8", count=2 * len(col), offset=col.offset * 16)
    return raw.reshape(-1, 2).astype(np.uint64)


def _canonical_rrd(raw: Path, out: Path, recording_id: str, stamp_ns: int) -> None:
    """Rewrite the recording ``raw`` into ``out`` with ids that depend on the data alone.

    Rerun stamps every row and chunk with a TUID (wall-clock nanoseconds and a random
    increment). Here each row gets (``stamp_ns``, its rank in the original log order)
    and each chunk (``stamp_ns``, 2**63 + its position), chunks in the order of their last
    row: the relative order of rows, which decides what a latest-at query shows, is kept.
    Rerun's own :meth:`rerun.chunk.Chunk.from_record_batch` carries the given ids into
    the file unchanged; nothing is edited below the SDK.

    Two passes over ``raw``, streamed: the first reads the row ids only, the second
    rewrites each chunk. ``raw``'s chunks were sent as they were logged, so they come
    in order (a chunk out of order waits for its turn): memory does not grow with the
    recording.
    """
    import pyarrow as pa
    from rerun.chunk import Chunk, LazyChunkStream, RrdReader

    def stream() -> Any:
        return RrdReader(str(raw)).stream()

    ids = []
    for c in stream():
        b = c.to_record_batch()
        ids.append(_tuids(b.column(b.schema.get_field_index(_ROW_ID))))
    every = np.concatenate(ids) if ids else np.zeros((0, 2), np.uint64)
    order = np.lexsort((every[:, 1], every[:, 0]))
    rank = np.empty(len(order), np.uint64)
    rank[order] = np.arange(1, len(order) + 1, dtype=np.uint64)
    ranks = np.split(rank, np.cumsum([len(i) for i in ids])[:-1]) if ids else []
    last = [int(r.max()) if len(r) else 0 for r in ranks]
    position = {k: n for n, k in enumerate(sorted(range(len(ids)), key=last.__getitem__))}
    del ids, every, order, rank

    def rewrite(b: Any, k: int) -> Any:
        n = position[k]
        new = np.empty((b.num_rows, 2), dtype=">u8")
        new[:, 0] = stamp_ns
        new[:, 1] = ranks[k]
        at = b.schema.get_field_index(_ROW_ID)
        col = pa.FixedSizeBinaryArray.from_buffers(
            pa.binary(16), b.num_rows, [None, pa.py_buffer(new.tobytes())]
        )
        b = b.set_column(at, b.schema.field(at), col)
        meta = dict(b.schema.metadata or {})
        chunk_id = np.array([stamp_ns, 2**63 + n], dtype=">u8").tobytes().hex().upper()
        meta[b"rerun:id"] = f"chunk_{chunk_id}".encode()
        made = Chunk.from_record_batch(b.replace_schema_metadata(meta))
        if len(made) != 1 or made[0].id.lower() != f"chunk_{chunk_id}".lower():
            msg = f"roslan view: rerun did not keep the canonical ids of chunk {n}"
            raise ViewError(msg)
        return made[0]

    def in_order() -> Any:
        waiting: dict[int, Any] = {}
        due = 0
        for k, c in enumerate(stream()):
            waiting[position[k]] = rewrite(c.to_record_batch(), k)
            while due in waiting:
                yield waiting.pop(due)
                due += 1
        if waiting:
            msg = f"roslan view: {raw} changed while it was rewritten"
            raise ViewError(msg)

    LazyChunkStream.from_iter(in_order()).write_rrd(
        str(out), application_id="roslan", recording_id=recording_id
    )


def _import_rerun() -> Any:
    try:
        import rerun as rr
    except ImportError:
        msg = (
            "roslan view needs the optional Rerun SDK: pip install 'roslan[view]' "
            "(or pip install rerun-sdk xxhash)"
        )
        raise ViewError(msg) from None
    return rr


def build_recording(
    outdir: Path, save: Path | None, *, event_window_ms: float = 10.0, spawn: bool = False
) -> dict[str, str]:
    """Log the run in ``outdir`` to Rerun: into ``save`` (an .rrd file) or, with ``spawn``,
    a viewer. Returns the entity path of every sensor (sensor name -> entity)."""
    if not (outdir / "run.json").is_file():
        msg = f"roslan view: {outdir} is not a complete roslan run folder (no run.json)"
        raise ViewError(msg)
    if not event_window_ms > 0:
        msg = f"roslan view: --event-window-ms = {event_window_ms!r}: must be > 0"
        raise ViewError(msg)
    rr = _import_rerun()
    run = json.loads((outdir / "run.json").read_text())
    paths = _bag_paths(outdir)
    recording_id = f"roslan-{outdir.resolve().name}"
    # No wall-clock log_time timeline and no properties (their start time). The batcher
    # never flushes on its clock and sends each logged row as it comes (one byte is
    # enough), so the chunks and their order follow the logging alone, and none is left
    # for its final flush (a hash map's order); the ids are made canonical after
    # (_canonical_rrd). Rerun compacts the small chunks when it loads the file.
    rec = rr.RecordingStream(
        "roslan",
        recording_id=recording_id,
        send_properties=False,
        batcher_config=None
        if save is None
        else rr.ChunkBatcherConfig(flush_tick=_NO_TICK_S, flush_num_bytes=1),
    )
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    raw = None if save is None else save.with_name(save.name + ".raw")
    if raw is not None:
        rec.save(str(raw))
    elif spawn:
        rec.spawn()
    try:
        entities = _log_run(rr, rec, outdir, run, paths, event_window_ms)
        if raw is not None and save is not None:
            rec.flush()
            rec.disconnect()
            stamp_ns = int(run["start_time_ns"])
            _canonical_rrd(raw, save, recording_id, stamp_ns)
            why = canonicalize_envelope(save, stamp_ns)
            if why is not None:
                warnings.warn(
                    f"roslan view: the recording is valid but not byte-reproducible: {why}",
                    stacklevel=2,
                )
    finally:
        if raw is not None:
            raw.unlink(missing_ok=True)
    return entities


def _log_run(
    rr: Any,
    rec: Any,
    outdir: Path,
    run: dict[str, Any],
    paths: list[Path],
    event_window_ms: float,
) -> dict[str, str]:
    from rosbags.highlevel import AnyReader

    from roslan.rundir.calibration import root_camera_name
    from roslan.scene.loader import load_scene
    from roslan.scene.markers import scene_mesh

    topics: dict[str, dict[str, Any]] = run["topics"]
    sensors: list[dict[str, Any]] = [
        s for s in (run.get("config") or {}).get("sensors", []) if isinstance(s, dict)
    ]
    entities: dict[str, str] = {}
    with rec:
        log = _Logger(rr, int(run["start_time_ns"]), event_window_ms)
        rr.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        scene_file = outdir / "scene" / "scene.yaml"
        if scene_file.is_file():
            mesh = scene_mesh(load_scene(scene_file))
            rr.log(
                "world/scene",
                rr.Mesh3D(
                    vertex_positions=mesh.corners.reshape(-1, 3).astype(np.float32),
                    vertex_colors=np.repeat((mesh.colors * 255).astype(np.uint8), 3, axis=0),
                ),
                static=True,
            )
        rr.log("world/base_link", rr.TransformAxes3D(0.2), static=True)
        handlers = _handlers(log)
        with AnyReader(paths) as reader:
            tree: dict[str, tuple[str, F64]] = {}
            placed: set[str] = set()
            for conn, _, raw in reader.messages(
                connections=[c for c in reader.connections if c.topic == "/tf_static"]
            ):
                tree.update(_static_tree(reader.deserialize(raw, conn.msgtype)))
            wanted = [
                c
                for c in reader.connections
                if c.msgtype in handlers
                and not c.topic.endswith("/event_image")  # drawn from the event files
                and (
                    c.topic == "/ground_truth/pose"
                    or topics.get(c.topic, {}).get("publisher", "ground_truth") != "ground_truth"
                )
            ]
            for conn, stamp, raw in reader.messages(connections=wanted):
                m: Any = reader.deserialize(raw, conn.msgtype)
                owner = topics.get(conn.topic, {}).get("publisher", "ground_truth")
                if owner == "ground_truth":
                    handlers[conn.msgtype]("world/base_link", stamp, m)
                    continue
                frame = m.header.frame_id
                entity = f"world/base_link/{owner}/{frame}"
                if entity not in placed:
                    placed.add(entity)
                    T = _T_base(tree, frame)
                    rr.log(
                        entity,
                        rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]),
                        static=True,
                    )
                    entities.setdefault(owner, entity)
                handlers[conn.msgtype](entity, stamp, m)
        log.flush_series()
        root = root_camera_name((str(s.get("type")), str(s.get("name"))) for s in sensors)
        for s in sensors:
            name = str(s.get("name"))
            if s.get("type") == "event_camera":
                entity = entities.get(name, f"world/base_link/{name}")
                if _log_events(log, outdir, name, entity, root):
                    entities.setdefault(name, entity)
    return entities
