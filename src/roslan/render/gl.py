"""Headless OpenGL rasterizer of the shared :class:`~roslan.scene.model.Scene`.

One OpenGL context per process (``moderngl`` on EGL: Mesa's llvmpipe on a CPU
machine, the GPU driver wherever there is one; same code). :func:`get_renderer`
returns one :class:`Renderer` per scene: the scene is uploaded once, its
triangles grouped by texture into a single vertex/index buffer drawn with one
call per texture; the sun's shadow map is rendered once at upload (scene and sun
are static).

Shading: textured Lambert, ``albedo * texture * (ambient + sun * max(0, n.l) *
lit)`` in LINEAR radiance (textures are sRGB-decoded by the sampler), two-sided,
4x MSAA resolved by averaging the samples, trilinear mip-mapped, anisotropic
texture filtering (aliasing would turn into fake events in the event camera).

Camera model: the pose ``T_world_cam`` of the OPTICAL frame (z forward, x right,
y down) and a pinhole ``K``. The projection is built from ``K`` exactly with
OpenCV's convention: pixel centres at integer coordinates, row 0 = top of the
image. The image is rendered upside down in GL's window coordinates (GL's first
row = image row 0), so the readback needs no flip.

Depth: the metric z-depth along the optical axis, written per fragment as 1/z
interpolated exactly at the pixel centre (``interpolateAtOffset``), so it is
independent of the depth-buffer precision; at silhouettes the nearest sample wins;
``inf`` where nothing is hit. The depth buffer only resolves visibility.
"""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError

if TYPE_CHECKING:
    from roslan.scene.model import Scene

