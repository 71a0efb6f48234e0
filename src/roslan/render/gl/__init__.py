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
Image formation, the same on every OpenGL implementation (nothing that sets a pixel is
left to the driver; :func:`image_formation` is what run.json records): aliasing would
turn into fake events in the event camera, over-blurring into missing ones. Textures:
mip levels computed by roslan (:mod:`.mipmaps`, area averages in linear light) and
filtered in the shader from explicit uv derivatives: the pixel's area average
supersampled in texture space, :data:`DEFAULT_TEXTURE_TAPS` bilinear taps at the centres
of its footprint's half-pixel cells in the mip level of a cell (llvmpipe's own
anisotropic filtering stalls, and a GPU's differs). Geometric edges: 1 sample per pixel
(:data:`DEFAULT_SAMPLES`) and an FXAA-style edge filter on geometric edges only: where
1/z is not affine in the image (silhouettes, creases) and the luma contrast is high, the
neighbour across the edge is blended in by its estimated coverage (1/12 to 3/8); texture
detail on planes is left untouched. One shadow-map size (:data:`.upload.SHADOW_MAP_MAX`).
Sub-pixel geometry (wires, lines thinner than a pixel) needs MSAA:
``ROSLAN_MSAA_SAMPLES=4``. ``render(supersampling=N)`` is the reference the default is
measured against (:mod:`.supersample`): N x N samples per pixel, box-filtered, textures
filtered per sample with up to :data:`MAX_ANISO` trilinear taps, no edge filter.

Where no surface is hit, colour and luminance are the scene's sky radiance
(:attr:`~roslan.scene.model.Lights.sky`) and depth is ``inf``.

Outputs (keywords of :meth:`Renderer.render`): linear RGB, Rec. 709 luminance (one
channel: what grayscale and event cameras need, computed in the shader, a quarter of
the readback), metric depth; each is computed and read back only when requested.

Camera model and depth: see :mod:`.renderer`.

Speed (see ``benchmarks/profile_render.py`` and the "Cameras" section of
docs/performance.md): llvmpipe shades on ``LP_NUM_THREADS`` threads (default: all
cores); vertex processing runs on the calling thread, hence the culling, and the colour
pass is flushed in :data:`FLUSH_CHUNKS` parts so that shading overlaps it. The edge
filter loads its texels through ``imageLoad`` (cheaper than ``texelFetch`` there) and
writes an RGB32F target where that is renderable; callers that render every frame pass
``out=`` buffers (fresh multi-MB arrays cost page faults).

Modules: :mod:`.context` (EGL context, raw GL entry points), :mod:`.shaders` (GLSL),
:mod:`.upload` (scene buffers, culling clusters, shadow map), :mod:`.mipmaps`,
:mod:`.targets` (framebuffers), :mod:`.settings` (image-formation settings),
:mod:`.supersample` (the reference), :mod:`.renderer` (:class:`Renderer`).
"""

from roslan.render.base import RenderResult
from roslan.render.gl.context import EGL_PACKAGES, create_context
from roslan.render.gl.renderer import (
    FLUSH_CHUNKS,
    Renderer,
    get_renderer,
    projection_from_K,
)
from roslan.render.gl.settings import (
    DEFAULT_SAMPLES,
    DEFAULT_TEXTURE_TAPS,
    MAX_ANISO,
    MAX_SUPERSAMPLING,
    default_samples,
    image_formation,
)

__all__ = [
    "DEFAULT_SAMPLES",
    "DEFAULT_TEXTURE_TAPS",
    "EGL_PACKAGES",
    "FLUSH_CHUNKS",
    "MAX_ANISO",
    "MAX_SUPERSAMPLING",
    "RenderResult",
    "Renderer",
    "create_context",
    "default_samples",
    "get_renderer",
    "image_formation",
    "projection_from_K",
]
