""":class:`BatchOmniRenderer`: the model's meshes, the views' cameras, the kernel and the draw.

The renderer owns the data: it builds the static meshes (:mod:`.meshes`), the views' constant
geometry and the kernel's named buffers (:mod:`.kernels`), the per-frame upload buffer and the
GL pipeline (:mod:`.draw`) in its own off-screen context (:mod:`.context`). A frame copies the
geoms' poses and colours and the light directions into the upload buffer, runs the views kernel
(cameras, headlights, draw commands) and draws.
"""

from __future__ import annotations

import numpy as np

from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.vision.batch_rendering import kernels
from cyber_rodent.vision.batch_rendering.context import OffscreenContext
from cyber_rodent.vision.batch_rendering.draw import DrawPipeline, FrameData
from cyber_rodent.vision.batch_rendering.meshes import LOD_RADIUS_PX, build_geometry
from cyber_rodent.vision.batch_rendering.shaders import directional_lights, transform_source
from cyber_rodent.vision.config import CameraConfig
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.vision.rendering import FAR_CLIP, close_at_exit, strips_buffer_size
from cyber_rodent.world import World


def _frustum(
    left: float, right: float, bottom: float, top: float, near: float, far: float
) -> np.ndarray:
    """OpenGL's ``glFrustum`` matrix (row-major)."""
    return np.array(
        [
            [2 * near / (right - left), 0, (right + left) / (right - left), 0],
            [0, 2 * near / (top - bottom), (top + bottom) / (top - bottom), 0],
            [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0, 0, -1, 0],
        ]
    )


