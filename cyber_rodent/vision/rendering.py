"""Off-screen rendering of every robot's 360° omni strip into one OpenGL buffer.

One call of :meth:`OmniRenderer.render` updates the MuJoCo scene once, then renders
``n_robots × n_views`` pinhole views as tiles of a single off-screen framebuffer (one
``mjr_render`` per tile, each with its own viewport and camera) and reads all pixels back with a
single ``mjr_readPixels``. Tiling into one buffer avoids a scene update and a pixel read-back
per camera (``docs/design.md`` §6). Robot ``i``'s strip is rows
``i*height … (i+1)*height`` of the buffer, views left to right as in
:class:`~cyber_rodent.vision.projection.OmniProjection`.

What each robot's camera does not see:

* its own body: before robot ``i``'s tiles are drawn, the scene geoms that belong to robot ``i``
  (``World.geom_robot``) are moved far out of every frustum, and put back afterwards;
* sites and rangefinder rays (``mjvOption``); collision-only geoms (group 3, MuJoCo's default
  geom groups);
* shadows, reflections, skybox, fog and haze are off, and the GL context is built with a coarse
  tessellation (:data:`TESSELLATION`): under Mesa llvmpipe the per-tile cost is dominated by
  vertex work, and MuJoCo's default 28 × 16 slices/stacks made a frame several times dearer,
  with no visible change of the coloured silhouettes at these resolutions.

The model's headlight follows each view (pointing along its axis), as it does in any MuJoCo
camera render, so a target facing the camera is lit the same way in every tile.

The views are not MJCF cameras: each is built from the ``camera_mount`` site's pose, with the
shifted frustum of :class:`OmniProjection` written into the scene's GL camera (MJCF cameras
only describe symmetric or intrinsic frusta). The four ``omni_*`` cameras in the robot's MJCF
show the same four directions for viewers and debugging.

Headless: the GL backend follows ``MUJOCO_GL`` (``egl`` by default, set by
:mod:`cyber_rodent`).
"""

from __future__ import annotations

import atexit
import os
import weakref
from typing import Any

import mujoco
import numpy as np

from cyber_rodent.vision.config import MAX_BUFFER_PIXELS, CameraConfig
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.world import World

#: Largest side of the shared off-screen buffer we ask OpenGL for (Mesa's limit is 16384).
MAX_BUFFER_SIDE = 16384
_HIDE_OFFSET = 1.0e4  # m, where a robot's own geoms go while its camera renders
#: m, the far clip distance of every omni view: beyond the field's diagonal from anywhere.
FAR_CLIP = 20.0
#: (numslices, numstacks, numquads) of the built-in meshes in the vision GL context.
TESSELLATION = (16, 4, 1)


def strips_buffer_size(config: CameraConfig, n_robots: int) -> tuple[int, int]:
    """(width, height) of the off-screen buffer holding every robot's strip, one per row band.

    Raises:
        ValueError: if the strips do not fit one off-screen buffer.
    """
    width, height = config.strip_width, n_robots * config.height
    if height > MAX_BUFFER_SIDE or width > MAX_BUFFER_SIDE or height * width > MAX_BUFFER_PIXELS:
        raise ValueError(
            f"height={config.height} px × {n_robots} robots = {height} rows (and {width} "
            f"columns) exceed the off-screen buffer (at most {MAX_BUFFER_SIDE} pixels a side, "
            f"{MAX_BUFFER_PIXELS} in all); lower the camera resolution"
        )
    return width, height


#: Renderers whose GL context is still open (see :func:`close_at_exit`).
_OPEN_RENDERERS: weakref.WeakSet[Any] = weakref.WeakSet()


def close_at_exit(renderer: Any) -> None:
    """Close ``renderer`` (its ``close()``) at interpreter exit if it is still open.

    MuJoCo's EGL module terminates its display in an ``atexit`` hook registered with the
    process's first context; a context still alive after it is freed by the garbage collector
    on a terminated display, which prints ``EGL_NOT_INITIALIZED`` tracebacks. ``atexit`` runs
    the last-registered hook first, so the hook that closes the open renderers is registered
    again after every new context: it always runs before EGL's teardown.
    """
    _OPEN_RENDERERS.add(renderer)
    atexit.unregister(_close_open_renderers)
    atexit.register(_close_open_renderers)


def _close_open_renderers() -> None:
    for renderer in list(_OPEN_RENDERERS):
        renderer.close()


def gl_context(width: int, height: int) -> Any:
    """An off-screen GL context (MuJoCo's ``GLContext``) of the backend named by ``MUJOCO_GL``."""
    backend = os.environ.get("MUJOCO_GL", "egl").lower()
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco import GLContext
    return GLContext(width, height)


