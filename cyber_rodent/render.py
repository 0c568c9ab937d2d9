"""Off-screen rendering of the field: a top-down view and a per-robot chase view.

Rendering is real OpenGL through ``mujoco.Renderer`` on a headless context (EGL by default, see
``cyber_rodent/__init__.py``). Settings follow what is fast under Mesa's software rasteriser
(docs/design.md §6): no shadows, no reflections, no skybox, no anti-aliasing
(``offsamples=0`` in the arena), untextured surfaces. Sites, rangefinder rays and the wheels'
collision spheres are hidden.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.atomic import atomic_output
from cyber_rodent.world import World

#: Geom group of collision-only helper geoms (the wheels' contact spheres): hidden in images.
COLLISION_ONLY_GROUP = 3
MAX_IMAGE_SIDE = 4096


def fast_scene_option() -> mujoco.MjvOption:
    """Visual options for clean, fast images: no sites, rays or collision-only geoms."""
    opt = mujoco.MjvOption()
    opt.sitegroup[:] = 0
    opt.geomgroup[COLLISION_ONLY_GROUP] = 0
    opt.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = 0
    return opt


def disable_slow_effects(scene: mujoco.MjvScene) -> None:
    """Turn off the rendering effects that cost the most in software GL."""
    scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
    scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
    scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = 0


def check_image_size(width: int, height: int) -> None:
    """Raise a clear error for sizes a renderer cannot or should not allocate."""
    for name, value in (("width", width), ("height", height)):
        if not isinstance(value, int) or not 1 <= value <= MAX_IMAGE_SIDE:
            raise ValueError(
                f"image {name} must be an integer in [1, {MAX_IMAGE_SIDE}] px, got {value!r}"
            )


class FieldRenderer:
    """Renders a :class:`World` off-screen.

    Args:
        world: the world to draw (its current ``MjData`` state).
        width: image width in pixels.
        height: image height in pixels.
    """

    def __init__(self, world: World, width: int = 640, height: int = 640):
        check_image_size(width, height)
        self.world = world
        model = world.model
        # The offscreen buffer must hold the image; grow it on this model if asked for more.
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        self._renderer = mujoco.Renderer(model, height=height, width=width)
        disable_slow_effects(self._renderer.scene)
        self._option = fast_scene_option()
        self._chase = np.array(
            [
                mujoco.mj_name2id(
                    model, mujoco.mjtObj.mjOBJ_CAMERA, C.robot_prefix(i) + C.CHASE_CAMERA
                )
                for i in range(world.config.n_robots)
            ]
        )

    def top_down(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the whole field from above."""
        return self._render(self.world.top_camera)

    def robot_view(self, robot: int) -> np.ndarray:
        """(H, W, 3) uint8 image from behind and above robot ``robot``."""
        if not 0 <= robot < len(self._chase):
            raise ValueError(f"robot must be in [0, {len(self._chase) - 1}], got {robot}")
        return self._render(int(self._chase[robot]))

    def _render(self, camera: int) -> np.ndarray:
        self._renderer.update_scene(self.world.data, camera=camera, scene_option=self._option)
        disable_slow_effects(self._renderer.scene)
        image: np.ndarray = self._renderer.render()
        return image

    def project_top_down(self, xyz: np.ndarray) -> np.ndarray:
        """Pixel (col, row) of world points in the top-down image (pinhole projection).

        Used to annotate images and to check them: the camera looks straight down with image
        right = world +x and image up = world +y.
        """
        m = self.world.model
        cam = self.world.top_camera
        height, width = self._renderer.height, self._renderer.width
        fovy = math.radians(float(m.cam_fovy[cam]))
        focal = (height / 2) / math.tan(fovy / 2)
        cam_pos = m.cam_pos[cam]
        xyz = np.atleast_2d(xyz)
        depth = cam_pos[2] - xyz[:, 2]
        col = width / 2 + (xyz[:, 0] - cam_pos[0]) * focal / depth
        row = height / 2 - (xyz[:, 1] - cam_pos[1]) * focal / depth
        return np.column_stack([col, row])

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> FieldRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_writable_output(path: str | os.PathLike[str]) -> Path:
    """Resolve an output file path and fail early, clearly, if it cannot be written.

    Raises:
        ValueError: if the parent directory is missing, not a directory, or not writable, or
            the path is an existing directory.
    """
    out = Path(path).expanduser().resolve()
    if out.is_dir():
        raise ValueError(f"--out {path!s} is a directory; give a file name such as field.png")
    parent = out.parent
    if not parent.is_dir():
        raise ValueError(f"--out {path!s}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"--out {path!s}: directory {parent} is not writable")
    if out.exists() and not os.access(out, os.W_OK):
        raise ValueError(f"--out {path!s}: file exists and is not writable")
    return out


def write_png(image: np.ndarray, path: str | os.PathLike[str]) -> Path:
    """Write an RGB image as PNG atomically (see :func:`cyber_rodent.atomic.atomic_output`)."""
    import imageio.v3 as iio

    out = check_writable_output(path)
    with atomic_output(out) as temp:
        iio.imwrite(temp, image, extension=".png")
    return out
