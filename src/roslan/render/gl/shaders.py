"""GLSL sources of the rasterizer's passes and :func:`source`, which prepends the
``#version`` line and the variant ``#define`` lines.

Variants (``#define``): ``LUM`` shades one luminance channel instead of RGB, ``DEPTH``
adds the 1/z attachment, ``IMAGE`` loads the edge filter's texels with ``imageLoad``
(GL 4.2), ``REFERENCE`` is the supersampled reference's texture filter. Every source
sees ``const vec3 LUMA``, the Rec. 709 luminance weights.
"""

from __future__ import annotations

from roslan.render.color import REC709_LUMA

__all__ = [
    "COLOR_FRAG",
    "COLOR_VERT",
    "FRAG_DEPTH",
    "FRAG_EDGE_AA",
    "FRAG_IDS",
    "FRAG_RESOLVE",
    "FRAG_SHADOW",
    "VERT_DEPTH",
    "VERT_QUAD",
    "VERT_SHADOW",
    "source",
]

_INF_BITS = "uintBitsToFloat(0x7F800000u)"

COLOR_VERT = """
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

COLOR_FRAG = """
uniform sampler2D u_tex;
uniform sampler2DShadow u_shadow;
uniform int u_max_aniso;     // REFERENCE: most taps of its texture filter
// Texture filtering in the shader, the same arithmetic on every OpenGL implementation
// (a driver's anisotropic filtering and mip-level arithmetic are its own, and
// llvmpipe's anisotropic filtering stalls), from the explicit (fine, per 2x2 quad) uv
// derivatives: the pixel's footprint in texels. Mip levels are picked here (integer
// lods: the textures' LINEAR_MIPMAP_NEAREST filter then only does bilinear filtering
// within that level).
// Default: the pixel's area average, supersampled in texture space: 2 x 2 bilinear taps
// at the quarter points of the footprint's parallelogram (the centres of its four
// half-pixel cells), each in the mip level of a half-pixel cell (its longer side a
// quarter level finer, its shorter side not), rounded down from 0.82 of a level up
// (0.32 of a level towards the finer one). One tap at a footprint-sized level is a mip
// texel convolved with the bilinear tent, about twice as wide as the pixel: it blurs and
// loses events (-6 to -10 % on the early landing); the constants were chosen against the
// supersampled reference (docs/performance.md, "Image formation").
// REFERENCE (the supersampled reference, whose samples are themselves 1/N pixel apart):
// the EXT_texture_filter_anisotropic recipe, n = ceil(major / minor) taps along the
// major axis (1 where the texture is magnified), up to u_max_aniso, each trilinear at
// the level of major / n, spread evenly over the footprint and averaged.
#ifndef GL_ARB_derivative_control
#define dFdxFine dFdx
#define dFdyFine dFdy
#endif
vec3 trilinear(vec2 p, float lod) {
    float l = max(lod, 0.0);
    float l0 = floor(l);
    return mix(textureLod(u_tex, p, l0).rgb, textureLod(u_tex, p, l0 + 1.0).rgb, l - l0);
}
vec3 tex_filtered(vec2 uv) {
    vec2 size = vec2(textureSize(u_tex, 0));
    vec2 gx = dFdxFine(uv), gy = dFdyFine(uv);
    float lx = dot(gx * size, gx * size), ly = dot(gy * size, gy * size);
    vec2 major = lx >= ly ? gx : gy;
    float lmaj = sqrt(max(lx, ly)), lmin = sqrt(min(lx, ly));
#ifdef REFERENCE
    float n = clamp(ceil(min(lmaj / max(lmin, 1e-20), lmaj)), 1.0, float(u_max_aniso));
    float lod = log2(max(lmaj / n, 1e-20));
    int taps = int(n);
    vec3 acc = vec3(0.0);
    for (int i = 0; i < taps; ++i) {
        acc += trilinear(uv + major * ((float(i) + 0.5) / n - 0.5), lod);
    }
    return acc / n;
#else
    // unrolled (a loop costs llvmpipe more)
    float lmj = log2(max(lmaj, 1e-20)) - 1.25, lmn = log2(max(lmin, 1e-20)) - 1.0;
    float lod = max(floor(max(lmj, lmn) + 0.18), 0.0);
    vec2 ox = 0.25 * gx, oy = 0.25 * gy;
    vec3 a = textureLod(u_tex, uv - ox - oy, lod).rgb + textureLod(u_tex, uv + ox - oy, lod).rgb;
    vec3 b = textureLod(u_tex, uv - ox + oy, lod).rgb + textureLod(u_tex, uv + ox + oy, lod).rgb;
    return 0.25 * (a + b);
#endif
}
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
    vec3 c = clamp(tex_filtered(v_uv) * v_albedo * (u_ambient + v_sun * lit), 0.0, 1.0);
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

