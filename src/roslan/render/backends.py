"""The back ends of one scene, bundled: what a run or an environment owns and releases.

:class:`SceneBackends` holds, for one :class:`~roslan.scene.model.Scene`, its OpenGL
rasterizer (:class:`~roslan.render.gl.Renderer`, made on first use) and its Embree ray
caster (:class:`~roslan.render.raycast.RayCaster`, the BVH built on first use). The
sensors render and cast through it (their context hands it out), and so do the path's
clearance check before the run (:func:`roslan.scene.clearance.check_clearance`) and the
closed loop's contact and collision checks (:mod:`roslan.env.contact`): collision, beams
and images all see the same triangles through the same caster, in robust mode.

The bundle belongs to whoever made it (a ``simulate`` run, a worker process, an
environment's episode); :meth:`SceneBackends.release` (or dropping the bundle and the
scene) lets both go. Nothing global holds a scene: the per-process lookups behind it
(:func:`~roslan.render.gl.get_renderer`, :func:`~roslan.render.raycast.get_raycaster`)
are weak, so two bundles of one scene in one process share its BVH and GL buffers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from roslan.render.base import BeamCaster, FrameRenderer
    from roslan.scene.model import Scene

__all__ = ["SceneBackends"]


class SceneBackends:
    """The renderer and the ray caster of one scene (module docstring)."""

    def __init__(self, scene: Scene) -> None:
        self.scene: Scene | None = scene
        self._renderer: FrameRenderer | None = None
        self._caster: BeamCaster | None = None

    def _scene(self) -> Scene:
        if self.scene is None:
            msg = "these scene back ends were released"
            raise RuntimeError(msg)
        return self.scene

    def renderer(self) -> FrameRenderer:
        """The scene's OpenGL rasterizer (created, the scene uploaded, on first use)."""
        if self._renderer is None:
            from roslan.render.gl import get_renderer

            self._renderer = get_renderer(self._scene())
        return self._renderer

    def caster(self) -> BeamCaster:
        """The scene's Embree ray caster (robust mode; the BVH built on first use)."""
        if self._caster is None:
            from roslan.render.raycast import get_raycaster

            self._caster = get_raycaster(self._scene())
        return self._caster

    def release(self) -> None:
        """Let the scene, its renderer and its caster go (idempotent): nothing of this
        bundle keeps them alive any more."""
        self.scene = None
        self._renderer = None
        self._caster = None
