"""The image-formation settings of the rasterizer, the same on every OpenGL
implementation, and the record of them that run.json keeps (:func:`image_formation`)."""

from __future__ import annotations

import os
from typing import Any

from roslan.errors import RenderError
from roslan.render.gl.context import create_context
from roslan.render.gl.upload import SHADOW_MAP_MAX

__all__ = [
    "DEFAULT_SAMPLES",
    "DEFAULT_TEXTURE_TAPS",
    "MAX_ANISO",
    "MAX_SUPERSAMPLING",
    "default_samples",
    "image_formation",
]

DEFAULT_SAMPLES = 1
"""Default MSAA samples per pixel of the colour pass, on every OpenGL implementation
(1: no MSAA, the edge filter instead; chosen against the supersampled reference, see
docs/performance.md). Override with ``ROSLAN_MSAA_SAMPLES`` or ``Renderer(samples=)``."""

MAX_ANISO = 16
"""Most taps of the supersampled reference's anisotropic texture filter
(:attr:`Renderer.max_aniso <roslan.render.gl.Renderer>`); the default image formation
takes :data:`DEFAULT_TEXTURE_TAPS`."""

DEFAULT_TEXTURE_TAPS = 4
"""Taps of the default image formation's texture filter: 2 x 2 bilinear taps over the
pixel's footprint in texture space, in one mip level (fixed in the shader; chosen against
the supersampled reference at llvmpipe's cost of a tap; docs/performance.md, "Image
formation")."""

MAX_SUPERSAMPLING = 8
"""Largest ``supersampling`` factor (N x N samples per pixel) of
:meth:`Renderer.render <roslan.render.gl.Renderer.render>`."""


def default_samples(samples: int | None = None) -> int:
    """MSAA samples to use: ``samples`` if given, else ``$ROSLAN_MSAA_SAMPLES``, else
    :data:`DEFAULT_SAMPLES` (the same on every OpenGL implementation)."""
    if samples is not None:
        return int(samples)
    env = os.environ.get("ROSLAN_MSAA_SAMPLES", "").strip()
    if env:
        try:
            return int(env)
        except ValueError:
            msg = f"ROSLAN_MSAA_SAMPLES = {env!r}: must be an integer number of samples (1, 4)"
            raise RenderError(msg) from None
    return DEFAULT_SAMPLES


def image_formation(samples: int | None = None) -> dict[str, Any]:
    """What run.json records about the images: the OpenGL implementation that renders
    them (``GL_RENDERER``, ``GL_VERSION``, ``GL_VENDOR``) and the anti-aliasing and
    texture filtering settings (the same on every implementation; each camera's
    ``supersampling`` is in the recorded config)."""
    info = create_context().info
    ns = default_samples(samples)
    return {
        "gl_renderer": str(info.get("GL_RENDERER", "")),
        "gl_version": str(info.get("GL_VERSION", "")),
        "gl_vendor": str(info.get("GL_VENDOR", "")),
        "msaa_samples": ns,
        "anti_aliasing": (
            "edge filter on geometric edges (1 sample per pixel)"
            if ns <= 1
            else f"{ns}x MSAA, samples averaged"
        ),
        "texture_filtering": (
            "in the shader on roslan-computed mip-maps (area average in linear light): "
            f"{DEFAULT_TEXTURE_TAPS} bilinear taps at the centres of the pixel footprint's "
            "half-pixel cells, in the mip level of a cell (the supersampled reference: up "
            f"to {MAX_ANISO} trilinear taps along each sample's footprint)"
        ),
        "shadow_map_max": SHADOW_MAP_MAX,
        "supersampling": "per camera (its supersampling key; N > 1: N x N samples per "
        "pixel, box-filtered, no edge filter)",
    }
