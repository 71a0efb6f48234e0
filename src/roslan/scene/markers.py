"""The scene as a latched ``/scene`` topic: one ``visualization_msgs/MarkerArray``.

RViz and Foxglove show the environment under the trajectory from this one message,
written at t = 0 and latched (ROS 1 ``latching=1``, ROS 2 ``transient_local``). It holds
a single ``TRIANGLE_LIST`` marker (namespace ``scene``, id 0) in the ``world`` frame: three
points per triangle and one colour per point, the object's material colour (sRGB) shaded
once by the scene's sun and ambient light (flat, per triangle), so the geometry reads in a
viewer without lighting of its own.

Triangle budget: a scene of up to :data:`SCENE_TRIANGLE_BUDGET` triangles goes in whole
(the built-in warehouse has 64 936, the refinery 33 864). A larger one is simplified by
vertex clustering (Rossignac & Borrel, "Multi-resolution 3D approximations for rendering
complex scenes", 1993): vertices are snapped to a uniform grid (the mean of the vertices in
each cell), triangles that collapse or repeat are dropped; the cell is the smallest (to 1 % in
size) whose result fits the budget. Flat, large surfaces (floors, walls, tanks) keep their
shape; fine detail merges. The marker takes 120 bytes per triangle (3 float64 points +
3 float32 RGBA colours) before the bags' chunk compression (the warehouse: 7.8 MB, 0.8 MB
in landing.bag with lz4 HC, 0.4 MB in the MCAP with zstd).

The points and colours are appended as NumPy bytes into a message whose other fields
rosbags serializes (its serializer would build a Python object per point).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from roslan.io.messages import MessageStore
from roslan.scene.model import Scene

__all__ = [
    "SCENE_MSGTYPE",
    "SCENE_TOPIC",
    "SCENE_TRIANGLE_BUDGET",
    "SceneMesh",
    "scene_marker_bytes",
    "scene_mesh",
]

SCENE_TOPIC = "/scene"
SCENE_MSGTYPE = "visualization_msgs/msg/MarkerArray"
SCENE_TRIANGLE_BUDGET = 250_000
"""Most triangles the /scene marker carries (30 MB uncompressed at the limit)."""
TRIANGLE_LIST = 11

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


@dataclass(frozen=True)
class SceneMesh:
    """Triangles as the /scene marker carries them.

    Attributes:
        corners: (F, 3, 3) float64 world corners of every triangle, m.
        colors: (F, 3) float32 sRGB colour of every triangle in [0, 1].
        source_triangles: triangles of the scene before simplification.
    """

    corners: F64
    colors: F32
    source_triangles: int

    @property
    def n_triangles(self) -> int:
        return int(self.corners.shape[0])


def _shade(scene: Scene, corners: F64, base: F64) -> F32:
    """Flat Lambert shading with the scene's sun and ambient term, then sRGB."""
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    sun = -np.asarray(scene.lights.sun_direction, dtype=np.float64)
    sun /= max(float(np.linalg.norm(sun)), 1e-12)
    # two-sided: a viewer sees either face
    lambert = np.abs(n @ sun) * scene.lights.sun_intensity
    lin = np.clip(base * (scene.lights.ambient + lambert)[:, None], 0.0, 1.0)
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
    out: F32 = srgb.astype(np.float32)
    return out


def _cluster(
    verts: F64, faces: NDArray[np.int64], cell: float
) -> tuple[F64, NDArray[np.int64], NDArray[np.int64]]:
    """Vertex clustering on a grid of ``cell`` metres: merged vertices, the merged vertex of
    every vertex, and the indices of the surviving faces (three distinct corners, each
    triangle once; first occurrence kept, in order)."""
    cells = np.floor((verts - verts.min(axis=0)) / cell).astype(np.int64)
    size = cells.max(axis=0) + 1
    keys = (cells[:, 0] * size[1] + cells[:, 1]) * size[2] + cells[:, 2]  # one int64 per cell
    _, cluster, counts = np.unique(keys, return_inverse=True, return_counts=True)
    sums = np.zeros((counts.size, 3))
    np.add.at(sums, cluster, verts)
    merged = sums / counts[:, None]
    f = cluster[faces]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    idx = np.flatnonzero(keep)
    tri = np.sort(f[idx], axis=1)
    n = np.int64(counts.size)
    if n < 2_000_000:  # n^3 fits an int64: one key per triangle
        _, first = np.unique((tri[:, 0] * n + tri[:, 1]) * n + tri[:, 2], return_index=True)
    else:
        _, first = np.unique(tri, axis=0, return_index=True)
    idx = idx[np.sort(first)]
    return merged, cluster, idx


