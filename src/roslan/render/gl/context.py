"""The process-wide headless OpenGL context (moderngl on EGL) and the few GL entry
points moderngl does not wrap, called through ctypes."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from roslan.errors import RenderError

__all__ = [
    "EGL_PACKAGES",
    "GL_COLOR",
    "GL_DEPTH",
    "create_context",
    "gl_clear_buffer",
    "gl_flush",
    "gl_mat",
]

EGL_PACKAGES = "libegl1, libegl-mesa0, libgl1-mesa-dri"
"""Debian packages that provide headless OpenGL through EGL (Mesa llvmpipe)."""

GL_COLOR = 0x1800
"""``GL_COLOR``: the ``buffer`` argument of ``glClearBufferfv`` for a colour attachment."""
GL_DEPTH = 0x1801
"""``GL_DEPTH``: the ``buffer`` argument of ``glClearBufferfv`` for the depth buffer."""

_context: Any = None
_context_pid = 0
_context_lock = threading.Lock()


def create_context() -> Any:
    """The process-wide headless moderngl context (created on first call).

    Raises:
        RenderError: no EGL/OpenGL 3.3+ available (names the Debian packages to install);
            or this process was forked from one that had a context (EGL does not survive
            a fork, and a new context would hang: start such processes with ``spawn``).
    """
    global _context, _context_pid
    with _context_lock:
        if _context is not None and _context_pid != os.getpid():
            msg = (
                "this process was forked from one that had an OpenGL context, which does not "
                "survive a fork; start rendering processes with the 'spawn' method (e.g. "
                "gymnasium.make_vec(..., vector_kwargs={'context': 'spawn'}), roslan.env's "
                "default)"
            )
            raise RenderError(msg)
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
        _context, _context_pid = ctx, os.getpid()
        return ctx


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


def gl_flush() -> Callable[[], None] | None:
    """``glFlush`` (moderngl has none), or None."""
    fn: Callable[[], None] | None = _gl_proc(b"glFlush")
    return fn


def gl_clear_buffer() -> Callable[[int, int, Any], None] | None:
    """``glClearBufferfv(buffer, drawbuffer, value)`` (one attachment of the bound
    framebuffer; moderngl clears all colour attachments with one colour), or None."""
    fn: Callable[[int, int, Any], None] | None = _gl_proc(
        b"glClearBufferfv", ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_float)
    )
    return fn


def gl_mat(M: NDArray[np.float64]) -> bytes:
    """Column-major float32 bytes of a 4x4 matrix (GLSL's layout)."""
    return np.ascontiguousarray(np.asarray(M, dtype=np.float32).T).tobytes()