class OmniRenderer:
    """Renders all robots' omni strips of a world in one buffer.

    Args:
        world: the world (its model and data are read at every :meth:`render`).
        config: the camera.

    Raises:
        ValueError: if all strips together do not fit one off-screen buffer.
    """

    def __init__(self, world: World, config: CameraConfig):
        self.world = world
        self.config = config
        self.projection = OmniProjection(config)
        n = world.config.n_robots
        self.n_robots = n
        self.width, self.buffer_height = strips_buffer_size(config, n)
        m = world.model
        # The off-screen buffer's size is read from the model when the context is made.
        m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), self.width)
        m.vis.global_.offheight = max(int(m.vis.global_.offheight), self.buffer_height)
        self._gl = gl_context(self.width, self.buffer_height)
        self._gl.make_current()
        # The built-in meshes are tessellated when the context is made; coarsen them for this
        # context only and restore the model's setting for other renderers (videos).
        q = m.vis.quality
        saved = (int(q.numslices), int(q.numstacks), int(q.numquads))
        q.numslices, q.numstacks, q.numquads = TESSELLATION
        try:
            self._con = mujoco.MjrContext(m, mujoco.mjtFontScale.mjFONTSCALE_100)
        finally:
            q.numslices, q.numstacks, q.numquads = saved
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        self._scene = mujoco.MjvScene(m, maxgeom=m.ngeom + 16)
        for flag in (
            mujoco.mjtRndFlag.mjRND_SHADOW,
            mujoco.mjtRndFlag.mjRND_REFLECTION,
            mujoco.mjtRndFlag.mjRND_SKYBOX,
            mujoco.mjtRndFlag.mjRND_FOG,
            mujoco.mjtRndFlag.mjRND_HAZE,
        ):
            self._scene.flags[flag] = 0
        self._opt = mujoco.MjvOption()
        self._opt.sitegroup[:] = 0
        self._opt.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = 0
        self._free_cam = mujoco.MjvCamera()
        self._scene_geoms = self._scene.geoms  # wrappers over the scene's fixed geom array
        # Tiles: robot i, view k. OpenGL's origin is the bottom-left corner.
        h, w = config.height, config.view_width
        self._viewports = [
            [mujoco.MjrRect(k * w, (n - 1 - i) * h, w, h) for k in range(config.n_views)]
            for i in range(n)
        ]
        self._full = mujoco.MjrRect(0, 0, self.width, self.buffer_height)
        centres = self.projection.view_centres
        self._view_dirs = np.stack(
            [np.cos(centres), np.sin(centres), np.zeros_like(centres)], axis=1
        )  # (n_views, 3), robot frame
        near = config.near_clip
        self._frustum = (
            near,
            FAR_CLIP,
            self.projection.half_tan * near,
            self.projection.v_bottom * near,
            self.projection.v_top * near,
        )
        self._pixels = np.empty((self.buffer_height, self.width, 3), dtype=np.uint8)
        self._cam_site = np.asarray(world.camera_site, dtype=np.int64)
        self._closed = False
        close_at_exit(self)

    def render(self) -> np.ndarray:
        """Render all strips; returns a (n_robots, height, strip_width, 3) uint8 RGB view.

        The returned array is overwritten by the next call; copy it to keep it.
        """
        if self._closed:
            raise RuntimeError("this OmniRenderer is closed")
        m, d = self.world.model, self.world.data
        scn = self._scene
        self._gl.make_current()
        mujoco.mjv_updateScene(
            m, d, self._opt, None, self._free_cam, mujoco.mjtCatBit.mjCAT_ALL, scn
        )
        own = self._own_scene_geoms()
        cam_pos = d.site_xpos[self._cam_site]
        cam_rot = d.site_xmat[self._cam_site].reshape(-1, 3, 3)
        near, far, half_w, bottom, top = self._frustum
        glcams = (scn.camera[0], scn.camera[1])
        headlights = [scn.lights[j] for j in range(scn.nlight) if scn.lights[j].headlight]
        for i in range(self.n_robots):
            hidden = [self._scene_geoms[j] for j in own[i]]
            for g in hidden:
                g.pos[2] += _HIDE_OFFSET
            up = cam_rot[i][:, 2]
            forwards = self._view_dirs @ cam_rot[i].T
            for k, viewport in enumerate(self._viewports[i]):
                for c in glcams:
                    c.pos[:] = cam_pos[i]
                    c.forward[:] = forwards[k]
                    c.up[:] = up
                    c.frustum_near = near
                    c.frustum_far = far
                    c.frustum_center = 0.0
                    c.frustum_width = half_w
                    c.frustum_bottom = bottom
                    c.frustum_top = top
                    c.orthographic = 0
                for light in headlights:
                    light.pos[:] = cam_pos[i]
                    light.dir[:] = forwards[k]
                mujoco.mjr_render(viewport, scn, self._con)
            for g in hidden:
                g.pos[2] -= _HIDE_OFFSET
        mujoco.mjr_readPixels(self._pixels, None, self._full, self._con)
        return self._pixels[::-1].reshape(self.n_robots, self.config.height, self.width, 3)

    def _own_scene_geoms(self) -> list[list[int]]:
        """Per robot, the indices of the scene geoms that belong to it."""
        geom_robot = self.world.geom_robot
        own: list[list[int]] = [[] for _ in range(self.n_robots)]
        geom_type = mujoco.mjtObj.mjOBJ_GEOM
        for j in range(self._scene.ngeom):
            g = self._scene_geoms[j]
            if g.objtype == geom_type:
                r = geom_robot[g.objid]
                if r >= 0:
                    own[r].append(j)
        return own

    def close(self) -> None:
        """Free the GL context (idempotent)."""
        if not self._closed:
            self._closed = True
            self._con.free()
            self._gl.free()

    def __enter__(self) -> OmniRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
