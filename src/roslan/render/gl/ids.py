"""The id pass: which scene triangle every pixel centre sees.

One pass over the same visible runs as the depth pass (same view, same near plane, no
MSAA, fragments at pixel centres, no blending): each fragment writes 1 + its uploaded
triangle (``gl_PrimitiveID`` plus the draw's first triangle) into an R32UI target,
beside 1/z (where 1/z is 0 nothing was hit). The readback maps the uploaded triangles
to :attr:`Scene.triangles <roslan.scene.model.Scene.triangles>` indices
(:attr:`SceneBuffers.tri_source <roslan.render.gl.upload.SceneBuffers>`), so a camera
turns them into instance or class ids with the scene's per-triangle table
(:func:`roslan.scene.instances.scene_labels`). At a silhouette the pixel shows the
surface its centre hits, nearest first (the depth test), as the depth camera does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from roslan.render.gl import shaders
from roslan.render.gl.upload import merge_runs

if TYPE_CHECKING:
    from roslan.render.gl.upload import SceneBuffers

__all__ = ["IdPass"]

U32 = NDArray[np.uint32]


class IdPass:
    """The id program, its vertex array and one target per image size."""

    def __init__(self, ctx: Any, buffers: SceneBuffers) -> None:
        self.ctx = ctx
        self.prog = ctx.program(vertex_shader=shaders.VERT_DEPTH, fragment_shader=shaders.FRAG_IDS)
        self.vao: Any = None
        if buffers.vbo is not None:
            self.vao = ctx.vertex_array(
                self.prog, [(buffers.vbo, "3f 32x", "in_pos")], buffers.ibo, index_element_size=4
            )
        # index 0: nothing; k + 1: uploaded triangle k -> its scene triangle + 1
        self.lut = np.concatenate([[0], buffers.tri_source + 1]).astype(np.uint32)
        self._targets: dict[tuple[int, int], tuple[Any, ...]] = {}

    def render(
        self, width: int, height: int, mvp: bytes, zrow: tuple[float, ...], runs: Any
    ) -> U32:
        """(H, W) uint32: 1 + the scene triangle at each pixel centre, 0 where nothing is
        hit. ``runs``: ``(first, count, cull)`` arrays of the visible index ranges."""
        ctx = self.ctx
        tgt = self._targets.get((width, height))
        if tgt is None:
            invz = ctx.texture((width, height), 1, dtype="f4")
            tri = ctx.texture((width, height), 1, dtype="u4")
            drb = ctx.depth_renderbuffer((width, height))
            tgt = (ctx.framebuffer([invz, tri], drb), invz, tri, drb)
            self._targets[(width, height)] = tgt
        fbo = tgt[0]
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        first, count, cull = runs
        if first.size and self.vao is not None:
            ctx.enable_only(ctx.DEPTH_TEST)
            ctx.depth_func = "<"
            ctx.front_face = "cw"  # (see Renderer._draw_color)
            self.prog["u_mvp"].write(mvp)
            self.prog["u_zrow"].value = zrow
            culling = False
            for f, n, c in merge_runs(first, count, cull):
                if c != culling:
                    (ctx.enable if c else ctx.disable)(ctx.CULL_FACE)
                    culling = c
                self.prog["u_tri0"].value = f // 3
                self.vao.render(ctx.TRIANGLES, vertices=n, first=f)
            ctx.disable(ctx.CULL_FACE)
        inv = np.empty((height, width), dtype=np.float32)
        fbo.read_into(inv, components=1, dtype="f4", attachment=0)
        up = np.empty((height, width), dtype=np.uint32)
        fbo.read_into(up, components=1, dtype="u4", attachment=1)
        # (an integer target's clear value is not defined by glClear: 1/z = 0 says "nothing")
        np.minimum(up, np.uint32(self.lut.size - 1), out=up)
        out: U32 = self.lut[up]
        out[inv <= 0.0] = 0
        return out

    def release(self) -> None:
        for tgt in self._targets.values():
            for o in tgt:
                o.release()
        self._targets.clear()
        for o in (self.vao, self.prog):
            if o is not None:
                o.release()