def scene_mesh(scene: Scene, budget: int = SCENE_TRIANGLE_BUDGET) -> SceneMesh:
    """The scene's triangles for /scene: whole up to ``budget``, else vertex-clustered
    (module docstring) until at most ``budget`` remain."""
    verts32, faces32, owner = scene.triangles
    verts = verts32.astype(np.float64)
    faces = faces32.astype(np.int64)
    colors = np.array([o.material.color for o in scene.objects], dtype=np.float64).reshape(-1, 3)
    base = colors[owner] if faces.shape[0] else np.zeros((0, 3))
    total = int(faces.shape[0])
    if total > budget:
        extent = max(float(np.max(scene.bounds[1] - scene.bounds[0])), 1e-6)
        # the finest power-of-two cell that fits, then 8 bisection steps of log(cell)
        # between it and half of it (the coarser the cell, the fewer the triangles)
        hi = extent / 8192
        best = _cluster(verts, faces, hi)
        while best[2].size > budget:
            hi *= 2.0
            best = _cluster(verts, faces, hi)
        lo = hi / 2.0
        for _ in range(8):
            mid = float(np.sqrt(lo * hi))
            trial = _cluster(verts, faces, mid)
            if trial[2].size <= budget:
                hi, best = mid, trial
            else:
                lo = mid
        merged, cluster, idx = best
        verts, faces, base = merged, cluster[faces[idx]], base[idx]
    corners = verts[faces] if faces.shape[0] else np.zeros((0, 3, 3))
    return SceneMesh(corners=corners, colors=_shade(scene, corners, base), source_triangles=total)


def _marker_array(store: MessageStore, stamp_ns: int, frame: str, n_pts: int, n_col: int) -> bytes:
    """Wire bytes of a MarkerArray with one TRIANGLE_LIST marker holding ``n_pts`` zero
    points and ``n_col`` zero colours (rosbags' own serializer)."""
    point = store.types["geometry_msgs/msg/Point"]
    color = store.types["std_msgs/msg/ColorRGBA"]
    fields = _marker_fields(store, stamp_ns, frame)
    fields["points"] = [point(x=0.0, y=0.0, z=0.0)] * n_pts
    fields["colors"] = [color(r=0.0, g=0.0, b=0.0, a=0.0)] * n_col
    marker = store.new("visualization_msgs/msg/Marker", **fields)
    msg = store.new(SCENE_MSGTYPE, markers=[marker])
    return store.serialize(msg, SCENE_MSGTYPE)


def _marker_fields(store: MessageStore, stamp_ns: int, frame: str) -> dict[str, object]:
    t = store.types
    fields: dict[str, object] = {
        "header": store.header(stamp_ns, frame),
        "ns": "scene",
        "id": 0,
        "type": TRIANGLE_LIST,
        "action": 0,
        "pose": t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
        "scale": t["geometry_msgs/msg/Vector3"](x=1.0, y=1.0, z=1.0),
        "color": t["std_msgs/msg/ColorRGBA"](r=1.0, g=1.0, b=1.0, a=1.0),
        "lifetime": t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
        "frame_locked": False,
        "points": [],
        "colors": [],
        "text": "",
        "mesh_resource": "",
        "mesh_use_embedded_materials": False,
    }
    if not store.is_ros1:  # ROS 2 Humble's extra fields
        fields["texture_resource"] = ""
        fields["texture"] = store.new(
            "sensor_msgs/msg/CompressedImage",
            header=store.header(0, ""),
            format="",
            data=np.zeros(0, np.uint8),
        )
        fields["uv_coordinates"] = []
        fields["mesh_file"] = store.new(
            "visualization_msgs/msg/MeshFile", filename="", data=np.zeros(0, np.uint8)
        )
    return fields


def _first_difference(a: bytes, b: bytes) -> int:
    n = min(len(a), len(b))
    diff = np.flatnonzero(np.frombuffer(a[:n], np.uint8) != np.frombuffer(b[:n], np.uint8))
    return int(diff[0]) if diff.size else n


def scene_marker_bytes(
    store: MessageStore, stamp_ns: int, mesh: SceneMesh, frame: str = "world"
) -> bytes:
    """Wire bytes (``store``'s flavour) of the /scene MarkerArray of ``mesh``.

    The sequences' length prefixes are located by serializing the message with zero and
    with one point (one colour); the element bytes go in after them, with the alignment
    padding the serializer itself inserted (CDR aligns float64 points to 8 bytes)."""
    empty = _marker_array(store, stamp_ns, frame, 0, 0)
    one_pt = _marker_array(store, stamp_ns, frame, 1, 0)
    one_col = _marker_array(store, stamp_ns, frame, 0, 1)
    at_pts = _first_difference(empty, one_pt)
    at_col = _first_difference(empty, one_col)
    pad_pts = len(one_pt) - len(empty) - 24
    pad_col = len(one_col) - len(empty) - 16
    n = 3 * mesh.n_triangles
    pts = np.ascontiguousarray(mesh.corners, dtype="<f8").reshape(-1)
    rgba = np.ones((mesh.n_triangles, 3, 4), dtype="<f4")
    rgba[..., :3] = mesh.colors[:, None, :]
    if n == 0:
        return empty
    return b"".join(
        (
            empty[:at_pts],
            struct.pack("<I", n),
            b"\0" * pad_pts,
            pts.tobytes(),
            empty[at_pts + 4 : at_col],
            struct.pack("<I", n),
            b"\0" * pad_col,
            rgba.tobytes(),
            empty[at_col + 4 :],
        )
    )
