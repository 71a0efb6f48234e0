"""Render targets: the framebuffers of one (size, samples, outputs) combination, and
the check of a caller's readback buffer."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError

__all__ = ["Targets", "out_array"]


class Targets:
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


def out_array(out: NDArray[np.float32] | None, shape: tuple[int, ...]) -> NDArray[np.float32]:
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