FRAG_DEPTH = """
#version 410
in float v_z;
layout(location = 0) out float o_invz;
void main() { o_invz = 1.0 / max(v_z, 1e-6); }
"""

VERT_DEPTH = """
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

FRAG_IDS = """
#version 410
uniform uint u_tri0;  // the draw's first triangle in the index buffer
in float v_z;
layout(location = 0) out float o_invz;
layout(location = 1) out uint o_tri;
// 1 + the uploaded triangle at the pixel centre (no MSAA, no blend: one surface)
void main() { o_invz = 1.0 / max(v_z, 1e-6); o_tri = u_tri0 + uint(gl_PrimitiveID) + 1u; }
"""

VERT_SHADOW = """
#version 410
uniform mat4 u_mvp;
in vec3 in_pos;
void main() { gl_Position = u_mvp * vec4(in_pos, 1.0); }
"""

FRAG_SHADOW = """
#version 410
void main() {}
"""

VERT_QUAD = """
#version 410
void main() {
    // one triangle covering the viewport
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

FRAG_RESOLVE = f"""
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


FRAG_EDGE_AA = """
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
    // aliases (texture detail lies on planes and is filtered already).
    // On the image border the clamped neighbour equals this pixel, which would make a
    // plane's one-sided slope look like a crease: that axis's difference is not used there.
    float zm = tm[ZCH];
    float d2y = (p.y > 0 && p.y < hi.y) ? abs(tn[ZCH] + ts[ZCH] - 2.0 * zm) : 0.0;
    float d2x = (p.x > 0 && p.x < hi.x) ? abs(te[ZCH] + tw[ZCH] - 2.0 * zm) : 0.0;
    float d2 = max(d2y, d2x);
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
        // blend in the neighbour across the edge by its estimated coverage of this
        // pixel: at least 1/12, up to 3/8 by the sub-pixel estimate. (A straight edge
        // between two pixel centres, at a uniform offset d in [0, 1), covers max(0, 1/2 -
        // d) of one of them and max(0, d - 1/2) of the other: 1/8 on average. Where edges
        // crowd, as on distant shelving, neighbouring blends compound, and 1/8 came out
        // 6-10 % under the supersampled reference's events there, 1/12 within 3 %;
        // FXAA's 1/4 lost 7 % of all the events; docs/performance.md, "Image formation".)
        // The blend uses the texels already loaded (llvmpipe runs a sampler call in a
        // branch for every pixel of a mixed SIMD group).
        c = mix(tm, t, max(sub * sub * 0.375, 1.0 / 12.0));
    }
#ifdef LUM
    o_color = c.r;
#else
    o_color = vec4(c.rgb, 1.0);
#endif
}
"""


def source(
    body: str, *, lum: bool, depth: bool, image: bool = False, reference: bool = False
) -> str:
    """``body`` with the ``#version`` line, the variant defines and ``LUMA`` prepended."""
    defs = ["#version 420" if image else "#version 410"]
    # explicit fine derivatives (core in GL 4.5; llvmpipe and the GPU drivers have it)
    defs.append("#extension GL_ARB_derivative_control : enable")
    if image:
        defs.append("#define IMAGE")
    if lum:
        defs.append("#define LUM")
    if depth:
        defs.append("#define DEPTH")
    if reference:
        defs.append("#define REFERENCE")
    defs.append("const vec3 LUMA = vec3({:.4f}, {:.4f}, {:.4f});".format(*REC709_LUMA))
    return "\n".join(defs) + "\n" + body
