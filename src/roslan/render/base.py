"""What the sensors use of the render layer: :class:`FrameRenderer` (the OpenGL
rasterizer, :class:`roslan.render.gl.Renderer`), :class:`BeamCaster` (the Embree ray
caster, :class:`roslan.render.raycast.RayCaster`) and :class:`RenderResult`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from roslan.render.raycast import Hits

__all__ = ["BeamCaster", "FrameRenderer", "RenderResult"]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]


@dataclass(frozen=True)
class RenderResult:
    """One rendered view: the one render product of every camera kind (each camera
    remaps it through its lens with :func:`roslan.sensors.cameras.remap.remap_result`:
    radiance and flow bilinear, depth and ids nearest).

    Attributes:
        color: (H, W, 3) float32 linear radiance in [0, 1], or None if not requested.
        depth: (H, W) float32 metric z-depth along the optical axis (m), ``inf`` where
            nothing is hit, or None if not requested.
        luminance: (H, W) float32 Rec. 709 luminance of the linear radiance in [0, 1]
            (``0.2126 R + 0.7152 G + 0.0722 B``), or None if not requested.
        flow: (H, W, 2) float32 image motion (px/s), or None (no renderer computes it
            yet: the cameras derive it from ``depth`` and their twist).
        ids: (H, W) uint32: 1 + the index in :attr:`Scene.triangles
            <roslan.scene.model.Scene.triangles>` of the triangle each pixel centre sees
            (0: nothing), or None if not requested; a camera maps it to instance and class
            ids (:func:`roslan.sensors.cameras.labels.label_images`) before its lens remap.
    """

    color: F32 | None
    depth: F32 | None
    luminance: F32 | None = None
    flow: F32 | None = None
    ids: NDArray[np.uint32] | None = None


class FrameRenderer(Protocol):
    """A rasterizer of one scene, as the camera sensors use it."""

    @property
    def max_size(self) -> int:
        """Largest image width/height the driver supports (pixels)."""
        ...

    def check_size(self, width: int, height: int) -> None:
        """Raise RenderError if ``width`` x ``height`` cannot be rendered."""
        ...

    def render(
        self,
        T_world_cam: F64,
        K: F64,
        width: int,
        height: int,
        *,
        color: bool = True,
        depth: bool = True,
        luminance: bool = False,
        samples: int | None = None,
        out: F32 | None = None,
        near: float | None = None,
        supersampling: int = 1,
        t: float | None = None,
        ids: bool = False,
    ) -> RenderResult:
        """Render the view of a pinhole camera (pose of the OPTICAL frame, OpenCV ``K``)
        of the scene at trajectory time ``t`` (s; None: t = 0); ``ids``: also the scene
        triangle at each pixel centre (:attr:`RenderResult.ids`)."""
        ...


class BeamCaster(Protocol):
    """A ray caster of one scene, as the beam sensors (LiDARs, laser, range) use it."""

    def cast(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        max_range: float | ArrayLike = ...,
        *,
        t: float | ArrayLike | None = None,
    ) -> Hits:
        """First hit of each of N rays, against the scene at the rays' trajectory time
        ``t`` (s, scalar or (N,); None: t = 0)."""
        ...

    def cast_incidence(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        max_range: float | ArrayLike = ...,
        *,
        t: float | ArrayLike | None = None,
    ) -> tuple[F32, F32]:
        """Distance (N,) and ``reflectivity * cos(incidence)`` (N,) of each of N rays."""
        ...
