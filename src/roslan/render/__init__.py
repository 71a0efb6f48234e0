"""Render layer: what the sensors see of the scene.

:mod:`roslan.render.gl` rasterizes camera images (headless OpenGL), :mod:`roslan.render.raycast`
casts the beams of the range sensors (Embree), both over the same triangles. The sensors
depend only on the protocols of :mod:`roslan.render.base`.
"""

from roslan.render.base import BeamCaster, FrameRenderer, RenderResult
from roslan.render.color import REC709_LUMA

__all__ = ["REC709_LUMA", "BeamCaster", "FrameRenderer", "RenderResult"]
