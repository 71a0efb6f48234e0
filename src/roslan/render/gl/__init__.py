"""Headless OpenGL rasterizer (package; split by concern in the next commit)."""

from roslan.render.gl.renderer import (
    EGL_PACKAGES,
    LUMA,
    MSAA_SAMPLES,
    SOFTWARE_MSAA_SAMPLES,
    Renderer,
    RenderResult,
    create_context,
    default_samples,
    get_renderer,
    projection_from_K,
)

__all__ = [
    "EGL_PACKAGES",
    "LUMA",
    "MSAA_SAMPLES",
    "SOFTWARE_MSAA_SAMPLES",
    "RenderResult",
    "Renderer",
    "create_context",
    "default_samples",
    "get_renderer",
    "projection_from_K",
]
