"""The :class:`Renderer` of one scene and the process-wide registry of renderers.

Camera model: the pose ``T_world_cam`` of the OPTICAL frame (z forward, x right,
y down) and a pinhole ``K``. The projection is built from ``K`` exactly with
OpenCV's convention: pixel centres at integer coordinates, row 0 = top of the
image. The image is rendered upside down in GL's window coordinates (GL's first
row = image row 0), so the readback needs no flip.

Depth: the metric z-depth along the optical axis, written per fragment as 1/z
interpolated at the pixel centre (non-centroid interpolation), so it is independent of
the depth-buffer precision; at silhouettes the nearest sample wins; ``inf`` where
nothing is hit. The depth buffer only resolves visibility.
"""

from __future__ import annotations

import ctypes
import os
import weakref
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError
from roslan.render.base import RenderResult
from roslan.render.color import REC709_LUMA
from roslan.render.gl import shaders
from roslan.render.gl.context import (
    GL_COLOR,
    GL_DEPTH,
    create_context,
    gl_clear_buffer,
    gl_flush,
    gl_mat,
)
from roslan.render.gl.ids import IdPass
from roslan.render.gl.programs import Programs
from roslan.render.gl.settings import MAX_ANISO, default_samples
from roslan.render.gl.supersample import render_supersampled
from roslan.render.gl.targets import Targets, out_array
from roslan.render.gl.upload import CLUSTER_CELLS, SceneBuffers, ShadowMap, merge_runs

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = ["FLUSH_CHUNKS", "Renderer", "get_renderer", "projection_from_K"]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

FLUSH_CHUNKS = 4
"""llvmpipe: the colour pass is flushed to the rasterizer threads in this many parts
(``Renderer.flush_chunks``; 1 = one flush at the end), so that shading overlaps the
vertex work, which runs on the calling thread (see docs/performance.md)."""

_renderers: weakref.WeakKeyDictionary[Scene, Renderer] = weakref.WeakKeyDictionary()
_owner: dict[int, int] = {}
"""id(renderer) -> the process that created it."""


@dataclass(frozen=True)
class _View:
    """One view's matrices and the index ranges to draw (see :meth:`Renderer.visible_ranges`)."""

    mvp: bytes  # clip from world, GLSL layout
    zrow: tuple[float, ...]  # optical z from world
    cam_pos: F64
    first: I64
    count: I64
    group: I64
    cull: NDArray[np.bool_]


def get_renderer(scene: Scene) -> Renderer:
    """The renderer of ``scene`` in this process: created (scene uploaded) on first use
    (and again after a fork: a renderer lives in the GL context of its process). Kept
    while the scene lives (the lookup is weak on the scene, and a renderer does not hold
    its scene); its GPU objects are freed when the last holder lets it go."""
    r = _renderers.get(scene)
    if r is not None and _owner.get(id(r)) != os.getpid():
        r = None  # inherited through fork: its context belongs to the parent
    if r is None:
        r = Renderer(scene)
        _renderers[scene] = r
        _owner[id(r)] = os.getpid()
    return r


def projection_from_K(K: F64, width: int, height: int, near: float, far: float) -> F64:
    """OpenGL clip matrix (4x4) for the optical frame and pinhole ``K`` (OpenCV convention).

    Maps an optical-frame point (x right, y down, z forward, m) to clip coordinates
    whose window position is ``(u + 0.5, v + 0.5)`` for the OpenCV pixel ``(u, v) =
    (fx x/z + s y/z + cx, fy y/z + cy)``: pixel centres at integer coordinates, and
    window row 0 is image row 0 (top), so a GL readback is already top-down. Depth
    maps ``z in [near, far]`` to NDC [-1, 1].
    """
    fx, s, cx = float(K[0, 0]), float(K[0, 1]), float(K[0, 2])
    fy, cy = float(K[1, 1]), float(K[1, 2])
    P = np.zeros((4, 4))
    P[0, 0] = 2.0 * fx / width
    P[0, 1] = 2.0 * s / width
    P[0, 2] = 2.0 * (cx + 0.5) / width - 1.0
    P[1, 1] = 2.0 * fy / height
    P[1, 2] = 2.0 * (cy + 0.5) / height - 1.0
    P[2, 2] = (far + near) / (far - near)
    P[2, 3] = -2.0 * far * near / (far - near)
    P[3, 2] = 1.0
    return P


