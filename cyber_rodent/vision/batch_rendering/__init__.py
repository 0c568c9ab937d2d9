"""All robots' omni strips in a handful of OpenGL calls: a batched drop-in for ``OmniRenderer``.

Why: :class:`~cyber_rodent.vision.rendering.OmniRenderer` renders each of the ``n_robots ×
n_views`` tiles with one ``mujoco.mjr_render``. MuJoCo's renderer is fixed-function OpenGL: for
every geom of the scene it issues its own draw with state changes (colour, material, matrix
push/pop, display list), and it sets up lights and GL state again for every tile. Under Mesa
llvmpipe (software OpenGL) that per-geom, per-tile overhead dominates, not the pixels.
:class:`BatchOmniRenderer` draws the same geoms with the same lighting in a few calls; what is
left is mostly llvmpipe filling the pixels with a depth test, which no batching removes.

The package, one concern a module:

* :mod:`.meshes`: one static vertex buffer, built once from the compiled model: every drawn
  geom's unit mesh (MuJoCo's own built-in shapes) scaled by ``geom_size``, with normals and the
  geom's index per vertex; index lists at three levels of detail over those vertices.
* :mod:`.kernels`: per frame, each view's camera, headlight and draw commands (the runs of
  consecutive geoms in its frustum, minus the observing robot's own geoms and fully transparent
  ones, each at a level of detail from its projected size, :data:`LOD_RADIUS_PX`: outlines move
  by at most ~0.15 px), compiled or in numpy after the renderer's ``backend``.
* :mod:`.shaders`: the two GLSL programs (a transform-feedback pass that moves and lights every
  vertex once per frame; one multi-draw for all views, each clipped to its tile by four
  ``gl_ClipDistance`` planes, which under llvmpipe beats viewport arrays and is not limited to
  ``GL_MAX_VIEWPORTS`` tiles).
* :mod:`.draw`: the per-frame upload buffer, the two passes and the read-back.
* :mod:`.context`: the off-screen GL context and its framebuffer.
* :mod:`.renderer`: :class:`BatchOmniRenderer`, which owns all of the above.

The images match ``OmniRenderer``'s: the same cameras (each robot's ``camera_mount`` site, view
``k`` along :attr:`OmniProjection.view_centres`, up along the site's z axis, the lens-shifted
frustum ``OmniRenderer`` writes into MuJoCo's GL camera), tile layout and orientation (robot
``i`` = strip ``i``, row 0 at the top), and MuJoCo's fixed-function lighting evaluated per vertex
as OpenGL does it: the headlight along each view (ambient + Lambert diffuse) and every active
directional model light (ambient + diffuse), no specular (the lights have none), colours clamped
to [0, 1] per vertex and interpolated (Gouraud), black background (MuJoCo clears to black when
the skybox is off). Over random scenes ~99.98 % of the pixels are within 8 levels of
``OmniRenderer``'s; the differences are single pixels on outlines (rasterisation ties, levels of
detail). Not drawn, as in ``OmniRenderer``: sites, collision-only geoms (groups other than 0–2),
shadows, reflections, textures, fog, anti-aliasing.

Limitations: geoms with 0 < alpha < 1 are drawn opaque (MuJoCo blends them; none in this model);
a finite plane is a quad of its size, an infinite one a quad as wide as the far clip distance;
which lights are active and the headlight's colours are read at construction (light directions
every frame). Supported geom types: plane, sphere, capsule, ellipsoid, cylinder, box; other
types, materials and non-directional lights raise ``ValueError``. Needs OpenGL 4.5 with
``ARB_shader_draw_parameters`` (Mesa's EGL llvmpipe has both).
"""

from __future__ import annotations

from cyber_rodent.vision.batch_rendering.meshes import (
    LEVELS_OF_DETAIL,
    LOD_RADIUS_PX,
    VISIBLE_GROUPS,
    SceneGeometry,
    build_geometry,
    draw_order,
    geom_mesh,
)
from cyber_rodent.vision.batch_rendering.renderer import BatchOmniRenderer

__all__ = [
    "LEVELS_OF_DETAIL",
    "LOD_RADIUS_PX",
    "VISIBLE_GROUPS",
    "BatchOmniRenderer",
    "SceneGeometry",
    "build_geometry",
    "draw_order",
    "geom_mesh",
]
