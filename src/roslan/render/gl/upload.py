"""Scene upload: one vertex/index buffer for the whole scene, its triangles grouped by
texture and, inside each group, into spatial culling clusters (one object's triangles
in one grid cell) with bounding boxes; the frustum culling over those clusters; and
the sun's shadow map, rendered once for a static scene.

A moving object (:attr:`SceneObject.is_static <roslan.scene.model.SceneObject.is_static>`
False) is uploaded like the others, and :meth:`SceneBuffers.move_to` rewrites only its
own vertex range (positions and normals at the render's time); its clusters are never
frustum-culled and its back faces never skipped (their boxes would be stale), and the
shadow map is drawn again for each new time. A static scene never takes this path: its
buffers, draws and pixels are those of a static upload."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.render.gl.context import gl_mat
from roslan.render.gl.mipmaps import mip_chain
from roslan.scene.mesh import closed_solid

if TYPE_CHECKING:
    from roslan.scene.model import Scene, SceneObject

__all__ = ["CLUSTER_CELLS", "SHADOW_MAP_MAX", "SceneBuffers", "ShadowMap", "merge_runs"]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

CLUSTER_CELLS = 12
"""Culling granularity: an object's triangles are split by a grid of cubic cells of
``max(scene diagonal / CLUSTER_CELLS, 1 m)``."""

SHADOW_MAP_MAX = 2048
"""Largest shadow map (texels per side), on every OpenGL implementation (llvmpipe's
lookups are memory bound; one size everywhere keeps the shadows' edges the same)."""

_UNBOUNDED = 1e30
"""Half size (m) of a moving object's culling boxes: never outside a frustum (finite, so
that ``0 * half`` stays 0)."""

_GL_SRGB8 = 0x8C41
_GL_SRGB8_ALPHA8 = 0x8C43


def _vertex_attrs(o: SceneObject) -> F32:
    """(V, 11) interleaved vertex attributes: position, normal, scaled UV, albedo."""
    attrs = np.empty((o.vertices.shape[0], 11), dtype=np.float32)
    attrs[:, 0:3] = o.vertices
    attrs[:, 3:6] = o.normals
    attrs[:, 6:8] = o.uvs * np.float32(o.material.texture_scale)
    attrs[:, 8:11] = np.asarray(o.material.color, dtype=np.float32)
    return attrs


def _texture(ctx: Any, img: NDArray[np.uint8]) -> Any:
    """A mip-mapped, repeating sRGB texture of an (H, W, 3+) uint8 image: the levels are
    computed by :func:`~roslan.render.gl.mipmaps.mip_chain` (the same on every OpenGL
    implementation); no hardware anisotropic filtering (the colour shader filters
    anisotropically itself, see :mod:`roslan.render.gl.shaders`)."""
    h, w = img.shape[:2]
    # RGBA: 4-byte texels sample ~10 % faster than RGB on llvmpipe.
    # GL's first texture row is v = 0: flip so v = 0 is the image's bottom
    # (the usual glTF/OBJ convention for UVs).
    rgba = np.full((h, w, 4), 255, dtype=np.uint8)
    rgba[..., :3] = img[::-1, :, :3]
    levels = mip_chain(rgba)
    tex = ctx.texture((w, h), 4, levels[0].tobytes(), internal_format=_GL_SRGB8_ALPHA8)
    tex.build_mipmaps()  # allocates every level; each is overwritten below
    for k, lvl in enumerate(levels[1:], start=1):
        tex.write(lvl.tobytes(), level=k)
    # the shader picks integer mip levels (and blends two for trilinear filtering)
    tex.filter = (ctx.LINEAR_MIPMAP_NEAREST, ctx.LINEAR)
    tex.anisotropy = 1.0
    tex.repeat_x = tex.repeat_y = True
    return tex


class _Clusters:
    """Accumulates the faces and culling clusters of the objects, in upload order."""

    def __init__(self, cell: float) -> None:
        self.cell = cell
        self.parts: list[F32] = []  # vertex attributes per object
        self.faces: list[NDArray[np.int32]] = []  # faces per object, sorted by cluster
        self.first: list[int] = []  # per cluster: first index, index count, group, box
        self.count: list[int] = []
        self.group: list[int] = []
        self.lo: list[F32] = []
        self.hi: list[F32] = []
        self.obj: list[int] = []  # per cluster: index into o_lo/o_hi/o_closed
        self.o_lo: list[F32] = []  # per drawn object: bounding box, closed solid
        self.o_hi: list[F32] = []
        self.o_closed: list[bool] = []
        self.closed_names: list[str] = []
        self.source: list[NDArray[np.int64]] = []  # per uploaded face: its scene triangle
        self.offset = 0  # vertices so far
        self.movers: list[tuple[SceneObject, int, int, int]] = []  # (obj, v0, cluster0, n)

    def add(self, o: SceneObject, group: int, first: int, tri0: int) -> int:
        """Add object ``o`` of texture group ``group`` whose indices start at ``first``
        and whose first face is triangle ``tri0`` of :attr:`Scene.triangles`; returns its
        index count."""
        nv = int(o.vertices.shape[0])
        nf = int(o.faces.shape[0])
        if not o.is_static:
            self.movers.append((o, self.offset, len(self.first), 0))
        self.parts.append(_vertex_attrs(o))
        tri = o.vertices[o.faces]  # (F, 3, 3)
        cells = np.floor(tri.mean(axis=1) / self.cell).astype(np.int64)
        _, inv = np.unique(cells, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        order = np.argsort(inv, kind="stable")
        self.faces.append(o.faces[order].astype(np.int32) + self.offset)
        self.source.append(order.astype(np.int64) + tri0)
        sizes = np.bincount(inv)
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        self.lo.append(np.minimum.reduceat(tri.min(axis=1)[order], starts, axis=0))
        self.hi.append(np.maximum.reduceat(tri.max(axis=1)[order], starts, axis=0))
        self.first.extend((first + 3 * starts).tolist())
        self.count.extend((3 * sizes).tolist())
        self.group.extend([group] * sizes.size)
        self.obj.extend([len(self.o_closed)] * sizes.size)
        self.o_lo.append(tri.min(axis=(0, 1)))
        self.o_hi.append(tri.max(axis=(0, 1)))
        self.o_closed.append(closed_solid(o.vertices, o.faces))
        if not o.is_static:
            m = self.movers[-1]
            self.movers[-1] = (m[0], m[1], m[2], len(self.first) - m[2])
            self.o_lo[-1] = np.full(3, -_UNBOUNDED, np.float32)  # never back-face culled
            self.o_hi[-1] = np.full(3, _UNBOUNDED, np.float32)
        if self.o_closed[-1]:
            self.closed_names.append(o.name)
        self.offset += nv
        return 3 * nf


class SceneBuffers:
    """The whole scene in one interleaved VBO + IBO, faces sorted by texture, then by
    object and grid cell (the culling clusters).

    Attributes:
        vbo, ibo: the vertex and index buffers (None for a scene without triangles).
        group_tex: the texture of each texture group (index ``group`` of a draw run).
        vao_depth, vao_shadow: position-only vertex arrays of the depth and shadow
            programs (None without triangles).
        closed_solids: names of the objects whose back faces may be culled.
        tri_source: (F,) int64, for every uploaded triangle (index buffer order) its
            index in :attr:`Scene.triangles <roslan.scene.model.Scene.triangles>`.
    """

    def __init__(
        self,
        ctx: Any,
        scene: Scene,
        *,
        cell: float,
        prog_depth: Any,
        prog_shadow: Any,
    ) -> None:
        self.group_tex: list[Any] = []
        self.textures: list[Any] = []  # owned (released with the buffers)
        acc = self._fill(ctx, scene, _Clusters(cell))
        self.c_first = np.asarray(acc.first, dtype=np.int64)
        self.c_count = np.asarray(acc.count, dtype=np.int64)
        self.c_group = np.asarray(acc.group, dtype=np.int64)
        self.closed_solids = frozenset(acc.closed_names)
        self.c_obj = np.asarray(acc.obj, dtype=np.int64)
        self.c_closed = np.asarray(acc.o_closed, dtype=bool)[self.c_obj]
        self.o_lo = np.asarray(acc.o_lo, dtype=np.float64).reshape(-1, 3)
        self.o_hi = np.asarray(acc.o_hi, dtype=np.float64).reshape(-1, 3)
        self.tri_source = np.concatenate(acc.source) if acc.source else np.zeros(0, dtype=np.int64)
        self.vbo: Any = None
        self.ibo: Any = None
        self.movers: list[tuple[SceneObject, int, F32 | None]] = []
        self.vao_depth: Any = None
        self.vao_shadow: Any = None
        if acc.offset == 0:
            self.c_centre = self.c_half = np.zeros((0, 3))
            return
        lo = np.concatenate(acc.lo).astype(np.float64)
        hi = np.concatenate(acc.hi).astype(np.float64)
        self.c_centre = 0.5 * (lo + hi)
        self.c_half = 0.5 * (hi - lo) + 1e-4
        for _, _, c0, nc in acc.movers:
            self.c_half[c0 : c0 + nc] = _UNBOUNDED
        self.movers = [
            (o, v0, acc.parts[acc.obj[c0]] if nc else None) for o, v0, c0, nc in acc.movers
        ]
        self.moved_at: float | None = None  # the time the moving objects' vertices are at
        self.mover_lo = self.mover_hi = np.zeros(3)
        data = np.concatenate(acc.parts)
        idx = np.concatenate(acc.faces).reshape(-1)
        self.vbo = ctx.buffer(data.tobytes())
        self.ibo = ctx.buffer(idx.astype(np.uint32).tobytes())
        self.vao_depth = ctx.vertex_array(
            prog_depth, [(self.vbo, "3f 32x", "in_pos")], self.ibo, index_element_size=4
        )
        self.vao_shadow = ctx.vertex_array(
            prog_shadow, [(self.vbo, "3f 32x", "in_pos")], self.ibo, index_element_size=4
        )
        self.n_index = int(idx.size)

    def _fill(self, ctx: Any, scene: Scene, acc: _Clusters) -> _Clusters:
        """Add the objects group by group (one group per texture) and make the textures."""
        groups: dict[int, list[int]] = {}
        images: dict[int, NDArray[np.uint8] | None] = {0: None}
        tri0 = np.concatenate([[0], np.cumsum([o.faces.shape[0] for o in scene.objects])])
        for i, obj in enumerate(scene.objects):
            tex = obj.material.texture
            key = 0 if tex is None else id(tex)
            images[key] = tex
            groups.setdefault(key, []).append(i)
        white = ctx.texture((1, 1), 3, bytes([255, 255, 255]), internal_format=_GL_SRGB8)
        self.textures.append(white)
        first = 0
        for key, members in groups.items():
            g = len(self.group_tex)
            count = 0
            for i in members:
                o = scene.objects[i]
                if o.faces.shape[0] != 0:
                    count += acc.add(o, g, first + count, int(tri0[i]))
            if count == 0:
                continue
            img = images[key]
            if img is None:
                tex = white
            else:
                tex = _texture(ctx, img)
                self.textures.append(tex)
            self.group_tex.append(tex)
            first += count
        return acc

    def move_to(self, t: float) -> bool:
        """Place the moving objects at trajectory time ``t`` (s): rewrite their vertex
        ranges (positions, normals) when ``t`` is not the time they are at; True when
        they moved (the shadow map is then stale). No moving object: False, nothing done."""
        if not self.movers or self.moved_at == t:
            return False
        los, his = [], []
        for o, v0, attrs in self.movers:
            if attrs is None:
                continue
            T = o.pose_at(t)
            R = T[:3, :3]
            loc_n = o.model_geometry()[1]
            sc = np.asarray(o.scale, dtype=np.float64)
            n = (loc_n.astype(np.float64) / sc) @ R.T
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
            pos = o.vertices_at(t)
            attrs[:, 0:3] = pos
            attrs[:, 3:6] = n
            self.vbo.write(attrs.tobytes(), offset=4 * 11 * v0)
            los.append(pos.min(axis=0))
            his.append(pos.max(axis=0))
        if los:
            self.mover_lo = np.min(los, axis=0).astype(np.float64)
            self.mover_hi = np.max(his, axis=0).astype(np.float64)
        self.moved_at = t
        return True

    @property
    def n_clusters(self) -> int:
        """Number of culling clusters of the scene."""
        return int(self.c_first.size)

    def visible_ranges(
        self,
        clip_from_world: F64,
        eye: F64 | None = None,
        *,
        sort: bool = True,
        near_reach: float = 0.0,
        cull_back_faces: bool = True,
    ) -> tuple[I64, I64, I64, NDArray[np.bool_]]:
        """Index ranges to draw for a view (see :meth:`Renderer.visible_ranges
        <roslan.render.gl.Renderer.visible_ranges>`); ``cull_back_faces`` enables the
        back-face culling of closed solids."""
        M = np.asarray(clip_from_world, dtype=np.float64)
        planes = np.stack([M[3] + M[0], M[3] - M[0], M[3] + M[1], M[3] - M[1], M[3] + M[2]])
        # a box is outside if it lies wholly on the negative side of one plane
        s = self.c_centre @ planes[:, :3].T + planes[:, 3]
        r = self.c_half @ np.abs(planes[:, :3]).T
        idx = np.flatnonzero(np.all(s + r >= 0.0, axis=1))
        if idx.size == 0:
            e = np.zeros(0, dtype=np.int64)
            return e, e, e, np.zeros(0, dtype=bool)
        if eye is not None and sort:
            gap = np.abs(self.c_centre[idx] - np.asarray(eye, dtype=np.float64))
            gap = np.maximum(gap - self.c_half[idx], 0.0)  # 0 inside the box
            idx = idx[np.argsort(np.einsum("ij,ij->i", gap, gap), kind="stable")]
        cull = np.zeros(idx.size, dtype=bool)
        if eye is not None and cull_back_faces:
            e = np.asarray(eye, dtype=np.float64)
            m = float(near_reach) + 1e-6
            inside = np.all((e >= self.o_lo - m) & (e <= self.o_hi + m), axis=1)
            cull = self.c_closed[idx] & ~inside[self.c_obj[idx]]
        brk = (
            np.flatnonzero(
                (np.diff(idx) != 1) | (np.diff(self.c_group[idx]) != 0) | (cull[1:] != cull[:-1])
            )
            + 1
        )
        begin = np.concatenate([[0], brk])
        starts = idx[begin]
        ends = idx[np.concatenate([brk - 1, [idx.size - 1]])]
        first = self.c_first[starts]
        count = self.c_first[ends] + self.c_count[ends] - first
        return first, count, self.c_group[starts], cull[begin]

    def release(self) -> None:
        """Free the textures, buffers and vertex arrays."""
        for tex in self.textures:
            tex.release()
        for o in (self.vao_depth, self.vao_shadow, self.vbo, self.ibo):
            if o is not None:
                o.release()


class ShadowMap:
    """Orthographic depth map along the sun over the scene's bounding sphere.

    Attributes:
        tex: the depth texture (compare mode, bilinear PCF).
        light: column-major bytes of the shadow-map ``[0,1]^3`` from world matrix.
        texel: texel size in ``[0, 1]`` units.
    """

    def __init__(
        self,
        ctx: Any,
        scene: Scene,
        buffers: SceneBuffers,
        prog_shadow: Any,
        *,
        max_size: int,
    ) -> None:
        lo, hi = scene.bounds
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        # ~1 cm texels where affordable, 1024..SHADOW_MAP_MAX texels
        size = int(
            np.clip(2 ** math.ceil(math.log2(max(2 * radius / 0.01, 1.0))), 1024, SHADOW_MAP_MAX)
        )
        size = min(size, max_size)
        L = _light_matrix(np.asarray(scene.lights.sun_direction, dtype=np.float64), centre, radius)
        to_unit = np.array(
            [[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]], dtype=np.float64
        )
        self.tex = ctx.depth_texture((size, size))
        self.tex.compare_func = "<="
        self.tex.filter = (ctx.LINEAR, ctx.LINEAR)
        self.tex.repeat_x = self.tex.repeat_y = False
        self.fbo = ctx.framebuffer(depth_attachment=self.tex)
        self._L = gl_mat(L)
        self.draw(ctx, buffers, prog_shadow)
        self.light = gl_mat(to_unit @ L)
        self.texel = 1.0 / size

    def draw(self, ctx: Any, buffers: SceneBuffers, prog_shadow: Any) -> None:
        """Draw the map of the buffers as they are now (again after moving objects move;
        the map covers the scene's bounds at upload)."""
        self.fbo.use()
        self.fbo.clear(depth=1.0)
        if buffers.vao_shadow is not None:
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            prog_shadow["u_mvp"].write(self._L)
            buffers.vao_shadow.render(ctx.TRIANGLES)

    def release(self) -> None:
        """Free the framebuffer and the texture."""
        self.fbo.release()
        self.tex.release()


def _light_matrix(d: F64, centre: F64, radius: float) -> F64:
    """Light coordinates in [-1, 1] from world: lateral / radius, along the light travel
    ``d`` -> depth, centred on the bounding sphere (``centre``, ``radius``)."""
    fwd = d / max(float(np.linalg.norm(d)), 1e-12)
    up = np.array([0.0, 0.0, 1.0]) if abs(fwd[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    up2 = np.cross(right, fwd)
    L = np.zeros((4, 4))
    L[0, :3], L[0, 3] = right / radius, -right @ centre / radius
    L[1, :3], L[1, 3] = up2 / radius, -up2 @ centre / radius
    L[2, :3], L[2, 3] = fwd / radius, -fwd @ centre / radius
    L[3, 3] = 1.0
    return L


def merge_runs(first: I64, count: I64, cull: NDArray[np.bool_]) -> list[tuple[int, int, bool]]:
    """Index ranges ``(first, count, cull)`` with adjacent ones of the same culling
    joined (texture-free passes)."""
    out: list[tuple[int, int, bool]] = []
    for f, n, c in zip(first.tolist(), count.tolist(), cull.tolist(), strict=True):
        if out and out[-1][0] + out[-1][1] == f and out[-1][2] == c:
            out[-1] = (out[-1][0], out[-1][1] + n, c)
        else:
            out.append((f, n, c))
    return out