class Renderer:
    """Rasterizer of one scene. Use :func:`get_renderer` (one per scene and process).

    Attributes:
        max_size: largest image width/height the driver supports (pixels).
        samples: default MSAA samples per pixel of the colour pass (1: no MSAA, the
            edge filter instead); see :func:`default_samples`.
        near: near clipping distance (m), chosen from the scene size.
        max_aniso: most taps of the supersampled reference's anisotropic texture filter
            (:data:`MAX_ANISO`; the default image formation takes at most 2).
        software: True on Mesa's llvmpipe (CPU) renderer (only the flushing differs:
            the image formation is the same on every implementation).
        front_to_back: draw the visible clusters nearest first (default; False: index
            order, for benchmarks), see :meth:`visible_ranges`.
        flush_chunks: flush the colour pass to the rasterizer in this many parts
            (:data:`FLUSH_CHUNKS` on llvmpipe, 1 on GPUs); the image is the same.
        cull_back_faces: skip the back faces of closed solids seen from outside their
            bounding box (default; same image, see :meth:`visible_ranges`; False: draw
            every face, for benchmarks).
        closed_solids: names of the scene objects whose back faces may be culled
            (:func:`~roslan.scene.mesh.closed_solid`).
        buffers: the scene's vertex/index buffers and culling clusters
            (:class:`~roslan.render.gl.upload.SceneBuffers`).
        shadow: the sun's shadow map (:class:`~roslan.render.gl.upload.ShadowMap`).
        programs: the compiled shader programs (:class:`~roslan.render.gl.programs.Programs`).
    """

    def __init__(self, scene: Scene, *, samples: int | None = None) -> None:
        # (the scene's lights only: a renderer must not keep its scene alive, so that the
        # per-process lookup of get_renderer, weak on the scene, lets both go)
        self.lights = scene.lights
        self.ctx = ctx = create_context()
        self.max_size = int(
            min(
                ctx.info["GL_MAX_RENDERBUFFER_SIZE"],
                ctx.info["GL_MAX_TEXTURE_SIZE"],
                *ctx.info["GL_MAX_VIEWPORT_DIMS"],
            )
        )
        # Nothing that changes a pixel depends on the implementation: the texture
        # filter runs in the shader (llvmpipe's own anisotropic filtering stalls for
        # minutes on near-grazing ground planes), mip-maps are computed here, one
        # shadow-map size and one anti-aliasing everywhere.
        self.software = "llvmpipe" in str(ctx.info.get("GL_RENDERER", "")).lower()
        self.samples = self._clamp_samples(default_samples(samples))
        self.max_aniso = MAX_ANISO
        self.front_to_back = True
        self.cull_back_faces = True
        # image load/store (GL 4.2) for the edge filter's point loads
        self._image = int(ctx.version_code) >= 420
        self._flush = gl_flush()
        self._clear_buffer = gl_clear_buffer()
        self.flush_chunks = FLUSH_CHUNKS if self.software else 1
        self._rgb_target = True  # RGB32F edge-filter output where renderable
        self._targets: dict[tuple[int, int, int, bool, bool, bool], Targets] = {}
        self._d_targets: dict[tuple[int, int], tuple[Any, Any, Any]] = {}
        self._released = False
        self._ids: IdPass | None = None  # made on the first render with ids=True

        lo, hi = scene.at(0.0).bounds
        diag = float(np.linalg.norm(hi - lo))
        self._bounds_corners = np.array(
            [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        # 24-bit depth buffer: resolution ~ z^2 / (near * 2^24); 1 cm near gives
        # ~6 mm at 100 m, while cameras may still fly within centimetres of a perch.
        self.near = float(np.clip(1e-4 * diag, 0.005, 0.02))

        self._prog_depth = ctx.program(
            vertex_shader=shaders.VERT_DEPTH, fragment_shader=shaders.FRAG_DEPTH
        )
        self._prog_shadow = ctx.program(
            vertex_shader=shaders.VERT_SHADOW, fragment_shader=shaders.FRAG_SHADOW
        )
        self.buffers = SceneBuffers(
            ctx,
            scene,
            cell=max(diag / CLUSTER_CELLS, 1.0),
            prog_depth=self._prog_depth,
            prog_shadow=self._prog_shadow,
        )
        self.closed_solids = self.buffers.closed_solids
        self.shadow = ShadowMap(
            ctx,
            scene,
            self.buffers,
            self._prog_shadow,
            max_size=self.max_size,
        )
        self.programs = Programs(ctx, scene, self.buffers, self.shadow)

    def _clamp_samples(self, samples: int) -> int:
        return max(1, min(int(samples), int(self.ctx.max_samples)))

    @property
    def n_clusters(self) -> int:
        """Number of culling clusters of the scene."""
        return self.buffers.n_clusters

    def check_size(self, width: int, height: int) -> None:
        """Raise RenderError if the driver cannot render ``width`` x ``height``."""
        if not (1 <= width <= self.max_size and 1 <= height <= self.max_size):
            msg = (
                f"image size {width}x{height} is not supported by this OpenGL renderer "
                f"({self.ctx.info['GL_RENDERER']}): width and height must be 1..{self.max_size}"
            )
            raise RenderError(msg)

    def visible_ranges(
        self,
        clip_from_world: F64,
        eye: F64 | None = None,
        *,
        sort: bool = True,
        near_reach: float = 0.0,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
        """Index ranges to draw for a view: clusters whose box meets the frustum.

        With ``eye`` and ``sort``, the clusters are ordered front to back (by the
        distance from ``eye`` to their box) so that the depth test rejects hidden
        fragments before shading (llvmpipe tests depth early);
        consecutive clusters that are also adjacent in the index buffer with the same
        texture and culling still merge into one run.

        Back-face culling: a run may skip back faces if its object is a closed solid
        and ``eye`` lies outside the object's bounding box grown by ``near_reach``
        (the farthest point of the near-clipping rectangle from the eye): seen from
        outside a closed solid, each back face is behind a front face of the same
        object (and the near plane cuts no solid open), so the image is the same up to
        ties: a back face coplanar with another part's front face, a pixel centre exactly
        on a silhouette edge.

        Args:
            clip_from_world: (4, 4) clip matrix ``P @ T_cam_world``.
            eye: (3,) camera position in the world (m), or None (index order, no culling).
            sort: order front to back (needs ``eye``).
            near_reach: distance (m) from ``eye`` to the near plane's corners.
        Returns:
            ``(first, count, group, cull)``: (R,) first index, index count, texture
            group and back-face culling flag of each run of consecutive visible
            clusters (one draw call each).
        """
        return self.buffers.visible_ranges(
            clip_from_world,
            eye,
            sort=sort,
            near_reach=near_reach,
            cull_back_faces=self.cull_back_faces,
        )

    # ----------------------------------------------------------------- render
    def render(
        self,
        T_world_cam: F64,
        K: F64,
        width: int,
        height: int,
        *,
        color: bool = True,
        depth: bool = True,
        luminance: bool = False,
        samples: int | None = None,
        out: F32 | None = None,
        near: float | None = None,
        supersampling: int = 1,
        t: float | None = None,
        ids: bool = False,
    ) -> RenderResult:
        """Render the view of a pinhole camera.

        Only the requested outputs are computed and read back: ``luminance=True,
        color=False`` is the fast path of grayscale and event cameras (one float32
        channel shaded, resolved and read back instead of RGB); ``color=False,
        luminance=False`` runs a depth-only pass (no MSAA, no shading).

        Args:
            T_world_cam: (4, 4) pose of the camera OPTICAL frame (z forward, x right,
                y down) in the world.
            K: (3, 3) intrinsic matrix (OpenCV convention, pixels).
            width, height: image size (pixels).
            color: compute and return :attr:`RenderResult.color` (H, W, 3) linear RGB.
            depth: compute and return :attr:`RenderResult.depth` (H, W) metric z-depth.
            luminance: compute and return :attr:`RenderResult.luminance` (H, W), the Rec.
                709 luminance of the linear RGB (with ``color`` too, derived from it).
            samples: MSAA samples per pixel for this call (None: :attr:`samples`; 1: no
                MSAA, the edge filter instead; clamped to what the driver supports).
            out: C-contiguous float32 array to read the colour (H, W, 3) into, or the
                luminance (H, W) when ``color`` is False: a caller's reused buffer (fresh
                multi-MB arrays per frame cost page faults).
            near: near clipping distance (m) of this view (None: :attr:`near`); the
                sensors pass their ``near_clip``.
            supersampling: N > 1 renders the reference: N x N samples per pixel on a
                regular grid (an N-times larger render, 1 sample each, no edge filter,
                textures filtered over each sample's own footprint), box-filtered, so
                the result converges to the area average of the true image as N grows;
                depth: see :func:`~roslan.render.gl.supersample.combine_depth`.
                ``samples`` is ignored then.
            t: trajectory time (s) of the view (None: t = 0): each moving object is
                drawn at its pose at ``t`` (:meth:`SceneBuffers.move_to
                <roslan.render.gl.upload.SceneBuffers.move_to>`); a static scene is the
                uploaded one at every time.
            ids: also return :attr:`RenderResult.ids`, the scene triangle at every pixel
                centre of the same view (:mod:`roslan.render.gl.ids`).
        Returns:
            :class:`RenderResult`; row 0 is the top of the image. Arrays are fresh (the
            caller may keep and modify them), except ``out``.
        """
        if self._released:
            msg = "renderer was released"
            raise RenderError(msg)
        width, height = int(width), int(height)
        self.check_size(width, height)
        if self.buffers.move_to(0.0 if t is None else float(t)):
            self.shadow.draw(self.ctx, self.buffers, self._prog_shadow)
        if ids:
            res = self.render(
                T_world_cam, K, width, height, color=color, depth=depth, luminance=luminance,
                samples=samples, out=out, near=near, supersampling=supersampling, t=t,
            )  # fmt: skip
            view = self._view(T_world_cam, K, width, height, near)
            if self._ids is None:
                self._ids = IdPass(self.ctx, self.buffers)
            tri = self._ids.render(
                width, height, view.mvp, view.zrow, (view.first, view.count, view.cull)
            )
            return replace(res, ids=tri)
        if not (color or depth or luminance):
            return RenderResult(None, None)
        n = int(supersampling)
        if n > 1:
            return render_supersampled(
                self, T_world_cam, K, width, height, n, (color, depth, luminance), out, near
            )
        view = self._view(T_world_cam, K, width, height, near)
        if not (color or luminance):
            return RenderResult(None, self._render_depth(width, height, view))
        ns = self.samples if samples is None else self._clamp_samples(samples)
        return self._render_color(view, width, height, color, depth, luminance, ns, False, out)

    def _render_color(
        self,
        view: _View,
        width: int,
        height: int,
        color: bool,
        depth: bool,
        luminance: bool,
        ns: int,
        reference: bool,
        out: F32 | None,
    ) -> RenderResult:
        """The colour pass of a view with ``ns`` MSAA samples (1: then the edge filter,
        unless ``reference``: the supersampled reference's samples), read back."""
        # No ctx.viewport here: in moderngl it writes the viewport of whichever framebuffer
        # is bound *now* (another resolution's), corrupting that target for its next frame.
        # Each target framebuffer keeps its own full-size viewport, applied by fbo.use().
        lum = luminance and not color
        key = (width, height, ns, lum, depth, self._rgb_target)
        t = self._targets.get(key)
        if t is None:
            t = Targets(self.ctx, width, height, ns, lum, depth, self._rgb_target)
            self._targets[key] = t
        fbo = t.ms_fbo if ns > 1 else t.out_fbo
        fbo.use()
        self._clear(fbo, lum, depth)
        if view.first.size:
            self._draw_color(view, lum, depth, reference)
        if ns > 1:
            src = self._resolve_pass(t, ns, lum, depth)
        else:
            src = t.out_fbo if reference else self._edge_pass(t, lum)
        col = lum_out = dep = None
        if lum:
            lum_out = out_array(out, (height, width))
            src.read_into(lum_out, components=1, dtype="f4", attachment=0)
        else:
            col = out_array(out, (height, width, 3))
            src.read_into(col, components=3, dtype="f4", attachment=0)
            if luminance:
                lum_out = col @ np.asarray(REC709_LUMA, dtype=np.float32)
        if depth:
            dep = np.empty((height, width), dtype=np.float32)
            t.out_fbo.read_into(dep, components=1, dtype="f4", attachment=1)
            if ns == 1:
                with np.errstate(divide="ignore"):
                    np.reciprocal(dep, out=dep)  # 1/0 -> inf: nothing hit
        return RenderResult(col, dep, lum_out)

    def _view(self, T_world_cam: F64, K: F64, width: int, height: int, near: float | None) -> _View:
        """Matrices of a view and its visible index ranges (near-to-far, culling flags)."""
        T = np.asarray(T_world_cam, dtype=np.float64)
        T_cam_world = np.linalg.inv(T)
        cam_pos = T[:3, 3]
        z_near = self.near if near is None else float(near)
        corners = self._bounds_corners
        if self.buffers.movers:  # (the moving objects where they are now)
            lo, hi = self.buffers.mover_lo, self.buffers.mover_hi
            box = np.array(
                [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
            )
            corners = np.vstack([corners, box])
        far = float(np.max(np.linalg.norm(corners - cam_pos, axis=1))) * 1.01
        far = max(far, 2.0 * z_near)
        P = projection_from_K(np.asarray(K, dtype=np.float64), width, height, z_near, far)
        clip = P @ T_cam_world
        # the near plane's corners: x/z, y/z at the image corners, z = near
        Kf = np.asarray(K, dtype=np.float64)
        uv = np.array(
            [[-0.5, -0.5], [width - 0.5, -0.5], [-0.5, height - 0.5], [width - 0.5, height - 0.5]]
        )
        y = (uv[:, 1] - Kf[1, 2]) / Kf[1, 1]
        x = (uv[:, 0] - Kf[0, 2] - Kf[0, 1] * y) / Kf[0, 0]
        reach = z_near * float(np.sqrt(np.max(x * x + y * y)) + 1.0)
        first, count, group, cull = self.visible_ranges(
            clip, cam_pos, sort=self.front_to_back, near_reach=reach
        )
        zrow = tuple(float(x) for x in T_cam_world[2])
        return _View(gl_mat(clip), zrow, cam_pos, first, count, group, cull)

    def _flush_marks(self, count: I64) -> set[int]:
        """Indices of the draws after which to flush: those that end each
        1/:attr:`flush_chunks` of the indices (none for 1 chunk or without glFlush)."""
        if self._flush is None or self.flush_chunks <= 1:
            return set()
        cum = np.cumsum(count)
        step = cum[-1] / self.flush_chunks
        marks = set(np.searchsorted(cum, step * np.arange(1, self.flush_chunks)).tolist())
        marks.discard(len(cum) - 1)
        return marks

    def _draw_color(self, view: _View, lum: bool, depth: bool, reference: bool = False) -> None:
        """The colour pass over the visible runs, into the bound framebuffer."""
        ctx = self.ctx
        prog, vao = self.programs.color(lum, depth, reference)
        ctx.enable_only(ctx.DEPTH_TEST)
        ctx.depth_func = "<"
        # outward faces are counter-clockwise seen from outside; the projection
        # keeps image row 0 at window row 0 (a mirror), so on screen they run clockwise
        ctx.front_face = "cw"
        culling = False
        prog["u_mvp"].write(view.mvp)
        # 1/z feeds the edge filter (last colour channel) whether or not depth is read back
        prog["u_zrow"].value = view.zrow
        prog["u_cam_pos"].value = tuple(float(x) for x in view.cam_pos)
        if "u_max_aniso" in prog:  # (a uniform the compiler optimised away is absent)
            prog["u_max_aniso"].value = int(self.max_aniso)
        self.shadow.tex.use(1)
        bound = -1
        # glFlush after the draws that end each 1/flush_chunks of the indices: the
        # rasterizer threads shade the nearer clusters while this thread still runs
        # the vertex work of the farther ones (llvmpipe; same pixels)
        marks = self._flush_marks(view.count)
        group_tex = self.buffers.group_tex
        for i, (f, n, g, c) in enumerate(
            zip(
                view.first.tolist(),
                view.count.tolist(),
                view.group.tolist(),
                view.cull.tolist(),
                strict=True,
            )
        ):
            if g != bound:
                group_tex[g].use(0)
                bound = g
            if c != culling:
                (ctx.enable if c else ctx.disable)(ctx.CULL_FACE)
                culling = c
            vao.render(ctx.TRIANGLES, vertices=n, first=f)
            if i in marks:
                self._flush()  # type: ignore[misc]

    def _resolve_pass(self, t: Targets, ns: int, lum: bool, depth: bool) -> Any:
        """MSAA resolve into ``t.out_fbo`` (average colour samples, nearest depth
        sample); returns the framebuffer to read the colour from."""
        ctx = self.ctx
        t.out_fbo.use()
        ctx.disable(ctx.DEPTH_TEST | ctx.CULL_FACE)
        rprog, quad = self.programs.resolve(lum, depth)
        rprog["u_samples"].value = ns
        t.ms_color.use(0)
        if depth:
            t.ms_invz.use(1)
        quad.render(ctx.TRIANGLES, vertices=3)
        return t.out_fbo

    def _edge_pass(self, t: Targets, lum: bool) -> Any:
        """Edge filter (FXAA-style, in place of MSAA) into ``t.aa_fbo``; returns it."""
        ctx = self.ctx
        t.aa_fbo.use()
        ctx.disable(ctx.DEPTH_TEST | ctx.CULL_FACE)
        _, quad = self.programs.edge_filter(lum, self._image)
        t.out_color.use(0)
        if self._image:
            t.out_color.bind_to_image(0, read=True, write=False)
        quad.render(ctx.TRIANGLES, vertices=3)
        return t.aa_fbo

    def _clear(self, fbo: Any, lum: bool, depth: bool) -> None:
        """Clear a colour-pass target: colour = the sky (luminance: its luma) with 1/z = 0
        (nothing hit), the 1/z attachment (``depth``) = 0, depth buffer = far."""
        sky = tuple(float(x) for x in self.lights.sky)
        if not any(sky):
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            return
        if self._clear_buffer is None:  # (core since GL 3.0; moderngl needs 3.3)
            msg = (
                "this OpenGL driver gives no glClearBufferfv: a scene with a sky colour "
                f"(lights.sky = {list(sky)}) cannot be rendered; use lights.sky = [0, 0, 0]"
            )
            raise RenderError(msg)
        fl4 = ctypes.c_float * 4
        value = (float(np.dot(sky, REC709_LUMA)), 0.0, 0.0, 0.0) if lum else (*sky, 0.0)
        self._clear_buffer(GL_COLOR, 0, fl4(*value))
        if depth:
            self._clear_buffer(GL_COLOR, 1, fl4(0.0, 0.0, 0.0, 0.0))
        self._clear_buffer(GL_DEPTH, 0, fl4(1.0, 0.0, 0.0, 0.0))

    def _render_depth(
        self,
        width: int,
        height: int,
        view: _View,
    ) -> F32:
        """Depth-only pass (no MSAA, fragments at pixel centres): (H, W) z-depth, inf."""
        ctx = self.ctx
        d = self._d_targets.get((width, height))
        if d is None:
            invz = ctx.texture((width, height), 1, dtype="f4")
            drb = ctx.depth_renderbuffer((width, height))
            d = (ctx.framebuffer([invz], drb), invz, drb)
            self._d_targets[(width, height)] = d
        fbo = d[0]
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        vao = self.buffers.vao_depth
        if view.first.size and vao is not None:
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            ctx.front_face = "cw"  # (see render)
            self._prog_depth["u_mvp"].write(view.mvp)
            self._prog_depth["u_zrow"].value = view.zrow
            # one draw over the merged runs of all texture groups
            culling = False
            for f, n, c in merge_runs(view.first, view.count, view.cull):
                if c != culling:
                    (ctx.enable if c else ctx.disable)(ctx.CULL_FACE)
                    culling = c
                vao.render(ctx.TRIANGLES, vertices=n, first=f)
            ctx.disable(ctx.CULL_FACE)
        inv = np.empty((height, width), dtype=np.float32)
        fbo.read_into(inv, components=1, dtype="f4", attachment=0)
        with np.errstate(divide="ignore"):
            np.reciprocal(inv, out=inv)  # 1/0 -> inf: nothing hit
        return inv

    def __del__(self) -> None:
        if _owner.pop(id(self), os.getpid()) == os.getpid():  # (never a parent's, forked)
            self.release()

    def release(self) -> None:
        """Free the GPU objects of this renderer (the context stays for others)."""
        if self._released:
            return
        self._released = True
        try:
            for t in self._targets.values():
                t.release()
            self._targets.clear()
            for d in self._d_targets.values():
                for o in d:
                    o.release()
            self._d_targets.clear()
            if self._ids is not None:
                self._ids.release()
            self.programs.release()
            self.buffers.release()
            self.shadow.release()
        except Exception:  # interpreter shutdown: the context may be gone already
            pass
