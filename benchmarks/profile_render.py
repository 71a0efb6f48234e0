"""Where the renderer's time goes, stage by stage, on one warehouse view.

Each stage is timed on its own (``ctx.finish()`` closes it; median of repetitions):
clear, colour draw (culled / all clusters; one draw per cluster / merged runs / one
draw; shader without shadow lookup, without textures), MSAA resolve, readback per
channel, the depth-only pass, and ``Renderer.render`` end to end for each output
combination, at 4 and 1 MSAA samples.

Run by hand: ``.venv/bin/python benchmarks/profile_render.py [WIDTH HEIGHT [FOCAL]]``
(default: 643 483 255, the render of bench_camera's 640x480 plumb_bob frame; it was
805 605 320 before the lens plan's density was reduced); compare
``LP_NUM_THREADS=1`` to see that llvmpipe uses both cores.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

import roslan.render.gl as gl
from roslan.render.gl import shaders
from roslan.render.gl.context import gl_mat
from roslan.scene import load_scene

REPS = 15
ATTRS = ("in_pos", "in_normal", "in_uv", "in_albedo")


def _ms(f: Callable[[], object], n: int = REPS) -> float:
    f()
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts) * 1e3


def view(scene: Any, w: int, h: int, f: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The bench_camera.py view: 6 m before, 3 m above the landing marker, pitched
    down 0.35 rad; K with fx = fy = ``f`` (default w / 2: the cameras' default 90 deg
    horizontal field of view; bench_camera's 640x480 plumb_bob camera renders 643x483
    with f = 255)."""
    T_wb = np.eye(4)
    T_wb[:3, 3] = np.asarray(scene.goal_position) + np.array([-6.0, 1.0, 3.0])
    p = 0.35
    T_wb[:3, :3] = [[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]]
    T_link_optical = np.array([[0, 0, 1, 0], [-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 0, 1.0]])
    f = w / 2 if f is None else f
    K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
    return T_wb @ T_link_optical, K


