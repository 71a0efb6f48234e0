"""Local (object-frame) triangle meshes: primitives with metric UVs, merging, placement.

A :class:`LocalMesh` is geometry in an object's own frame, float64, with vertex
normals and UVs. Primitives put their UVs in metres along the surface, so a
material's ``texture_scale`` means "repeats per metre". :func:`place` turns a local
mesh into a world-frame :class:`~roslan.scene.model.SceneObject` (scale, then pose).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from roslan.frames import rpy_to_matrix
from roslan.scene.model import Material, SceneObject

__all__ = [
    "LocalMesh",
    "box",
    "capsule",
    "closed_solid",
    "cylinder",
    "cylinder_between",
    "merge",
    "place",
    "plane",
    "pose_matrix",
    "ring",
    "sphere",
    "transformed",
]

F64 = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class LocalMesh:
    """Triangles in an object frame.

    Attributes:
        vertices: (V, 3) float64 positions, m.
        normals: (V, 3) float64 unit vertex normals.
        uvs: (V, 2) float64 texture coordinates (metres along the surface for primitives).
        faces: (F, 3) int64 vertex indices, counter-clockwise seen from outside.
    """

    vertices: F64
    normals: F64
    uvs: F64
    faces: NDArray[np.int64]

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])


def pose_matrix(position: ArrayLike = (0.0, 0.0, 0.0), rpy: ArrayLike = (0.0, 0.0, 0.0)) -> F64:
    """4x4 ``T_parent_child`` from a position (m) and roll/pitch/yaw (rad)."""
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(np.asarray(rpy, dtype=np.float64))
    T[:3, 3] = np.asarray(position, dtype=np.float64)
    return T


def _quad(center: F64, n: F64, u: F64, v: F64, hu: float, hv: float) -> LocalMesh:
    """One rectangle, normal ``n = u x v``, UVs in metres from its corner."""
    su = np.array([-1.0, 1.0, 1.0, -1.0])
    sv = np.array([-1.0, -1.0, 1.0, 1.0])
    verts = center + (su * hu)[:, None] * u + (sv * hv)[:, None] * v
    uvs = np.stack([(su + 1.0) * hu, (sv + 1.0) * hv], axis=1)
    faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    return LocalMesh(verts, np.tile(n, (4, 1)), uvs, faces)


_AX = np.eye(3)


# the six faces of a box: (axis of the face centre, its sign, u axis, v axis), each face
# spanned by +-half[u-extent] * u, +-half[v-extent] * v with normal = sign * axis = u x v
_BOX_AXIS = np.array([0, 0, 1, 1, 2, 2])
_BOX_SIGN = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
_BOX_U = np.array([_AX[1], -_AX[1], -_AX[0], _AX[0], _AX[0], _AX[0]])
_BOX_V = np.array([_AX[2], _AX[2], _AX[2], _AX[2], _AX[1], -_AX[1]])
_BOX_HU = np.array([1, 1, 0, 0, 0, 0])  # which half size spans u
_BOX_HV = np.array([2, 2, 2, 2, 1, 1])
_QUAD_SU = np.array([-1.0, 1.0, 1.0, -1.0])
_QUAD_SV = np.array([-1.0, -1.0, 1.0, 1.0])
_BOX_FACES = (np.array([[0, 1, 2], [0, 2, 3]]) + 4 * np.arange(6)[:, None, None]).reshape(12, 3)
_BOX_NORMALS = np.repeat(_BOX_SIGN[:, None] * _AX[_BOX_AXIS], 4, axis=0)


def box(size: Sequence[float], center: Sequence[float] = (0.0, 0.0, 0.0)) -> LocalMesh:
    """Axis-aligned box of ``size`` (sx, sy, sz) m around ``center``; 24 vertices, 12 triangles.

    Six :func:`_quad` faces (+x, -x, +y, -y, +z, -z), evaluated together (same numbers)."""
    half = np.array([float(s) / 2.0 for s in size])
    c = np.asarray(center, dtype=np.float64)
    centres = c + (_BOX_SIGN * half[_BOX_AXIS])[:, None] * _AX[_BOX_AXIS]  # (6, 3)
    hu, hv = half[_BOX_HU][:, None], half[_BOX_HV][:, None]  # (6, 1)
    a, b = _QUAD_SU * hu, _QUAD_SV * hv  # (6, 4)
    verts = (
        centres[:, None, :] + a[..., None] * _BOX_U[:, None, :] + b[..., None] * _BOX_V[:, None, :]
    )
    uvs = np.stack([(_QUAD_SU + 1.0) * hu, (_QUAD_SV + 1.0) * hv], axis=-1)
    return LocalMesh(
        verts.reshape(24, 3), _BOX_NORMALS.copy(), uvs.reshape(24, 2), _BOX_FACES.copy()
    )


def plane(size: Sequence[float]) -> LocalMesh:
    """Rectangle ``size`` (sx, sy) m in z = 0 centred at the origin, facing +z (one-sided)."""
    return _quad(np.zeros(3), _AX[2], _AX[0], _AX[1], float(size[0]) / 2.0, float(size[1]) / 2.0)


def cylinder(radius: float, height: float, segments: int = 32, caps: bool = True) -> LocalMesh:
    """Cylinder along z from -height/2 to +height/2. Side UVs: (arc length, z) in m."""
    n = int(segments)
    th = np.linspace(0.0, 2.0 * math.pi, n + 1)
    th[-1] = 0.0  # close the seam exactly
    c, s = np.cos(th), np.sin(th)
    h2 = height / 2.0
    ring_xy = np.stack([radius * c, radius * s], axis=1)
    bottom = np.column_stack([ring_xy, np.full(n + 1, -h2)])
    top = np.column_stack([ring_xy, np.full(n + 1, h2)])
    verts = np.concatenate([bottom, top])
    normals = np.concatenate([np.column_stack([c, s, np.zeros(n + 1)])] * 2)
    arc = np.linspace(0.0, 2.0 * math.pi * radius, n + 1)
    uvs = np.concatenate(
        [np.column_stack([arc, np.zeros(n + 1)]), np.column_stack([arc, np.full(n + 1, height)])]
    )
    j = np.arange(n)
    b0, b1, t0, t1 = j, j + 1, j + n + 1, j + n + 2
    faces = np.concatenate([np.stack([b0, b1, t1], 1), np.stack([b0, t1, t0], 1)])
    parts = [LocalMesh(verts, normals, uvs, faces)]
    if caps:
        for zc, sign in ((h2, 1.0), (-h2, -1.0)):
            cv = np.concatenate([[[0.0, 0.0, zc]], np.column_stack([ring_xy[:n], np.full(n, zc)])])
            cn = np.tile([0.0, 0.0, sign], (n + 1, 1))
            cuv = cv[:, :2].copy()
            a = np.arange(1, n + 1)
            b = np.roll(a, -1)
            f = (
                np.stack([np.zeros(n, np.int64), a, b], 1)
                if sign > 0
                else np.stack([np.zeros(n, np.int64), b, a], 1)
            )
            parts.append(LocalMesh(cv, cn, cuv, f))
    return merge(parts)


def _lathe(rows_phi: F64, rows_z: F64, radius: float, segments: int) -> LocalMesh:
    """Surface of revolution of sphere-like rows: polar angle ``phi`` from +z, shifted by ``z``."""
    n = int(segments)
    th = np.linspace(0.0, 2.0 * math.pi, n + 1)
    th[-1] = 0.0
    sp, cp = np.sin(rows_phi), np.cos(rows_phi)
    nrm = np.stack(
        [
            sp[:, None] * np.cos(th)[None, :],
            sp[:, None] * np.sin(th)[None, :],
            np.repeat(cp[:, None], n + 1, 1),
        ],
        axis=-1,
    )
    verts = radius * nrm
    verts[..., 2] += rows_z[:, None]
    # v: arc length of the profile from the bottom; u: arc length around at the equator
    prof = np.concatenate(
        [[0.0], np.cumsum(np.hypot(np.diff(verts[:, 0, 0]), np.diff(verts[:, 0, 2])))]
    )
    vcoord = prof[-1] - prof
    ucoord = np.linspace(0.0, 2.0 * math.pi * radius, n + 1)
    uvs = np.stack(np.broadcast_arrays(ucoord[None, :], vcoord[:, None]), axis=-1)
    m = rows_phi.shape[0]
    i, j = np.meshgrid(np.arange(m - 1), np.arange(n), indexing="ij")
    a = i * (n + 1) + j
    b = (i + 1) * (n + 1) + j
    c = b + 1
    d = a + 1
    top = (sp[i] < 1e-12).ravel()  # row i is a pole: (a, c, d) degenerates
    bot = (sp[i + 1] < 1e-12).ravel()
    t1 = np.stack([a.ravel(), b.ravel(), c.ravel()], 1)[~bot]
    t2 = np.stack([a.ravel(), c.ravel(), d.ravel()], 1)[~top]
    return LocalMesh(
        verts.reshape(-1, 3),
        nrm.reshape(-1, 3),
        uvs.reshape(-1, 2),
        np.concatenate([t1, t2]).astype(np.int64),
    )


def sphere(radius: float, segments: int = 24) -> LocalMesh:
    """UV sphere centred at the origin: ``segments`` around, ``segments // 2`` pole to pole."""
    rows = max(int(segments) // 2, 2)
    phi = np.linspace(0.0, math.pi, rows + 1)
    return _lathe(phi, np.zeros(rows + 1), radius, segments)


def capsule(radius: float, height: float, segments: int = 24) -> LocalMesh:
    """Capsule along z, total length ``height`` (>= 2 radius) tip to tip, centred at the origin."""
    half = max(int(segments) // 4, 2)
    hc = max(height / 2.0 - radius, 0.0)
    up = np.linspace(0.0, math.pi / 2.0, half + 1)
    down = np.linspace(math.pi / 2.0, math.pi, half + 1)
    phi = np.concatenate([up, down])
    z = np.concatenate([np.full(half + 1, hc), np.full(half + 1, -hc)])
    return _lathe(phi, z, radius, segments)


def ring(r_in: float, r_out: float, thickness: float, segments: int = 32) -> LocalMesh:
    """Flat annulus (a platform around a column) from z = 0 to z = thickness."""
    n = int(segments)
    th = np.linspace(0.0, 2.0 * math.pi, n + 1)
    th[-1] = 0.0
    c, s = np.cos(th), np.sin(th)
    j = np.arange(n)
    parts = []
    for zc, sign in ((thickness, 1.0), (0.0, -1.0)):
        inner = np.column_stack([r_in * c, r_in * s, np.full(n + 1, zc)])
        outer = np.column_stack([r_out * c, r_out * s, np.full(n + 1, zc)])
        v = np.concatenate([inner, outer])
        i0, i1, o0, o1 = j, j + 1, j + n + 1, j + n + 2
        if sign > 0:
            f = np.concatenate([np.stack([i0, o0, o1], 1), np.stack([i0, o1, i1], 1)])
        else:
            f = np.concatenate([np.stack([i0, o1, o0], 1), np.stack([i0, i1, o1], 1)])
        parts.append(LocalMesh(v, np.tile([0.0, 0.0, sign], (2 * n + 2, 1)), v[:, :2].copy(), f))
    side = cylinder(r_out, thickness, n, caps=False)
    parts.append(transformed(side, pose_matrix((0.0, 0.0, thickness / 2.0))))
    inner_side = cylinder(r_in, thickness, n, caps=False)
    # inner wall faces the axis: flip winding and normals
    parts.append(
        transformed(
            LocalMesh(
                inner_side.vertices, -inner_side.normals, inner_side.uvs, inner_side.faces[:, ::-1]
            ),
            pose_matrix((0.0, 0.0, thickness / 2.0)),
        )
    )
    return merge(parts)


def transformed(mesh: LocalMesh, T: F64) -> LocalMesh:
    """``mesh`` moved by the rigid 4x4 transform ``T`` (UVs unchanged)."""
    R = T[:3, :3]
    return LocalMesh(mesh.vertices @ R.T + T[:3, 3], mesh.normals @ R.T, mesh.uvs, mesh.faces)


def cylinder_between(p0: ArrayLike, p1: ArrayLike, radius: float, segments: int = 24) -> LocalMesh:
    """Cylinder of ``radius`` whose axis runs from ``p0`` to ``p1`` (m)."""
    a = np.asarray(p0, dtype=np.float64)
    b = np.asarray(p1, dtype=np.float64)
    d = b - a
    length = float(np.linalg.norm(d))
    z = d / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = (a + b) / 2.0
    return transformed(cylinder(radius, length, segments), T)


def merge(parts: Sequence[LocalMesh]) -> LocalMesh:
    """Concatenate meshes into one (faces re-indexed)."""
    offsets = np.cumsum([0] + [p.vertices.shape[0] for p in parts[:-1]])
    return LocalMesh(
        np.concatenate([p.vertices for p in parts]),
        np.concatenate([p.normals for p in parts]),
        np.concatenate([p.uvs for p in parts]),
        np.concatenate([p.faces + o for p, o in zip(parts, offsets, strict=True)]).astype(np.int64),
    )


def closed_solid(vertices: ArrayLike, faces: ArrayLike) -> bool:
    """True if the triangles bound solids and face outwards: then, seen from outside
    the solids, every back face (one turned away from the viewer) is hidden behind a
    front face of the same mesh, and a renderer may skip back faces.

    Conditions, after merging vertices closer than ~1e-6 of the mesh's size (or a few
    float32 steps of its coordinates, if coarser: duplicate corners of primitives, lathe
    seams and poles) and dropping the faces that merging collapses: every directed edge
    a -> b is matched by an edge b -> a (no border; also where two closed parts touch
    along an edge), and each connected part encloses a positive volume (faces
    counter-clockwise seen from outside).
    Conservative: open surfaces (planes, uncapped tubes, meshes with cracks),
    inside-out parts, zero-volume double-sided sheets, and also hollow solids (their
    cavity is a part of negative volume) are not closed solids.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[0] == 0 or f.shape[1] != 3 or not np.isfinite(v).all():
        return False
    vid = _merged_ids(v)
    mf = vid[f]  # (F, 3) merged vertex ids
    keep = (mf[:, 0] != mf[:, 1]) & (mf[:, 1] != mf[:, 2]) & (mf[:, 2] != mf[:, 0])
    if not keep.any():
        return False
    a = mf[keep].reshape(-1)
    b = mf[keep][:, [1, 2, 0]].reshape(-1)
    n = int(vid.max()) + 1
    if not np.array_equal(np.sort(a * n + b), np.sort(b * n + a)):
        return False
    label = _components(n, a, b)
    tri = v[f[keep]]
    tri -= 0.5 * (tri.min(axis=(0, 1)) + tri.max(axis=(0, 1)))  # conditioning
    vol6 = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    part = label[mf[keep][:, 0]]
    per_part = np.bincount(part, weights=vol6)
    used = np.bincount(part) > 0
    return bool(np.all(per_part[used] > 0.0))


def _merged_ids(v: NDArray[np.float64]) -> NDArray[np.int64]:
    """(V,) id per vertex, equal for vertices on one cell of a grid of 2^-20 of the mesh's
    extent, or of 4 float32 steps at its largest coordinate if coarser (one int64 key per
    vertex: three 21-bit fields of 0 .. 2^20)."""
    lo = v.min(axis=0)
    extent = float(np.ptp(v, axis=0).max())
    tol = max(extent * 2.0**-20, float(np.abs(v).max()) * 2.0**-22, 1e-12)
    q = np.round((v - lo) / tol).astype(np.int64)
    _, vid = np.unique((q[:, 0] << 42) | (q[:, 1] << 21) | q[:, 2], return_inverse=True)
    ids: NDArray[np.int64] = vid.reshape(-1)
    return ids


def _components(n: int, a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.int64]:
    """Connected-component label (its smallest vertex) of vertices 0..n-1 joined by the
    edges a-b: hooking onto the smaller label, then pointer jumping, until stable."""
    label = np.arange(n, dtype=np.int64)
    while True:
        la, lb = label[a], label[b]
        low = np.minimum(la, lb)
        new = label.copy()
        np.minimum.at(new, la, low)
        np.minimum.at(new, lb, low)
        while True:
            jumped = new[new]
            if np.array_equal(jumped, new):
                break
            new = jumped
        if np.array_equal(new, label):
            return label
        label = new


def _frozen(a: NDArray[np.generic]) -> NDArray[np.generic]:
    a.flags.writeable = False
    return a


def place(
    name: str,
    mesh: LocalMesh,
    material: Material,
    pose: F64 | None = None,
    scale: Sequence[float] = (1.0, 1.0, 1.0),
    source: str = "",
) -> SceneObject:
    """World-frame :class:`SceneObject` from a local mesh: ``p_world = R (scale * p) + t``.

    The local vertices/normals are kept (float32) on the object so that an export
    writes exactly the numbers a reload turns back into the same world triangles.
    """
    T = np.eye(4) if pose is None else np.asarray(pose, dtype=np.float64)
    sc = np.asarray(scale, dtype=np.float64)
    local_v = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
    local_n = np.ascontiguousarray(mesh.normals, dtype=np.float32)
    return place_local(name, local_v, local_n, mesh.uvs, mesh.faces, material, T, sc, source)


def place_local(
    name: str,
    local_v: NDArray[np.float32],
    local_n: NDArray[np.float32],
    uvs: ArrayLike,
    faces: ArrayLike,
    material: Material,
    T: F64,
    sc: F64,
    source: str,
) -> SceneObject:
    """As :func:`place`, from float32 local arrays (used by the file loader)."""
    R = T[:3, :3]
    world = (local_v.astype(np.float64) * sc) @ R.T + T[:3, 3]
    n = (local_n.astype(np.float64) / sc) @ R.T
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = n / np.where(norm > 0, norm, 1.0)
    return SceneObject(
        name=name,
        vertices=_frozen(np.ascontiguousarray(world, dtype=np.float32)),  # type: ignore[arg-type]
        normals=_frozen(np.ascontiguousarray(n, dtype=np.float32)),  # type: ignore[arg-type]
        uvs=_frozen(np.ascontiguousarray(uvs, dtype=np.float32)),  # type: ignore[arg-type]
        faces=_frozen(np.ascontiguousarray(faces, dtype=np.int32)),  # type: ignore[arg-type]
        material=material,
        pose=_frozen(T.copy()),  # type: ignore[arg-type]
        scale=(float(sc[0]), float(sc[1]), float(sc[2])),
        source=source,
        local_vertices=_frozen(local_v),  # type: ignore[arg-type]
        local_normals=_frozen(local_n),  # type: ignore[arg-type]
    )