class BatchOmniRenderer:
    """Renders all robots' omni strips of a world in one buffer with a few OpenGL calls.

    A drop-in replacement for :class:`~cyber_rodent.vision.rendering.OmniRenderer`: same
    arguments, output, tile layout and errors.

    Args:
        world: the world (its model and data are read at every :meth:`render`).
        config: the camera.
        backend: ``"numba"`` (the compiled views kernel) or ``"numpy"`` (its reference).

    Attributes:
        geometry: the static meshes of the drawn geoms.
        state, view_geometry, view_outputs: the views kernel's named buffers
            (:mod:`cyber_rodent.vision.batch_rendering.kernels`); ``view_outputs`` are views
            of the upload buffer, filled by every :meth:`render`.

    Raises:
        ValueError: if all strips together do not fit one off-screen buffer, the model has
            geoms or lights this renderer cannot draw, or ``backend`` is unknown.
    """

    def __init__(self, world: World, config: CameraConfig, backend: Backend = DEFAULT_BACKEND):
        self.backend = check_backend(backend)
        self.world = world
        self.config = config
        self.projection = OmniProjection(config)
        n = world.config.n_robots
        self.n_robots = n
        self.width, self.buffer_height = strips_buffer_size(config, n)
        m, d = world.model, world.data
        self._closed = True
        self._lights = directional_lights(m)
        self.geometry = build_geometry(m)
        n_k = config.n_views
        self.n_views = n * n_k
        self.frame = FrameData(len(self._lights), m.ngeom, n, n_k, len(self.geometry.geoms))
        self.state = kernels.SceneState(d.site_xpos, d.site_xmat, d.geom_xpos, m.geom_rgba)
        self.view_geometry = self._view_geometry()
        self.view_outputs = kernels.ViewOutputs(
            self.frame.clip_t, self.frame.head, self.frame.commands
        )
        # Binding compiles (or loads) the compiled kernel now, not in the first frame.
        self._frame_views = bind(
            pick(self.backend, kernels.frame_views, kernels.frame_views_reference),
            self.state, self.view_geometry, self.view_outputs,
        )  # fmt: skip
        self._pixels = np.empty((self.buffer_height, self.width, 3), dtype=np.uint8)
        self._strips = self._pixels.reshape(n, config.height, self.width, 3)
        self._context = OffscreenContext(self.width, self.buffer_height)
        self._closed = False
        close_at_exit(self)
        try:
            self._pipeline = DrawPipeline(
                self.geometry,
                transform_source(m, self._lights),
                self.frame,
                self.width,
                self.buffer_height,
            )
        except Exception:
            self.close()
            raise

    def _view_geometry(self) -> kernels.ViewGeometry:
        """The views' constants: cameras in the camera site's frame, culling, levels of detail."""
        n, n_k = self.n_robots, self.config.n_views
        m, drawn = self.world.model, self.geometry.geoms
        centres = self.projection.view_centres
        fwd = np.stack([np.cos(centres), np.sin(centres), np.zeros_like(centres)], axis=1)
        up = np.array([0.0, 0.0, 1.0])
        # Eye frame from the camera site's frame, rows right, up, backwards (mjr_lookAt).
        eye = np.zeros((n_k, 4, 4))
        eye[:, 0, :3] = np.cross(fwd, up)
        eye[:, 1, :3] = up
        eye[:, 2, :3] = -fwd
        eye[:, 3, 3] = 1.0
        near = self.config.near_clip
        half_w = self.projection.half_tan * near
        proj = _frustum(
            -half_w,
            half_w,
            self.projection.v_bottom * near,
            self.projection.v_top * near,
            near,
            FAR_CLIP,
        )
        proj[1] *= -1.0  # image row 0 at the tile's lowest GL row: read back top row first
        site_clip_t = np.ascontiguousarray((proj @ eye).transpose(0, 2, 1))  # transposed
        # Culling: each view's frustum planes in the camera site's frame (w ± x, w ± y, w ± z
        # of its clip matrix, unit normals), the drawn geoms' owners and bounding radii (MuJoCo
        # gives infinite planes 0: always drawn).
        site_clip = site_clip_t.transpose(0, 2, 1)
        planes = np.concatenate(
            [site_clip[:, 3:] + site_clip[:, :3], site_clip[:, 3:] - site_clip[:, :3]], axis=1
        )
        rbound = m.geom_rbound[drawn].copy()
        rbound[rbound <= 0.0] = np.inf
        owner = np.asarray(self.world.geom_robot, dtype=np.int64)[drawn]
        # Level of detail from the depth of a geom's nearest point: level >= l beyond the
        # depth at which its projected radius is LOD_RADIUS_PX[l - 1].
        px_u = self.projection.px_per_u
        px_any = max(px_u, self.projection.px_per_v)
        return kernels.ViewGeometry(
            camera_site=np.asarray(self.world.camera_site, dtype=np.int64),
            drawn=drawn,
            site_clip_t=site_clip_t,
            site_planes=planes / np.linalg.norm(planes[:, :, :3], axis=2, keepdims=True),
            view_back=np.ascontiguousarray(-fwd),
            rbound=rbound,
            lod_depth=np.stack(
                [rbound * px_u / LOD_RADIUS_PX[0], rbound * px_any / LOD_RADIUS_PX[1]]
            ),
            same_at_all_levels=self.geometry.same_at_all_levels,
            near=float(near),
            own=owner[None, :] == np.repeat(np.arange(n), n_k)[:, None],  # (n * n_k, n_drawn)
            index_start=self.geometry.index_start,
        )

    def _update_frame(self) -> int:
        """Write this frame's data into the upload buffer; returns the number of commands."""
        m, d, frame = self.world.model, self.world.data, self.frame
        np.copyto(frame.geom_pos, d.geom_xpos, casting="same_kind")
        np.copyto(frame.geom_mat, d.geom_xmat.reshape(-1, 3, 3), casting="same_kind")
        np.copyto(frame.geom_rgba, m.geom_rgba, casting="same_kind")
        if self._lights:
            np.negative(d.light_xdir[self._lights], out=frame.light_dir, casting="same_kind")
        return int(self._frame_views())

    def render(self) -> np.ndarray:
        """Render all strips; returns a (n_robots, height, strip_width, 3) uint8 RGB view.

        The returned array is overwritten by the next call; copy it to keep it.
        """
        if self._closed:
            raise RuntimeError("this BatchOmniRenderer is closed")
        n_commands = self._update_frame()
        self._context.make_current()
        self._pipeline.draw(n_commands, self._pixels)
        return self._strips

    def close(self) -> None:
        """Free the GL context (idempotent)."""
        if not self._closed:
            self._closed = True
            self._context.free()

    def __enter__(self) -> BatchOmniRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

