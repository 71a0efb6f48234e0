"""The compiled shader programs of a renderer: every variant compiled on first use,
with its constant uniforms (lights, shadow map) set once."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from roslan.render.gl import shaders

if TYPE_CHECKING:
    from roslan.render.gl.upload import SceneBuffers, ShadowMap
    from roslan.scene.model import Scene

__all__ = ["Programs"]

_COLOR_ATTRS = ("3f 3f 2f 3f", "in_pos", "in_normal", "in_uv", "in_albedo")


class Programs:
    """Cache of (program, vertex array) pairs of the colour, resolve and edge-filter
    passes of one scene."""

    def __init__(self, ctx: Any, scene: Scene, buffers: SceneBuffers, shadow: ShadowMap) -> None:
        self.ctx = ctx
        self.lights = scene.lights  # (not the scene: see Renderer)
        self.buffers = buffers
        self.shadow = shadow
        self._color: dict[tuple[bool, bool, bool], tuple[Any, Any]] = {}
        self._resolve: dict[tuple[bool, bool], tuple[Any, Any]] = {}
        self._edge: dict[tuple[bool, bool], tuple[Any, Any]] = {}

    def color(self, lum: bool, depth: bool, reference: bool = False) -> tuple[Any, Any]:
        """(program, vertex array) of the colour pass variant (vertex array None for a
        scene without triangles); ``reference``: the supersampled reference's texture
        filter (up to ``u_max_aniso`` taps)."""
        key = (lum, depth, reference)
        pv = self._color.get(key)
        if pv is None:
            ctx = self.ctx
            prog = ctx.program(
                vertex_shader=shaders.source(shaders.COLOR_VERT, lum=lum, depth=depth),
                fragment_shader=shaders.source(
                    shaders.COLOR_FRAG, lum=lum, depth=depth, reference=reference
                ),
            )
            lights = self.lights
            d = np.asarray(lights.sun_direction, dtype=np.float64)
            to_sun = -d / max(float(np.linalg.norm(d)), 1e-12)
            consts: dict[str, Any] = {
                "u_to_sun": tuple(float(x) for x in to_sun),
                "u_sun": float(lights.sun_intensity),
                "u_ambient": float(lights.ambient),
                "u_tex": 0,
                "u_shadow": 1,
                "u_shadow_texel": self.shadow.texel,
            }
            for k, v in consts.items():
                if k in prog:  # (a uniform the compiler optimised away is absent)
                    prog[k].value = v
            if "u_light" in prog:
                prog["u_light"].write(self.shadow.light)
            vao = None
            if self.buffers.vbo is not None:
                vao = ctx.vertex_array(
                    prog,
                    [(self.buffers.vbo, *_COLOR_ATTRS)],
                    self.buffers.ibo,
                    index_element_size=4,
                )
            pv = (prog, vao)
            self._color[key] = pv
        return pv

    def resolve(self, lum: bool, depth: bool) -> tuple[Any, Any]:
        """(program, empty vertex array) of the MSAA resolve pass variant."""
        key = (lum, depth)
        pv = self._resolve.get(key)
        if pv is None:
            prog = self.ctx.program(
                vertex_shader=shaders.VERT_QUAD,
                fragment_shader=shaders.source(shaders.FRAG_RESOLVE, lum=lum, depth=depth),
            )
            prog["u_color"].value = 0
            if depth:
                prog["u_invz"].value = 1
            pv = (prog, self.ctx.vertex_array(prog, []))
            self._resolve[key] = pv
        return pv

    def edge_filter(self, lum: bool, image: bool) -> tuple[Any, Any]:
        """(program, empty vertex array) of the edge filter variant (``image``: texel
        loads through ``imageLoad``)."""
        pv = self._edge.get((lum, image))
        if pv is None:
            prog = self.ctx.program(
                vertex_shader=shaders.VERT_QUAD,
                fragment_shader=shaders.source(
                    shaders.FRAG_EDGE_AA, lum=lum, depth=False, image=image
                ),
            )
            prog["u_color"].value = 0
            if image:
                prog["u_image"].value = 0  # image unit 0
            pv = (prog, self.ctx.vertex_array(prog, []))
            self._edge[(lum, image)] = pv
        return pv

    def release(self) -> None:
        """Free every compiled program and its vertex array."""
        for prog, vao in [*self._color.values(), *self._resolve.values(), *self._edge.values()]:
            if vao is not None:
                vao.release()
            prog.release()
