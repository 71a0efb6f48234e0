"""Headless OpenGL rasterizer of the shared :class:`~roslan.scene.model.Scene`.

One OpenGL context per process (``moderngl`` on EGL: Mesa's llvmpipe on a CPU
machine, the GPU driver wherever there is one; same code). :func:`get_renderer`
returns one :class:`Renderer` per scene: the scene is uploaded once into a single
vertex/index buffer, its triangles grouped by texture and, inside each group, into
spatial clusters (one object's triangles in one grid cell) with bounding boxes; every
frame draws only the clusters whose box meets the view frustum, nearest first (so that
the early depth test rejects hidden fragments), consecutive ones merged into one draw
call. Objects that are closed solids (:func:`~roslan.scene.mesh.closed_solid`: no
border, faces counter-clockwise seen from outside) are drawn with back faces culled
while the camera is outside their bounding box, so their far sides are neither
rasterized nor shaded (same image up to ties between coplanar faces); open surfaces
(planes, user meshes with holes, inside-out meshes) stay two-sided.
The sun's shadow map is rendered once at upload (scene and sun are static).

Shading: textured Lambert, ``albedo * texture * (ambient + sun * max(0, n.l) * lit)``
in LINEAR radiance (textures are sRGB-decoded by the sampler), two-sided (the side
facing the camera is lit). The sun term ``n.l`` and the shadow-map bias are computed
per vertex (exact for flat faces, whose normal is constant; Gouraud for smooth ones);
``lit`` is one hardware-filtered (bilinear PCF) shadow-map lookup per fragment.
Anti-aliasing (aliasing would turn into fake events in the event camera): trilinear
mip-mapped textures, anisotropic filtering on GPUs, and for geometric edges either
MSAA (:data:`MSAA_SAMPLES` = 4 per pixel on a GPU, resolved by averaging the samples)
or, with 1 sample (the default on llvmpipe, :data:`SOFTWARE_MSAA_SAMPLES`, where MSAA
costs 2.4x the frame), an FXAA-style edge filter on geometric edges only: where 1/z is
not affine in the image (silhouettes, creases) and the luma contrast is high, the pixel
is resampled bilinearly across the edge by its sub-pixel coverage estimate; texture
detail on planes is left untouched. Sub-pixel geometry (wires, lines thinner than a
pixel) needs MSAA: ``ROSLAN_MSAA_SAMPLES=4``.

Where no surface is hit, colour and luminance are the scene's sky radiance
(:attr:`~roslan.scene.model.Lights.sky`) and depth is ``inf``.

Outputs (keywords of :meth:`Renderer.render`): linear RGB, Rec. 709 luminance (one
channel: what grayscale and event cameras need, computed in the shader, a quarter of
the readback), metric depth; each is computed and read back only when requested.

Camera model: the pose ``T_world_cam`` of the OPTICAL frame (z forward, x right,
y down) and a pinhole ``K``. The projection is built from ``K`` exactly with
OpenCV's convention: pixel centres at integer coordinates, row 0 = top of the
image. The image is rendered upside down in GL's window coordinates (GL's first
row = image row 0), so the readback needs no flip.

Depth: the metric z-depth along the optical axis, written per fragment as 1/z
interpolated at the pixel centre (non-centroid interpolation), so it is independent of
the depth-buffer precision; at silhouettes the nearest sample wins; ``inf`` where
nothing is hit. The depth buffer only resolves visibility.

Speed (llvmpipe, 2 cores): see ``benchmarks/profile_render.py`` and the "Cameras"
section of docs/performance.md. llvmpipe shades on ``LP_NUM_THREADS`` threads (default:
all cores); vertex processing runs on the calling thread, hence the culling, and the
colour pass is flushed in :data:`FLUSH_CHUNKS` parts so that shading overlaps it. The
edge filter loads its texels through ``imageLoad`` (cheaper than ``texelFetch`` there)
and writes an RGB32F target where that is renderable; callers that render every frame
pass ``out=`` buffers (fresh multi-MB arrays cost page faults).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError
from roslan.scene.mesh import closed_solid

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = [
    "EGL_PACKAGES",
    "RenderResult",
    "Renderer",
    "create_context",
    "default_samples",
    "get_renderer",
    "projection_from_K",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

EGL_PACKAGES = "libegl1, libegl-mesa0, libgl1-mesa-dri"
"""Debian packages that provide headless OpenGL through EGL (Mesa llvmpipe)."""

MSAA_SAMPLES = 4
"""MSAA samples per pixel of the colour pass on a GPU (clamped to what it supports)."""

SOFTWARE_MSAA_SAMPLES = 1
"""Default MSAA samples on Mesa's llvmpipe (CPU). There MSAA costs 2.4x the whole
colour pass (2 samples cost as much as 4) while the edge filter costs ~15 %: see
docs/performance.md. Override with ``ROSLAN_MSAA_SAMPLES`` or ``Renderer(samples=)``."""

FLUSH_CHUNKS = 4
"""llvmpipe: the colour pass is flushed to the rasterizer threads in this many parts
(``Renderer.flush_chunks``; 1 = one flush at the end), so that shading overlaps the
vertex work, which runs on the calling thread (see docs/performance.md)."""

SOFTWARE_SHADOW_MAP = 2048
"""Largest shadow map (texels per side) on llvmpipe (4096 on a GPU)."""

LUMA = (0.2126, 0.7152, 0.0722)
"""Rec. 709 luminance weights of linear RGB (the ``luminance`` output)."""

CLUSTER_CELLS = 12
"""Culling granularity: an object's triangles are split by a grid of cubic cells of
``max(scene diagonal / CLUSTER_CELLS, 1 m)``."""

_GL_SRGB8 = 0x8C41
_GL_SRGB8_ALPHA8 = 0x8C43
_INF_BITS = "uintBitsToFloat(0x7F800000u)"

_context: Any = None
_context_lock = threading.Lock()
_renderers: weakref.WeakKeyDictionary[Scene, Renderer] = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class RenderResult:
    """One rendered view.

    Attributes:
        color: (H, W, 3) float32 linear radiance in [0, 1], or None if not requested.
        depth: (H, W) float32 metric z-depth along the optical axis (m), ``inf`` where
            nothing is hit, or None if not requested.
        luminance: (H, W) float32 Rec. 709 luminance of the linear radiance in [0, 1]
            (``0.2126 R + 0.7152 G + 0.0722 B``), or None if not requested.
    """

    color: F32 | None
    depth: F32 | None
    luminance: F32 | None = None


def create_context() -> Any:
    """The process-wide headless moderngl context (created on first call).

    Raises:
        RenderError: no EGL/OpenGL 3.3+ available; names the Debian packages to install.
    """
    global _context
    with _context_lock:
        if _context is not None:
            return _context
        try:
            import moderngl

            # (moderngl's stub mistypes `backend`; it is a string such as "egl")
            options: dict[str, Any] = {"backend": "egl", "require": 410}
            ctx = moderngl.create_standalone_context(**options)
        except Exception as err:  # moderngl/glcontext raise plain Exceptions
            msg = (
                "cannot create a headless OpenGL 4.1 context through EGL "
                f"({type(err).__name__}: {err}). On Debian/Ubuntu install the packages "
                f"{EGL_PACKAGES} (apt-get install {EGL_PACKAGES.replace(',', '')}): "
                "they provide libEGL and Mesa's llvmpipe software renderer; on a GPU "
                "machine install the vendor's EGL driver instead"
            )
            raise RenderError(msg) from err
        _context = ctx
        return ctx


def get_renderer(scene: Scene) -> Renderer:
    """The renderer of ``scene`` in this process: created (scene uploaded) on first use."""
    r = _renderers.get(scene)
    if r is None:
        r = Renderer(scene)
        _renderers[scene] = r
        weakref.finalize(scene, r.release)
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


_COLOR_VERT = """
uniform mat4 u_mvp;          // clip from world
uniform vec4 u_zrow;         // optical z from world (third row of T_cam_world)
uniform mat4 u_light;        // shadow-map [0,1]^3 from world
uniform vec3 u_cam_pos;
uniform vec3 u_to_sun;       // unit vector towards the sun (world)
uniform float u_sun;
uniform float u_shadow_texel;  // shadow-map texel size in [0,1] units
in vec3 in_pos;
in vec3 in_normal;
in vec2 in_uv;
in vec3 in_albedo;
out vec2 v_uv;
out vec3 v_albedo;
out float v_sun;
out vec3 v_light;
out float v_z;
void main() {
    vec4 p = vec4(in_pos, 1.0);
    gl_Position = u_mvp * p;
    // Two-sided: light the side facing the camera. For a flat face the sign of
    // dot(n, cam - p) is the camera's side of its plane: the same at every vertex.
    vec3 n = in_normal;
    if (dot(n, u_cam_pos - in_pos) < 0.0) n = -n;
    float ndl = max(dot(n, u_to_sun), 0.0);
    v_uv = in_uv;
    v_albedo = in_albedo;
    v_sun = u_sun * ndl;
    // slope-scaled bias against acne; linear in the (orthographic) light frame
    float bias = u_shadow_texel * (1.5 + 2.0 * sqrt(max(1.0 - ndl * ndl, 0.0)) / max(ndl, 0.05));
    vec4 lp = u_light * p;
    v_light = vec3(lp.xy, lp.z - bias);
    v_z = dot(u_zrow, p);
}
"""

_COLOR_FRAG = """
uniform sampler2D u_tex;
uniform sampler2DShadow u_shadow;
in vec2 v_uv;
uniform float u_ambient;
in vec3 v_albedo;
in float v_sun;
in vec3 v_light;
in float v_z;
#ifdef DEPTH
layout(location = 1) out float o_invz;
#endif
// the last channel carries 1/z for the edge filter (ignored by 1-channel MSAA targets)
#ifdef LUM
layout(location = 0) out vec2 o_color;
#else
layout(location = 0) out vec4 o_color;
#endif
void main() {
    float lit = texture(u_shadow, v_light);  // bilinear PCF (compare + LINEAR)
    vec3 c = clamp(texture(u_tex, v_uv).rgb * v_albedo * (u_ambient + v_sun * lit), 0.0, 1.0);
    // optical z at the pixel centre (non-centroid), even for partially covered pixels
    float invz = 1.0 / max(v_z, 1e-6);
#ifdef LUM
    o_color = vec2(dot(c, LUMA), invz);
#else
    o_color = vec4(c, invz);
#endif
#ifdef DEPTH
    o_invz = invz;
#endif
}
"""

_FRAG_DEPTH = """
#version 410
in float v_z;
layout(location = 0) out float o_invz;
void main() { o_invz = 1.0 / max(v_z, 1e-6); }
"""

_VERT_DEPTH = """
#version 410
uniform mat4 u_mvp;
uniform vec4 u_zrow;
in vec3 in_pos;
out float v_z;
void main() {
    vec4 p = vec4(in_pos, 1.0);
    gl_Position = u_mvp * p;
    v_z = dot(u_zrow, p);
}
"""

_VERT_SHADOW = """
#version 410
uniform mat4 u_mvp;
in vec3 in_pos;
void main() { gl_Position = u_mvp * vec4(in_pos, 1.0); }
"""

_FRAG_SHADOW = """
#version 410
void main() {}
"""

_VERT_QUAD = """
#version 410
void main() {
    // one triangle covering the viewport
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

_FRAG_RESOLVE = f"""
uniform sampler2DMS u_color;
uniform int u_samples;
#ifdef LUM
layout(location = 0) out float o_color;
#else
layout(location = 0) out vec4 o_color;
#endif
#ifdef DEPTH
uniform sampler2DMS u_invz;
layout(location = 1) out float o_depth;
#endif
void main() {{
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = vec4(0.0);
    float m = 0.0;
    for (int i = 0; i < u_samples; ++i) {{
        c += texelFetch(u_color, p, i);
#ifdef DEPTH
        m = max(m, texelFetch(u_invz, p, i).r);   // nearest surface wins
#endif
    }}
    c /= float(u_samples);
#ifdef LUM
    o_color = c.r;
#else
    o_color = vec4(c.rgb, 1.0);
#endif
#ifdef DEPTH
    o_depth = m > 0.0 ? 1.0 / m : {_INF_BITS};
#endif
}}
"""


_FRAG_EDGE_AA = """
// Edge filter for 1-sample rendering (after FXAA 3.11, restricted to geometric edges).
// u_color: RGB + 1/z in .a (LUM: luminance + 1/z in .rg); only point loads.
// IMAGE: the same texture bound as a read-only image too (GL >= 4.2): llvmpipe's
// imageLoad is ~1/3 cheaper than texelFetch (no sampler path), same values.
uniform sampler2D u_color;
#ifdef LUM
layout(location = 0) out float o_color;
#define ZCH 1
#define LCH 0
#ifdef IMAGE
layout(rg32f) uniform readonly image2D u_image;
#endif
#else
layout(location = 0) out vec4 o_color;
#define ZCH 3
#define LCH 1
#ifdef IMAGE
layout(rgba32f) uniform readonly image2D u_image;
#endif
#endif
#ifdef IMAGE
#define FETCH(q) imageLoad(u_image, q)
#else
#define FETCH(q) texelFetch(u_color, q, 0)
#endif
void main() {
    // this pixel and its 4 neighbours, unfiltered (point loads: ~10 % cheaper than
    // gathers on llvmpipe, and non-edge pixels pass through bit-exactly)
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 hi = textureSize(u_color, 0) - 1;
    vec4 tm = FETCH(p);
    vec4 tw = FETCH(ivec2(max(p.x - 1, 0), p.y));
    vec4 te = FETCH(ivec2(min(p.x + 1, hi.x), p.y));
    vec4 ts = FETCH(ivec2(p.x, max(p.y - 1, 0)));
    vec4 tn = FETCH(ivec2(p.x, min(p.y + 1, hi.y)));
    // Over a plane 1/z is affine in the image, so its second differences vanish: they
    // are non-zero only at silhouettes and creases, the edges that rasterization
    // aliases (texture detail lies on planes and is mip-mapped already).
    float zm = tm[ZCH];
    float d2 = max(abs(tn[ZCH] + ts[ZCH] - 2.0 * zm), abs(te[ZCH] + tw[ZCH] - 2.0 * zm));
    float zmax = max(max(max(tw[ZCH], zm), max(ts[ZCH], tn[ZCH])), te[ZCH]);
    // ~perceptual luma, like FXAA's (LUM: luminance; RGB: green, its 72 % share)
    float w = sqrt(tw[LCH]), m = sqrt(tm[LCH]), s = sqrt(ts[LCH]);
    float n = sqrt(tn[LCH]), e = sqrt(te[LCH]);
    float lmin = min(m, min(min(n, s), min(e, w)));
    float lmax = max(m, max(max(n, s), max(e, w)));
    float range = lmax - lmin;
    vec4 c = tm;
    if (d2 > 1e-3 * zmax && range >= max(0.0156, 0.0625 * lmax)) {
        bool horz = abs(n + s - 2.0 * m) >= abs(e + w - 2.0 * m);  // step across in y
        float l1 = horz ? s : w;
        float l2 = horz ? n : e;
        // the neighbour across the edge, towards the larger luma step
        vec4 t = abs(l1 - m) >= abs(l2 - m) ? (horz ? ts : tw) : (horz ? tn : te);
        // sub-pixel coverage estimate from the neighbourhood
        float sub = clamp(abs(0.25 * (n + s + e + w) - m) / max(range, 1e-6), 0.0, 1.0);
        sub = smoothstep(0.0, 1.0, sub);
        // resample linearly across the edge, from this pixel's centre: the bilinear
        // sample at an offset along one axis, from the texels already loaded (llvmpipe
        // runs a sampler call in a branch for every pixel of a mixed SIMD group)
        c = mix(tm, t, max(sub * sub * 0.75, 0.25));
    }
#ifdef LUM
    o_color = c.r;
#else
    o_color = vec4(c.rgb, 1.0);
#endif
}
"""


def _source(body: str, *, lum: bool, depth: bool, image: bool = False) -> str:
    defs = ["#version 420" if image else "#version 410"]
    if image:
        defs.append("#define IMAGE")
    if lum:
        defs.append("#define LUM")
    if depth:
        defs.append("#define DEPTH")
    defs.append("const vec3 LUMA = vec3({:.4f}, {:.4f}, {:.4f});".format(*LUMA))
    return "\n".join(defs) + "\n" + body


class _Targets:
    """Framebuffers of one (size, samples, outputs) combination, created once, reused.

    With MSAA the colour pass draws into ``ms_fbo`` and a resolve pass averages it into
    ``out_fbo`` (attachment 0: RGBA or luminance, 1: depth in m); without MSAA the
    colour pass draws into ``out_fbo`` directly (attachment 0: RGB + 1/z or luminance +
    1/z, 1: 1/z) and the edge filter writes ``aa_fbo``.
    """

    def __init__(
        self,
        ctx: Any,
        width: int,
        height: int,
        samples: int,
        lum: bool,
        depth: bool,
        rgb: bool = True,
    ) -> None:
        size = (width, height)
        ncomp = 1 if lum else 4
        cdtype = "f4" if lum else "f2"
        self._objs: list[Any] = []
        self.ms_fbo: Any = None
        self.ms_color: Any = None
        self.ms_invz: Any = None
        if samples > 1:
            self.ms_color = ctx.texture(size, ncomp, samples=samples, dtype=cdtype)
            atts = [self.ms_color]
            if depth:
                self.ms_invz = ctx.texture(size, 1, samples=samples, dtype="f4")
                atts.append(self.ms_invz)
            ms_depth = ctx.depth_renderbuffer(size, samples=samples)
            self.ms_fbo = ctx.framebuffer(atts, ms_depth)
            self._objs += [self.ms_fbo, *atts, ms_depth]
        # 1 sample: the edge filter reads 1/z from the colour target's last channel
        out = [ctx.texture(size, (2 if lum else 4) if samples == 1 else ncomp, dtype="f4")]
        if depth:
            out.append(ctx.texture(size, 1, dtype="f4"))
        out_depth = None if samples > 1 else ctx.depth_renderbuffer(size)
        self.out_fbo = ctx.framebuffer(out, out_depth)
        self.out_color = out[0]
        self._objs += [self.out_fbo, *out] + ([out_depth] if out_depth is not None else [])
        self.aa_fbo: Any = None
        if samples == 1:  # edge filter: out_color -> aa_fbo
            self.out_color.filter = (ctx.LINEAR, ctx.LINEAR)
            self.out_color.repeat_x = self.out_color.repeat_y = False
            self.aa_fbo = None
            if rgb and not lum:
                # RGB32F where it is colour-renderable (optional in GL; llvmpipe: yes):
                # 12 instead of 16 bytes written per pixel, and a plain copy to read back
                aa = ctx.texture(size, 3, dtype="f4")
                try:
                    self.aa_fbo = ctx.framebuffer([aa])
                except Exception:  # moderngl: "the framebuffer is not complete"
                    aa.release()
            if self.aa_fbo is None:
                aa = ctx.texture(size, ncomp, dtype="f4")
                self.aa_fbo = ctx.framebuffer([aa])
            self._objs += [self.aa_fbo, aa]

    def release(self) -> None:
        for o in self._objs:
            o.release()


class Renderer:
    """Rasterizer of one scene. Use :func:`get_renderer` (one per scene and process).

    Attributes:
        max_size: largest image width/height the driver supports (pixels).
        samples: default MSAA samples per pixel of the colour pass (1: no MSAA, the
            edge filter instead); see :func:`default_samples`.
        near: near clipping distance (m), chosen from the scene size.
        anisotropy: texture anisotropic filtering level (1 on llvmpipe: see below).
        software: True on Mesa's llvmpipe (CPU) renderer.
        front_to_back: draw the visible clusters nearest first (default; False: index
            order, for benchmarks), see :meth:`visible_ranges`.
        flush_chunks: flush the colour pass to the rasterizer in this many parts
            (:data:`FLUSH_CHUNKS` on llvmpipe, 1 on GPUs); the image is the same.
        cull_back_faces: skip the back faces of closed solids seen from outside their
            bounding box (default; same image, see :meth:`visible_ranges`; False: draw
            every face, for benchmarks).
        closed_solids: names of the scene objects whose back faces may be culled
            (:func:`~roslan.scene.mesh.closed_solid`).
    """

    def __init__(self, scene: Scene, *, samples: int | None = None) -> None:
        self.scene = scene
        self.ctx = ctx = create_context()
        self.max_size = int(
            min(
                ctx.info["GL_MAX_RENDERBUFFER_SIZE"],
                ctx.info["GL_MAX_TEXTURE_SIZE"],
                *ctx.info["GL_MAX_VIEWPORT_DIMS"],
            )
        )
        # Mesa's llvmpipe (LLVM 15) stalls for minutes on anisotropic filtering of
        # near-grazing, near-clipped ground planes: trilinear mip-mapping + MSAA there.
        self.software = "llvmpipe" in str(ctx.info.get("GL_RENDERER", "")).lower()
        self.samples = self._clamp_samples(default_samples(self.software, samples))
        self.anisotropy = 1.0 if self.software else 16.0
        self.front_to_back = True
        self.cull_back_faces = True
        # image load/store (GL 4.2) for the edge filter's point loads
        self._image = int(ctx.version_code) >= 420
        self._flush = _gl_flush()
        self._clear_buffer = _gl_clear_buffer()
        self.flush_chunks = FLUSH_CHUNKS if self.software else 1
        self._rgb_target = True  # RGB32F edge-filter output where renderable
        self._targets: dict[tuple[int, int, int, bool, bool, bool], _Targets] = {}
        self._d_targets: dict[tuple[int, int], tuple[Any, Any, Any]] = {}
        self._programs: dict[tuple[bool, bool], tuple[Any, Any]] = {}
        self._resolves: dict[tuple[bool, bool], tuple[Any, Any]] = {}
        self._edge_aa: dict[tuple[bool, bool], tuple[Any, Any]] = {}
        self._released = False

        lo, hi = scene.bounds
        diag = float(np.linalg.norm(hi - lo))
        self._bounds_corners = np.array(
            [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        # 24-bit depth buffer: resolution ~ z^2 / (near * 2^24); 1 cm near gives
        # ~6 mm at 100 m, while cameras may still fly within centimetres of a perch.
        self.near = float(np.clip(1e-4 * diag, 0.005, 0.02))
        self._cell = max(diag / CLUSTER_CELLS, 1.0)

        self._prog_depth = ctx.program(vertex_shader=_VERT_DEPTH, fragment_shader=_FRAG_DEPTH)
        self._prog_shadow = ctx.program(vertex_shader=_VERT_SHADOW, fragment_shader=_FRAG_SHADOW)
        self._upload(scene)
        self._build_shadow_map(scene)

    def _clamp_samples(self, samples: int) -> int:
        return max(1, min(int(samples), int(self.ctx.max_samples)))

    # ----------------------------------------------------------------- upload
    def _upload(self, scene: Scene) -> None:
        """One interleaved VBO + IBO for the whole scene, faces sorted by texture, then by
        object and grid cell (the culling clusters)."""
        ctx = self.ctx
        groups: dict[int, list[int]] = {}
        textures: dict[int, NDArray[np.uint8] | None] = {0: None}
        for i, obj in enumerate(scene.objects):
            tex = obj.material.texture
            key = 0 if tex is None else id(tex)
            textures[key] = tex
            groups.setdefault(key, []).append(i)

        parts: list[F32] = []
        faces: list[NDArray[np.int32]] = []
        self._group_tex: list[Any] = []
        self._textures: list[Any] = []
        c_first: list[int] = []  # per cluster: first index, index count, group, box
        c_count: list[int] = []
        c_group: list[int] = []
        c_lo: list[F32] = []
        c_hi: list[F32] = []
        c_obj: list[int] = []  # per cluster: index into o_lo/o_hi/o_closed
        o_lo: list[F32] = []  # per drawn object: bounding box, closed solid
        o_hi: list[F32] = []
        o_closed: list[bool] = []
        closed_names: list[str] = []
        offset = 0
        first = 0
        white = ctx.texture((1, 1), 3, bytes([255, 255, 255]), internal_format=_GL_SRGB8)
        self._textures.append(white)
        aniso = float(min(self.anisotropy, ctx.max_anisotropy))
        for key, members in groups.items():
            g = len(self._group_tex)
            count = 0
            for i in members:
                o = scene.objects[i]
                nv = o.vertices.shape[0]
                nf = o.faces.shape[0]
                if nf == 0:
                    continue
                attrs = np.empty((nv, 11), dtype=np.float32)
                attrs[:, 0:3] = o.vertices
                attrs[:, 3:6] = o.normals
                attrs[:, 6:8] = o.uvs * np.float32(o.material.texture_scale)
                attrs[:, 8:11] = np.asarray(o.material.color, dtype=np.float32)
                parts.append(attrs)
                tri = o.vertices[o.faces]  # (F, 3, 3)
                cells = np.floor(tri.mean(axis=1) / self._cell).astype(np.int64)
                _, inv = np.unique(cells, axis=0, return_inverse=True)
                inv = inv.reshape(-1)
                order = np.argsort(inv, kind="stable")
                faces.append(o.faces[order].astype(np.int32) + offset)
                sizes = np.bincount(inv)
                starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
                c_lo.append(np.minimum.reduceat(tri.min(axis=1)[order], starts, axis=0))
                c_hi.append(np.maximum.reduceat(tri.max(axis=1)[order], starts, axis=0))
                c_first.extend((first + count + 3 * starts).tolist())
                c_count.extend((3 * sizes).tolist())
                c_group.extend([g] * sizes.size)
                c_obj.extend([len(o_closed)] * sizes.size)
                o_lo.append(tri.min(axis=(0, 1)))
                o_hi.append(tri.max(axis=(0, 1)))
                o_closed.append(closed_solid(o.vertices, o.faces))
                if o_closed[-1]:
                    closed_names.append(o.name)
                offset += nv
                count += 3 * nf
            if count == 0:
                continue
            img = textures[key]
            if img is None:
                tex = white
            else:
                h, w = img.shape[:2]
                # RGBA: 4-byte texels sample ~10 % faster than RGB on llvmpipe.
                # GL's first texture row is v = 0: flip so v = 0 is the image's bottom
                # (the usual glTF/OBJ convention for UVs).
                rgba = np.full((h, w, 4), 255, dtype=np.uint8)
                rgba[..., :3] = img[::-1, :, :3]
                tex = ctx.texture((w, h), 4, rgba.tobytes(), internal_format=_GL_SRGB8_ALPHA8)
                tex.build_mipmaps()
                tex.filter = (ctx.LINEAR_MIPMAP_LINEAR, ctx.LINEAR)
                tex.anisotropy = aniso
                tex.repeat_x = tex.repeat_y = True
                self._textures.append(tex)
            self._group_tex.append(tex)
            first += count

        self._c_first = np.asarray(c_first, dtype=np.int64)
        self._c_count = np.asarray(c_count, dtype=np.int64)
        self._c_group = np.asarray(c_group, dtype=np.int64)
        self.closed_solids = frozenset(closed_names)
        self._c_obj = np.asarray(c_obj, dtype=np.int64)
        self._c_closed = np.asarray(o_closed, dtype=bool)[self._c_obj]
        self._o_lo = np.asarray(o_lo, dtype=np.float64).reshape(-1, 3)
        self._o_hi = np.asarray(o_hi, dtype=np.float64).reshape(-1, 3)
        if offset == 0:
            self._vbo = self._ibo = None
            self._vao_depth = self._vao_shadow = None
            self._c_centre = self._c_half = np.zeros((0, 3))
            return
        lo = np.concatenate(c_lo).astype(np.float64)
        hi = np.concatenate(c_hi).astype(np.float64)
        self._c_centre = 0.5 * (lo + hi)
        self._c_half = 0.5 * (hi - lo) + 1e-4
        data = np.concatenate(parts)
        idx = np.concatenate(faces).reshape(-1)
        self._vbo = ctx.buffer(data.tobytes())
        self._ibo = ctx.buffer(idx.astype(np.uint32).tobytes())
        self._vao_depth = ctx.vertex_array(
            self._prog_depth, [(self._vbo, "3f 32x", "in_pos")], self._ibo, index_element_size=4
        )
        self._vao_shadow = ctx.vertex_array(
            self._prog_shadow, [(self._vbo, "3f 32x", "in_pos")], self._ibo, index_element_size=4
        )
        self._n_index = int(idx.size)

    @property
    def n_clusters(self) -> int:
        """Number of culling clusters of the scene."""
        return int(self._c_first.size)

    def _build_shadow_map(self, scene: Scene) -> None:
        """Orthographic depth map along the sun over the scene's bounding sphere."""
        ctx = self.ctx
        lo, hi = scene.bounds
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        # ~1 cm texels where affordable, 1024..4096 texels (2048 on llvmpipe: its
        # lookups are memory bound; a 4096^2 map costs ~15 % more per frame)
        cap = SOFTWARE_SHADOW_MAP if self.software else 4096
        size = int(np.clip(2 ** math.ceil(math.log2(max(2 * radius / 0.01, 1.0))), 1024, cap))
        size = min(size, self.max_size)
        d = np.asarray(scene.lights.sun_direction, dtype=np.float64)
        fwd = d / max(float(np.linalg.norm(d)), 1e-12)
        up = np.array([0.0, 0.0, 1.0]) if abs(fwd[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        right = np.cross(fwd, up)
        right /= np.linalg.norm(right)
        up2 = np.cross(right, fwd)
        # light coordinates in [-1, 1]: lateral / radius, along the light travel -> depth
        L = np.zeros((4, 4))
        L[0, :3], L[0, 3] = right / radius, -right @ centre / radius
        L[1, :3], L[1, 3] = up2 / radius, -up2 @ centre / radius
        L[2, :3], L[2, 3] = fwd / radius, -fwd @ centre / radius
        L[3, 3] = 1.0
        to_unit = np.array(
            [[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]], dtype=np.float64
        )
        self._shadow_tex = ctx.depth_texture((size, size))
        self._shadow_tex.compare_func = "<="
        self._shadow_tex.filter = (ctx.LINEAR, ctx.LINEAR)
        self._shadow_tex.repeat_x = self._shadow_tex.repeat_y = False
        self._shadow_fbo = ctx.framebuffer(depth_attachment=self._shadow_tex)
        self._shadow_fbo.use()
        self._shadow_fbo.clear(depth=1.0)
        if self._vao_shadow is not None:
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            self._prog_shadow["u_mvp"].write(_gl_mat(L))
            self._vao_shadow.render(ctx.TRIANGLES)
        self._light = _gl_mat(to_unit @ L)
        self._shadow_texel = 1.0 / size

    def _program(self, lum: bool, depth: bool) -> tuple[Any, Any]:
        """(program, vertex array) of the colour pass variant (compiled on first use)."""
        key = (lum, depth)
        pv = self._programs.get(key)
        if pv is None:
            ctx = self.ctx
            prog = ctx.program(
                vertex_shader=_source(_COLOR_VERT, lum=lum, depth=depth),
                fragment_shader=_source(_COLOR_FRAG, lum=lum, depth=depth),
            )
            lights = self.scene.lights
            d = np.asarray(lights.sun_direction, dtype=np.float64)
            to_sun = -d / max(float(np.linalg.norm(d)), 1e-12)
            consts: dict[str, Any] = {
                "u_to_sun": tuple(float(x) for x in to_sun),
                "u_sun": float(lights.sun_intensity),
                "u_ambient": float(lights.ambient),
                "u_tex": 0,
                "u_shadow": 1,
                "u_shadow_texel": self._shadow_texel,
            }
            for k, v in consts.items():
                if k in prog:  # (a uniform the compiler optimised away is absent)
                    prog[k].value = v
            if "u_light" in prog:
                prog["u_light"].write(self._light)
            vao = None
            if self._vbo is not None:
                vao = ctx.vertex_array(
                    prog,
                    [(self._vbo, "3f 3f 2f 3f", "in_pos", "in_normal", "in_uv", "in_albedo")],
                    self._ibo,
                    index_element_size=4,
                )
            pv = (prog, vao)
            self._programs[key] = pv
        return pv

    def _resolve(self, lum: bool, depth: bool) -> tuple[Any, Any]:
        key = (lum, depth)
        pv = self._resolves.get(key)
        if pv is None:
            prog = self.ctx.program(
                vertex_shader=_VERT_QUAD,
                fragment_shader=_source(_FRAG_RESOLVE, lum=lum, depth=depth),
            )
            prog["u_color"].value = 0
            if depth:
                prog["u_invz"].value = 1
            pv = (prog, self.ctx.vertex_array(prog, []))
            self._resolves[key] = pv
        return pv

    def _edge_filter(self, lum: bool) -> tuple[Any, Any]:
        pv = self._edge_aa.get((lum, self._image))
        if pv is None:
            prog = self.ctx.program(
                vertex_shader=_VERT_QUAD,
                fragment_shader=_source(_FRAG_EDGE_AA, lum=lum, depth=False, image=self._image),
            )
            prog["u_color"].value = 0
            if self._image:
                prog["u_image"].value = 0  # image unit 0
            pv = (prog, self.ctx.vertex_array(prog, []))
            self._edge_aa[(lum, self._image)] = pv
        return pv

    # ----------------------------------------------------------------- render
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
        fragments before shading (llvmpipe tests depth early: 1.31 instead of 1.80
        shaded fragments per pixel on the warehouse view of bench_camera.py);
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
        M = np.asarray(clip_from_world, dtype=np.float64)
        planes = np.stack([M[3] + M[0], M[3] - M[0], M[3] + M[1], M[3] - M[1], M[3] + M[2]])
        # a box is outside if it lies wholly on the negative side of one plane
        s = self._c_centre @ planes[:, :3].T + planes[:, 3]
        r = self._c_half @ np.abs(planes[:, :3]).T
        idx = np.flatnonzero(np.all(s + r >= 0.0, axis=1))
        if idx.size == 0:
            e = np.zeros(0, dtype=np.int64)
            return e, e, e, np.zeros(0, dtype=bool)
        if eye is not None and sort:
            gap = np.abs(self._c_centre[idx] - np.asarray(eye, dtype=np.float64))
            gap = np.maximum(gap - self._c_half[idx], 0.0)  # 0 inside the box
            idx = idx[np.argsort(np.einsum("ij,ij->i", gap, gap), kind="stable")]
        cull = np.zeros(idx.size, dtype=bool)
        if eye is not None and self.cull_back_faces:
            e = np.asarray(eye, dtype=np.float64)
            m = float(near_reach) + 1e-6
            inside = np.all((e >= self._o_lo - m) & (e <= self._o_hi + m), axis=1)
            cull = self._c_closed[idx] & ~inside[self._c_obj[idx]]
        brk = (
            np.flatnonzero(
                (np.diff(idx) != 1) | (np.diff(self._c_group[idx]) != 0) | (cull[1:] != cull[:-1])
            )
            + 1
        )
        begin = np.concatenate([[0], brk])
        starts = idx[begin]
        ends = idx[np.concatenate([brk - 1, [idx.size - 1]])]
        first = self._c_first[starts]
        count = self._c_first[ends] + self._c_count[ends] - first
        return first, count, self._c_group[starts], cull[begin]

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
                luminance (H, W) when ``color`` is False: a caller's reused buffer (a
                fresh 3.7 MB array per frame costs ~900 page faults, ~1 ms on this VM).
            near: near clipping distance (m) of this view (None: :attr:`near`); the
                sensors pass their ``near_clip``.
        Returns:
            :class:`RenderResult`; row 0 is the top of the image. Arrays are fresh (the
            caller may keep and modify them), except ``out``.
        """
        if self._released:
            msg = "renderer was released"
            raise RenderError(msg)
        width, height = int(width), int(height)
        self.check_size(width, height)
        if not (color or depth or luminance):
            return RenderResult(None, None)
        T = np.asarray(T_world_cam, dtype=np.float64)
        T_cam_world = np.linalg.inv(T)
        cam_pos = T[:3, 3]
        z_near = self.near if near is None else float(near)
        far = float(np.max(np.linalg.norm(self._bounds_corners - cam_pos, axis=1))) * 1.01
        far = max(far, 2.0 * z_near)
        P = projection_from_K(np.asarray(K, dtype=np.float64), width, height, z_near, far)
        clip = P @ T_cam_world
        mvp = _gl_mat(clip)
        zrow = tuple(float(x) for x in T_cam_world[2])
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
        ctx = self.ctx
        # No ctx.viewport here: in moderngl it writes the viewport of whichever framebuffer
        # is bound *now* (another resolution's), corrupting that target for its next frame.
        # Each target framebuffer keeps its own full-size viewport, applied by fbo.use().

        if not (color or luminance):
            inv = self._render_depth(width, height, mvp, zrow, first, count, cull)
            return RenderResult(None, inv)

        lum = luminance and not color
        ns = self.samples if samples is None else self._clamp_samples(samples)
        key = (width, height, ns, lum, depth, self._rgb_target)
        t = self._targets.get(key)
        if t is None:
            t = _Targets(ctx, width, height, ns, lum, depth, self._rgb_target)
            self._targets[key] = t
        fbo = t.ms_fbo if ns > 1 else t.out_fbo
        fbo.use()
        self._clear(fbo, lum, depth)
        if first.size:
            prog, vao = self._program(lum, depth)
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            # outward faces are counter-clockwise seen from outside; the projection
            # keeps image row 0 at window row 0 (a mirror), so on screen they run clockwise
            ctx.front_face = "cw"
            culling = False
            prog["u_mvp"].write(mvp)
            if depth:
                prog["u_zrow"].value = zrow
            prog["u_cam_pos"].value = tuple(float(x) for x in cam_pos)
            self._shadow_tex.use(1)
            bound = -1
            # glFlush after the draws that end each 1/flush_chunks of the indices: the
            # rasterizer threads shade the nearer clusters while this thread still runs
            # the vertex work of the farther ones (llvmpipe; same pixels)
            flush = self._flush if self.flush_chunks > 1 else None
            marks: set[int] = set()
            if flush is not None:
                cum = np.cumsum(count)
                step = cum[-1] / self.flush_chunks
                marks = set(np.searchsorted(cum, step * np.arange(1, self.flush_chunks)).tolist())
                marks.discard(len(cum) - 1)
            for i, (f, n, g, c) in enumerate(
                zip(first.tolist(), count.tolist(), group.tolist(), cull.tolist(), strict=True)
            ):
                if g != bound:
                    self._group_tex[g].use(0)
                    bound = g
                if c != culling:
                    (ctx.enable if c else ctx.disable)(ctx.CULL_FACE)
                    culling = c
                vao.render(ctx.TRIANGLES, vertices=n, first=f)
                if i in marks:
                    flush()  # type: ignore[misc]
        if ns > 1:
            # resolve: average colour samples, nearest depth sample
            t.out_fbo.use()
            ctx.disable(ctx.DEPTH_TEST | ctx.CULL_FACE)
            rprog, quad = self._resolve(lum, depth)
            rprog["u_samples"].value = ns
            t.ms_color.use(0)
            if depth:
                t.ms_invz.use(1)
            quad.render(ctx.TRIANGLES, vertices=3)
            src = t.out_fbo
        else:
            # edge filter (FXAA-style) in place of MSAA
            t.aa_fbo.use()
            ctx.disable(ctx.DEPTH_TEST | ctx.CULL_FACE)
            _, quad = self._edge_filter(lum)
            t.out_color.use(0)
            if self._image:
                t.out_color.bind_to_image(0, read=True, write=False)
            quad.render(ctx.TRIANGLES, vertices=3)
            src = t.aa_fbo
        col = lum_out = dep = None
        if lum:
            lum_out = _out_array(out, (height, width))
            src.read_into(lum_out, components=1, dtype="f4", attachment=0)
        else:
            col = _out_array(out, (height, width, 3))
            src.read_into(col, components=3, dtype="f4", attachment=0)
            if luminance:
                lum_out = col @ np.asarray(LUMA, dtype=np.float32)
        if depth:
            dep = np.empty((height, width), dtype=np.float32)
            t.out_fbo.read_into(dep, components=1, dtype="f4", attachment=1)
            if ns == 1:
                with np.errstate(divide="ignore"):
                    np.reciprocal(dep, out=dep)  # 1/0 -> inf: nothing hit
        return RenderResult(col, dep, lum_out)

    def _clear(self, fbo: Any, lum: bool, depth: bool) -> None:
        """Clear a colour-pass target: colour = the sky (luminance: its luma) with 1/z = 0
        (nothing hit), the 1/z attachment (``depth``) = 0, depth buffer = far."""
        sky = tuple(float(x) for x in self.scene.lights.sky)
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
        value = (float(np.dot(sky, LUMA)), 0.0, 0.0, 0.0) if lum else (*sky, 0.0)
        self._clear_buffer(_GL_COLOR, 0, fl4(*value))
        if depth:
            self._clear_buffer(_GL_COLOR, 1, fl4(0.0, 0.0, 0.0, 0.0))
        self._clear_buffer(_GL_DEPTH, 0, fl4(1.0, 0.0, 0.0, 0.0))

    def _render_depth(
        self,
        width: int,
        height: int,
        mvp: bytes,
        zrow: tuple[float, ...],
        first: NDArray[np.int64],
        count: NDArray[np.int64],
        cull: NDArray[np.bool_],
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
        if first.size and self._vao_depth is not None:
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            ctx.front_face = "cw"  # (see render)
            self._prog_depth["u_mvp"].write(mvp)
            self._prog_depth["u_zrow"].value = zrow
            # one draw over the merged runs of all texture groups
            culling = False
            for f, n, c in _merge_runs(first, count, cull):
                if c != culling:
                    (ctx.enable if c else ctx.disable)(ctx.CULL_FACE)
                    culling = c
                self._vao_depth.render(ctx.TRIANGLES, vertices=n, first=f)
            ctx.disable(ctx.CULL_FACE)
        inv = np.empty((height, width), dtype=np.float32)
        fbo.read_into(inv, components=1, dtype="f4", attachment=0)
        with np.errstate(divide="ignore"):
            np.reciprocal(inv, out=inv)  # 1/0 -> inf: nothing hit
        return inv

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
            for tex in self._textures:
                tex.release()
            for prog, vao in [
                *self._programs.values(),
                *self._resolves.values(),
                *self._edge_aa.values(),
            ]:
                if vao is not None:
                    vao.release()
                prog.release()
            for o in (self._vao_depth, self._vao_shadow, self._vbo, self._ibo):
                if o is not None:
                    o.release()
            self._shadow_fbo.release()
            self._shadow_tex.release()
        except Exception:  # interpreter shutdown: the context may be gone already
            pass


def default_samples(software: bool, samples: int | None = None) -> int:
    """MSAA samples to use: ``samples`` if given, else ``$ROSLAN_MSAA_SAMPLES``, else
    :data:`SOFTWARE_MSAA_SAMPLES` on llvmpipe and :data:`MSAA_SAMPLES` on a GPU."""
    if samples is not None:
        return int(samples)
    env = os.environ.get("ROSLAN_MSAA_SAMPLES", "").strip()
    if env:
        try:
            return int(env)
        except ValueError:
            msg = f"ROSLAN_MSAA_SAMPLES = {env!r}: must be an integer number of samples (1, 4)"
            raise RenderError(msg) from None
    return SOFTWARE_MSAA_SAMPLES if software else MSAA_SAMPLES


def _out_array(out: F32 | None, shape: tuple[int, ...]) -> F32:
    """``out`` checked against ``shape`` (float32, C-contiguous), or a fresh array."""
    if out is None:
        return np.empty(shape, dtype=np.float32)
    if out.shape != shape or out.dtype != np.float32 or not out.flags.c_contiguous:
        msg = (
            f"render(out=): a C-contiguous float32 array of shape {shape} is needed, got "
            f"{out.dtype} {out.shape}{'' if out.flags.c_contiguous else ' (not contiguous)'}"
        )
        raise RenderError(msg)
    return out


def _merge_runs(
    first: NDArray[np.int64], count: NDArray[np.int64], cull: NDArray[np.bool_]
) -> list[tuple[int, int, bool]]:
    """Index ranges ``(first, count, cull)`` with adjacent ones of the same culling
    joined (texture-free passes)."""
    out: list[tuple[int, int, bool]] = []
    for f, n, c in zip(first.tolist(), count.tolist(), cull.tolist(), strict=True):
        if out and out[-1][0] + out[-1][1] == f and out[-1][2] == c:
            out[-1] = (out[-1][0], out[-1][1] + n, c)
        else:
            out.append((f, n, c))
    return out


def _gl_proc(name: bytes, *argtypes: Any) -> Any:
    """A GL entry point of the current EGL context that moderngl does not wrap, as a
    ctypes function returning nothing, or None."""
    try:
        egl = ctypes.CDLL(ctypes.util.find_library("EGL") or "libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        addr = egl.eglGetProcAddress(name)
    except (OSError, AttributeError):
        return None
    if not addr:
        return None
    return ctypes.CFUNCTYPE(None, *argtypes)(addr)


def _gl_flush() -> Callable[[], None] | None:
    """``glFlush`` (moderngl has none), or None."""
    fn: Callable[[], None] | None = _gl_proc(b"glFlush")
    return fn


_GL_COLOR = 0x1800
_GL_DEPTH = 0x1801


def _gl_clear_buffer() -> Callable[[int, int, Any], None] | None:
    """``glClearBufferfv(buffer, drawbuffer, value)`` (one attachment of the bound
    framebuffer; moderngl clears all colour attachments with one colour), or None."""
    fn: Callable[[int, int, Any], None] | None = _gl_proc(
        b"glClearBufferfv", ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_float)
    )
    return fn


def _gl_mat(M: F64) -> bytes:
    """Column-major float32 bytes of a 4x4 matrix (GLSL's layout)."""
    return np.ascontiguousarray(np.asarray(M, dtype=np.float32).T).tobytes()