__all__ = [
    "EGL_PACKAGES",
    "RenderResult",
    "Renderer",
    "create_context",
    "get_renderer",
    "projection_from_K",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

EGL_PACKAGES = "libegl1, libegl-mesa0, libgl1-mesa-dri"
"""Debian packages that provide headless OpenGL through EGL (Mesa llvmpipe)."""

MSAA_SAMPLES = 4
"""Samples per pixel of the colour pass (clamped to what the driver supports)."""

_GL_SRGB8 = 0x8C41
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
    """

    color: F32 | None
    depth: F32 | None


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


_VERT = """
#version 410
uniform mat4 u_mvp;          // clip from world
uniform vec4 u_zrow;         // optical z from world (third row of T_cam_world)
uniform mat4 u_light;        // shadow-map [0,1]^3 from world
in vec3 in_pos;
in vec3 in_normal;
in vec2 in_uv;
in vec3 in_albedo;
out vec3 v_pos;
out vec3 v_normal;
out vec2 v_uv;
out vec3 v_albedo;
out float v_z;
out vec4 v_light;
void main() {
    vec4 p = vec4(in_pos, 1.0);
    gl_Position = u_mvp * p;
    v_pos = in_pos;
    v_normal = in_normal;
    v_uv = in_uv;
    v_albedo = in_albedo;
    v_z = dot(u_zrow, p);
    v_light = u_light * p;
}
"""

_FRAG = """
#version 410
uniform sampler2D u_tex;
uniform sampler2DShadow u_shadow;
uniform vec3 u_cam_pos;
uniform vec3 u_to_sun;        // unit vector towards the sun (world)
uniform float u_sun;
uniform float u_ambient;
uniform float u_shadow_texel;  // shadow-map texel size in [0,1] units
uniform bool u_shadows;
in vec3 v_pos;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_albedo;
in float v_z;
in vec4 v_light;
layout(location = 0) out vec4 o_color;
layout(location = 1) out float o_invz;
void main() {
    vec3 n = normalize(v_normal);
    // Two-sided: light the side facing the camera (window y is flipped, so
    // gl_FrontFacing is inverted; the geometric test needs no convention).
    if (dot(n, u_cam_pos - v_pos) < 0.0) n = -n;
    float ndl = max(dot(n, u_to_sun), 0.0);
    float lit = 1.0;
    if (u_shadows && ndl > 0.0) {
        vec3 lp = v_light.xyz;
        // slope-scaled bias against acne
        float bias = u_shadow_texel * (1.5 + 2.0 * sqrt(1.0 - ndl * ndl) / max(ndl, 0.05));
        lit = 0.0;
        for (int i = -1; i <= 1; ++i)
            for (int j = -1; j <= 1; ++j)
                lit += texture(u_shadow, vec3(lp.xy + vec2(i, j) * u_shadow_texel, lp.z - bias));
        lit /= 9.0;
    }
    vec3 albedo = v_albedo * texture(u_tex, v_uv).rgb;
    o_color = vec4(clamp(albedo * (u_ambient + u_sun * ndl * lit), 0.0, 1.0), 1.0);
    // exact optical z at the pixel centre, even for partially covered pixels
    float z = max(interpolateAtOffset(v_z, vec2(0.0)), 1e-6);
    o_invz = 1.0 / z;
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
#version 410
uniform sampler2DMS u_color;
uniform sampler2DMS u_invz;
uniform int u_samples;
layout(location = 0) out vec4 o_color;
layout(location = 1) out float o_depth;
void main() {{
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 c = vec3(0.0);
    float m = 0.0;
    for (int i = 0; i < u_samples; ++i) {{
        c += texelFetch(u_color, p, i).rgb;
        m = max(m, texelFetch(u_invz, p, i).r);   // nearest surface wins
    }}
    o_color = vec4(c / float(u_samples), 1.0);
    o_depth = m > 0.0 ? 1.0 / m : {_INF_BITS};
}}
"""


class _Targets:
    """Framebuffers of one resolution (created once, reused every frame)."""

    def __init__(self, ctx: Any, width: int, height: int, samples: int) -> None:
        size = (width, height)
        self.ms_color = ctx.texture(size, 4, samples=samples, dtype="f2")
        self.ms_invz = ctx.texture(size, 1, samples=samples, dtype="f4")
        self.ms_depth = ctx.depth_renderbuffer(size, samples=samples)
        self.ms_fbo = ctx.framebuffer([self.ms_color, self.ms_invz], self.ms_depth)
        self.out_color = ctx.texture(size, 4, dtype="f4")
        self.out_depth = ctx.texture(size, 1, dtype="f4")
        self.out_fbo = ctx.framebuffer([self.out_color, self.out_depth])
        # depth-only path: no MSAA, fragments shaded at pixel centres
        self.d_invz = ctx.texture(size, 1, dtype="f4")
        self.d_depth = ctx.depth_renderbuffer(size)
        self.d_fbo = ctx.framebuffer([self.d_invz], self.d_depth)
        self._objs = [
            self.ms_fbo,
            self.out_fbo,
            self.d_fbo,
            self.ms_color,
            self.ms_invz,
            self.ms_depth,
            self.out_color,
            self.out_depth,
            self.d_invz,
            self.d_depth,
        ]

    def release(self) -> None:
        for o in self._objs:
            o.release()


class Renderer:
    """Rasterizer of one scene. Use :func:`get_renderer` (one per scene and process).

    Attributes:
        max_size: largest image width/height the driver supports (pixels).
        samples: MSAA samples per pixel of the colour pass.
        near: near clipping distance (m), chosen from the scene size.
        anisotropy: texture anisotropic filtering level (1 on llvmpipe: see below).
    """

    def __init__(self, scene: Scene, *, samples: int = MSAA_SAMPLES) -> None:
        self.scene = scene
        self.ctx = ctx = create_context()
        self.max_size = int(
            min(
                ctx.info["GL_MAX_RENDERBUFFER_SIZE"],
                ctx.info["GL_MAX_TEXTURE_SIZE"],
                *ctx.info["GL_MAX_VIEWPORT_DIMS"],
            )
        )
        self.samples = max(1, min(samples, int(ctx.max_samples)))
        # Mesa's llvmpipe (LLVM 15) stalls for minutes on anisotropic filtering of
        # near-grazing, near-clipped ground planes: trilinear mip-mapping + MSAA there.
        software = "llvmpipe" in str(ctx.info.get("GL_RENDERER", "")).lower()
        self.anisotropy = 1.0 if software else 16.0
        self._targets: dict[tuple[int, int], _Targets] = {}
        self._released = False

        lo, hi = scene.bounds
        diag = float(np.linalg.norm(hi - lo))
        self._bounds_corners = np.array(
            [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        # 24-bit depth buffer: resolution ~ z^2 / (near * 2^24); 1 cm near gives
        # ~6 mm at 100 m, while cameras may still fly within centimetres of a perch.
        self.near = float(np.clip(1e-4 * diag, 0.005, 0.02))

        self._prog = ctx.program(vertex_shader=_VERT, fragment_shader=_FRAG)
        self._prog_depth = ctx.program(vertex_shader=_VERT_DEPTH, fragment_shader=_FRAG_DEPTH)
        self._prog_shadow = ctx.program(vertex_shader=_VERT_SHADOW, fragment_shader=_FRAG_SHADOW)
        self._prog_resolve = ctx.program(vertex_shader=_VERT_QUAD, fragment_shader=_FRAG_RESOLVE)
        self._quad = ctx.vertex_array(self._prog_resolve, [])
        self._upload(scene)
        self._build_shadow_map(scene)

        lights = scene.lights
        d = np.asarray(lights.sun_direction, dtype=np.float64)
        to_sun = -d / max(float(np.linalg.norm(d)), 1e-12)
        self._prog["u_to_sun"].value = tuple(to_sun)
        self._prog["u_sun"].value = float(lights.sun_intensity)
        self._prog["u_ambient"].value = float(lights.ambient)
        self._prog["u_tex"].value = 0
        self._prog["u_shadow"].value = 1
        self._prog_resolve["u_color"].value = 0
        self._prog_resolve["u_invz"].value = 1
        self._prog_resolve["u_samples"].value = self.samples

    # ----------------------------------------------------------------- upload
    def _upload(self, scene: Scene) -> None:
        """One interleaved VBO + IBO for the whole scene, faces sorted by texture."""
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
        self._draws: list[tuple[Any, int, int]] = []  # (texture, first index, count)
        self._textures: list[Any] = []
        offset = 0
        first = 0
        white = ctx.texture((1, 1), 3, bytes([255, 255, 255]), internal_format=_GL_SRGB8)
        self._textures.append(white)
        aniso = float(min(self.anisotropy, ctx.max_anisotropy))
        for key, members in groups.items():
            count = 0
            for i in members:
                o = scene.objects[i]
                nv = o.vertices.shape[0]
                attrs = np.empty((nv, 11), dtype=np.float32)
                attrs[:, 0:3] = o.vertices
                attrs[:, 3:6] = o.normals
                attrs[:, 6:8] = o.uvs * np.float32(o.material.texture_scale)
                attrs[:, 8:11] = np.asarray(o.material.color, dtype=np.float32)
                parts.append(attrs)
                faces.append(o.faces.astype(np.int32) + offset)
                offset += nv
                count += o.faces.size
            if count == 0:
                continue
            img = textures[key]
            if img is None:
                tex = white
            else:
                img = np.ascontiguousarray(img[..., :3], dtype=np.uint8)
                h, w = img.shape[:2]
                # GL's first texture row is v = 0: flip so v = 0 is the image's bottom
                # (the usual glTF/OBJ convention for UVs).
                tex = ctx.texture(
                    (w, h), 3, np.ascontiguousarray(img[::-1]).tobytes(), internal_format=_GL_SRGB8
                )
                tex.build_mipmaps()
                tex.filter = (ctx.LINEAR_MIPMAP_LINEAR, ctx.LINEAR)
                tex.anisotropy = aniso
                tex.repeat_x = tex.repeat_y = True
                self._textures.append(tex)
            self._draws.append((tex, first, count))
            first += count

        if offset == 0:
            self._vbo = None
            self._vao = self._vao_depth = self._vao_shadow = None
            return
        data = np.concatenate(parts)
        idx = np.concatenate(faces).reshape(-1)
        self._vbo = ctx.buffer(data.tobytes())
        self._ibo = ctx.buffer(idx.astype(np.uint32).tobytes())
        fmt = "3f 3f 2f 3f"
        self._vao = ctx.vertex_array(
            self._prog,
            [(self._vbo, fmt, "in_pos", "in_normal", "in_uv", "in_albedo")],
            self._ibo,
            index_element_size=4,
        )
        self._vao_depth = ctx.vertex_array(
            self._prog_depth, [(self._vbo, "3f 32x", "in_pos")], self._ibo, index_element_size=4
        )
        self._vao_shadow = ctx.vertex_array(
            self._prog_shadow, [(self._vbo, "3f 32x", "in_pos")], self._ibo, index_element_size=4
        )
        self._n_index = int(idx.size)

    def _build_shadow_map(self, scene: Scene) -> None:
        """Orthographic depth map along the sun over the scene's bounding sphere."""
        ctx = self.ctx
        lo, hi = scene.bounds
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        # ~1 cm texels where affordable, 1024..4096 texels
        size = int(np.clip(2 ** math.ceil(math.log2(max(2 * radius / 0.01, 1.0))), 1024, 4096))
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
        self._prog["u_light"].write(_gl_mat(to_unit @ L))
        self._prog["u_shadow_texel"].value = 1.0 / size
        self._prog["u_shadows"].value = self._vao_shadow is not None

    # ----------------------------------------------------------------- render
    def _targets_for(self, width: int, height: int) -> _Targets:
        t = self._targets.get((width, height))
        if t is None:
            t = _Targets(self.ctx, width, height, self.samples)
            self._targets[(width, height)] = t
        return t

    def check_size(self, width: int, height: int) -> None:
        """Raise RenderError if the driver cannot render ``width`` x ``height``."""
        if not (1 <= width <= self.max_size and 1 <= height <= self.max_size):
            msg = (
                f"image size {width}x{height} is not supported by this OpenGL renderer "
                f"({self.ctx.info['GL_RENDERER']}): width and height must be 1..{self.max_size}"
            )
            raise RenderError(msg)

    def render(
        self,
        T_world_cam: F64,
        K: F64,
        width: int,
        height: int,
        *,
        color: bool = True,
        depth: bool = True,
    ) -> RenderResult:
        """Render the view of a pinhole camera.

        Args:
            T_world_cam: (4, 4) pose of the camera OPTICAL frame (z forward, x right,
                y down) in the world.
            K: (3, 3) intrinsic matrix (OpenCV convention, pixels).
            width, height: image size (pixels).
            color, depth: which channels to compute and read back.
        Returns:
            :class:`RenderResult`; row 0 is the top of the image.
        """
        if self._released:
            msg = "renderer was released"
            raise RenderError(msg)
        width, height = int(width), int(height)
        self.check_size(width, height)
        if not (color or depth):
            return RenderResult(None, None)
        T = np.asarray(T_world_cam, dtype=np.float64)
        T_cam_world = np.linalg.inv(T)
        cam_pos = T[:3, 3]
        far = float(np.max(np.linalg.norm(self._bounds_corners - cam_pos, axis=1))) * 1.01
        far = max(far, 2.0 * self.near)
        P = projection_from_K(np.asarray(K, dtype=np.float64), width, height, self.near, far)
        mvp = _gl_mat(P @ T_cam_world)
        zrow = tuple(float(x) for x in T_cam_world[2])
        t = self._targets_for(width, height)
        ctx = self.ctx
        ctx.viewport = (0, 0, width, height)

        if not color:
            t.d_fbo.use()
            t.d_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            if self._vao_depth is not None:
                ctx.enable_only(ctx.DEPTH_TEST)
                ctx.depth_func = "<"
                self._prog_depth["u_mvp"].write(mvp)
                self._prog_depth["u_zrow"].value = zrow
                self._vao_depth.render(ctx.TRIANGLES)
            inv = np.empty((height, width), dtype=np.float32)
            t.d_fbo.read_into(inv, components=1, dtype="f4", attachment=0)
            with np.errstate(divide="ignore"):
                np.reciprocal(inv, out=inv)  # 1/0 -> inf: nothing hit
            return RenderResult(None, inv)

        t.ms_fbo.use()
        t.ms_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if self._vao is not None:
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            prog = self._prog
            prog["u_mvp"].write(mvp)
            prog["u_zrow"].value = zrow
            prog["u_cam_pos"].value = tuple(float(x) for x in cam_pos)
            self._shadow_tex.use(1)
            for tex, first, count in self._draws:
                tex.use(0)
                self._vao.render(ctx.TRIANGLES, vertices=count, first=first)
        # resolve: average colour samples, nearest depth sample
        t.out_fbo.use()
        ctx.disable(ctx.DEPTH_TEST)
        t.ms_color.use(0)
        t.ms_invz.use(1)
        self._quad.render(ctx.TRIANGLES, vertices=3)
        col = dep = None
        if color:
            col = np.empty((height, width, 3), dtype=np.float32)
            t.out_fbo.read_into(col, components=3, dtype="f4", attachment=0)
        if depth:
            dep = np.empty((height, width), dtype=np.float32)
            t.out_fbo.read_into(dep, components=1, dtype="f4", attachment=1)
        return RenderResult(col, dep)

    def release(self) -> None:
        """Free the GPU objects of this renderer (the context stays for others)."""
        if self._released:
            return
        self._released = True
        try:
            for t in self._targets.values():
                t.release()
            self._targets.clear()
            for tex in self._textures:
                tex.release()
            for o in (self._vao, self._vao_depth, self._vao_shadow, self._vbo):
                if o is not None:
                    o.release()
            if self._vbo is not None:
                self._ibo.release()
            self._shadow_fbo.release()
            self._shadow_tex.release()
        except Exception:  # interpreter shutdown: the context may be gone already
            pass


def _gl_mat(M: F64) -> bytes:
    """Column-major float32 bytes of a 4x4 matrix (GLSL's layout)."""
    return np.ascontiguousarray(np.asarray(M, dtype=np.float32).T).tobytes()