def stages(r: gl.Renderer, T: np.ndarray, K: np.ndarray, w: int, h: int, ns: int) -> None:
    ctx = r.ctx
    T_cw = np.linalg.inv(T)
    P = gl.projection_from_K(K, w, h, r.near, 80.0)  # (the far plane culls nothing here)
    clip = P @ T_cw
    # front to back with back faces culled, as render() (the near plane's reach is
    # irrelevant here: the camera is far from every object's box)
    first, count, group, bfc = r.visible_ranges(clip, T[:3, 3])
    no_bfc = np.zeros_like(bfc)
    all_first, all_count, all_group = r.buffers.c_first, r.buffers.c_count, r.buffers.c_group
    all_bfc = np.zeros(all_first.size, dtype=bool)
    n_vis = int(count.sum()) // 3
    cull_ms = _ms(lambda: r.visible_ranges(clip, T[:3, 3]))
    print(
        f"  culling: {n_vis} of {r.scene.n_triangles} triangles in {first.size} draws "
        f"({r.n_clusters} clusters), {int(count[bfc].sum()) // 3} of them back-face "
        f"culled; frustum test + sort {cull_ms:.2f} ms"
    )
    r.render(T, K, w, h, samples=ns)  # targets and programs
    t = r._targets[(w, h, ns, False, True, r._rgb_target)]
    fbo = t.ms_fbo if ns > 1 else t.out_fbo
    prog, vao = r.programs.color(False, True)
    prog["u_mvp"].write(gl_mat(clip))
    prog["u_zrow"].value = tuple(T_cw[2])
    prog["u_cam_pos"].value = tuple(T[:3, 3])

    def clear() -> None:
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.finish()

    def draw(
        fs: np.ndarray,
        cs: np.ndarray,
        gs: np.ndarray,
        bs: np.ndarray,
        vao: Any = vao,
        one: bool = False,
    ) -> Callable[[], None]:
        def f() -> None:
            fbo.use()
            ctx.viewport = (0, 0, w, h)
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            ctx.front_face = "cw"
            r.shadow.tex.use(1)
            if one:
                r.buffers.group_tex[0].use(0)
                vao.render(ctx.TRIANGLES)
            else:
                for a, b, g, c in zip(
                    fs.tolist(), cs.tolist(), gs.tolist(), bs.tolist(), strict=True
                ):
                    r.buffers.group_tex[g].use(0)
                    (ctx.enable if c else ctx.disable)(ctx.CULL_FACE)
                    vao.render(ctx.TRIANGLES, vertices=b, first=a)
            ctx.disable(ctx.CULL_FACE)
            ctx.finish()

        return f

    clear_ms = _ms(clear)
    print(f"  clear: {clear_ms:.1f} ms")

    def report(name: str, f: Callable[[], None]) -> None:
        print(f"  {name}: {_ms(f) - clear_ms:.1f} ms")

    report("draw, culled, merged runs (the renderer)", draw(first, count, group, bfc))
    report("draw, no back-face culling", draw(first, count, group, no_bfc))
    report("draw, all clusters, one draw each", draw(all_first, all_count, all_group, all_bfc))
    report("draw, no culling, one draw", draw(first, count, group, no_bfc, one=True))
    # shader ablations (same culled draws)
    for name, old, new in [
        ("no shadow lookup", "texture(u_shadow, v_light)", "1.0"),
        ("no texture lookup", "tex_filtered(v_uv)", "vec3(1.0)"),
    ]:
        p2 = ctx.program(
            vertex_shader=shaders.source(shaders.COLOR_VERT, lum=False, depth=True),
            fragment_shader=shaders.source(
                shaders.COLOR_FRAG.replace(old, new), lum=False, depth=True
            ),
        )
        for k in ("u_to_sun", "u_sun", "u_ambient", "u_shadow_texel", "u_zrow", "u_cam_pos"):
            if k in p2:
                p2[k].value = prog[k].value
        for k in ("u_mvp", "u_light"):
            if k in p2:
                p2[k].write(prog[k].read())
        if "u_shadow" in p2:
            p2["u_shadow"].value = 1
        attrs = [a for a in ATTRS if a in p2]
        fmt = " ".join(
            f if a in attrs else f"{4 * int(f[0])}x"
            for f, a in zip(("3f", "3f", "2f", "3f"), ATTRS, strict=True)
        )
        v2 = ctx.vertex_array(
            p2, [(r.buffers.vbo, fmt, *attrs)], r.buffers.ibo, index_element_size=4
        )
        report(f"draw, {name}", draw(first, count, group, bfc, vao=v2))
        v2.release()
        p2.release()
    if ns > 1:
        rprog, quad = r.programs.resolve(False, True)

        def resolve() -> None:
            t.out_fbo.use()
            ctx.disable(ctx.DEPTH_TEST)
            rprog["u_samples"].value = ns
            t.ms_color.use(0)
            t.ms_invz.use(1)
            quad.render(ctx.TRIANGLES, vertices=3)
            ctx.finish()

        print(f"  resolve (RGB + depth): {_ms(resolve):.1f} ms")
    else:
        _, aquad = r.programs.edge_filter(False, r._image)

        def edge_filter() -> None:
            t.aa_fbo.use()
            ctx.disable(ctx.DEPTH_TEST)
            t.out_color.use(0)
            if r._image:  # the point loads read the same texture as an image
                t.out_color.bind_to_image(0, read=True, write=False)
            aquad.render(ctx.TRIANGLES, vertices=3)
            ctx.finish()

        print(f"  edge filter (RGB): {_ms(edge_filter):.1f} ms")
    col = np.empty((h, w, 3), np.float32)
    dep = np.empty((h, w), np.float32)
    print(
        "  readback: RGB float32 "
        f"{_ms(lambda: t.out_fbo.read_into(col, components=3, dtype='f4', attachment=0)):.2f}"
        " ms, depth float32 "
        f"{_ms(lambda: t.out_fbo.read_into(dep, components=1, dtype='f4', attachment=1)):.2f}"
        " ms"
    )


def main() -> None:
    w, h = (int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (643, 483)
    f = float(sys.argv[3]) if len(sys.argv) > 3 else (255.0 if (w, h) == (643, 483) else None)
    scene = load_scene("warehouse")
    r = gl.get_renderer(scene)
    print(
        f"{r.ctx.info['GL_RENDERER']}; LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', '-')}; "
        f"warehouse {scene.n_triangles} triangles; {w}x{h}; "
        f"load average {os.getloadavg()[0]:.2f}; median of {REPS}"
    )
    T, K = view(scene, w, h, f)
    for ns in (4, 1):
        print(f"--- MSAA samples {ns}")
        for opts in (
            {"color": True, "depth": False},
            {"color": True, "depth": True},
            {"color": False, "depth": False, "luminance": True},
            {"color": False, "depth": True, "luminance": True},
        ):
            f = lambda o=opts, s=ns: r.render(T, K, w, h, samples=s, **o)  # noqa: E731
            print(f"  render({', '.join(k for k, v in opts.items() if v)}): {_ms(f):.1f} ms")
        stages(r, T, K, w, h, ns)
    f = lambda: r.render(T, K, w, h, color=False, depth=True)  # noqa: E731
    print(f"--- depth-only pass (no MSAA): {_ms(f):.1f} ms")


if __name__ == "__main__":
    main()
