"""All robots' omni strips in a handful of OpenGL calls: a batched drop-in for ``OmniRenderer``.

Why: :class:`~cyber_rodent.vision.rendering.OmniRenderer` renders each of the ``n_robots ×
n_views`` tiles with one ``mujoco.mjr_render``. MuJoCo's renderer is fixed-function OpenGL: for
every geom of the scene it issues its own draw with state changes (colour, material, matrix
push/pop, display list), and it sets up lights and GL state again for every tile. Under Mesa
llvmpipe (software OpenGL) that per-geom, per-tile overhead dominates, not the pixels: ~0.5–1.2
ms a tile, ~12.5 ms for the 16 tiles of four robots. :class:`BatchOmniRenderer` draws the same
geoms with the same lighting in a few calls: ~2.5–2.7 ms a frame on the same machine (2 cores,
``LP_NUM_THREADS=1``). About half of that is llvmpipe filling the 4 × 192 × 512 pixels with a
depth test, which no batching removes: one full-screen quad per tile alone costs ~1.1 ms
including clear and read-back.

1. One static vertex buffer, built once from the compiled model: every drawn geom's unit mesh
   (MuJoCo's own built-in shapes at the vision context's coarse
   :data:`~cyber_rodent.vision.rendering.TESSELLATION`) scaled by ``geom_size``, with normals
   and the geom's index per vertex; index lists at three levels of detail over those vertices.
2. Per frame, one buffer upload: ``geom_xpos``, ``geom_xmat``, ``geom_rgba`` (the LED's colour
   changes at run time) and the light directions, plus per view a clip matrix and the draw
   commands (below).
3. A transform-feedback pass (one draw, no rasterisation) moves every vertex to the world frame
   and lights it with the view-independent terms, once per frame rather than once per view
   (per-view vertex work was the largest cost of a one-pass design).
4. One ``glMultiDrawElementsIndirect`` draws all views. Its commands come from a small compiled
   kernel (numba; numpy without it): per view, the runs of consecutive geoms whose bounding
   sphere meets the view's frustum, minus the observing robot's own geoms (a robot never sees
   itself) and fully transparent ones, each at a level of detail chosen from its projected size
   (:data:`LOD_RADIUS_PX`: outlines move by at most ~0.15 px). A command's ``baseInstance`` is
   its view: the vertex shader applies that view's camera and headlight and moves the result
   into the view's tile of the framebuffer, clipped to the tile by four ``gl_ClipDistance``
   planes (faster under llvmpipe than viewport arrays selected by ``gl_ViewportIndex``, and not
   limited to ``GL_MAX_VIEWPORTS`` tiles).
5. One ``glReadPixels`` (RGBA, llvmpipe's fast path) and an OpenCV RGBA → RGB conversion into
   the preallocated output. The per-frame GL calls go through plain ctypes entry points.

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

Row order: each view's projection is flipped vertically, so OpenGL's bottom-up rows come back
from ``glReadPixels`` top row first and the output needs no flip (the flip mirrors triangles'
winding, hence ``glFrontFace(GL_CW)``).
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass

import cv2
import mujoco
import numpy as np
from OpenGL import GL
from OpenGL.GL import shaders
from OpenGL.platform import PLATFORM

from cyber_rodent import compiled
from cyber_rodent.compiled import jit as _jit
from cyber_rodent.vision.config import CameraConfig
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.vision.rendering import (
    _FAR_CLIP,
    TESSELLATION,
    _gl_context,
    strips_buffer_size,
)
from cyber_rodent.world import World

#: Geom groups MuJoCo draws by default (``mjvOption.geomgroup``); group 3 is collision-only.
VISIBLE_GROUPS = (0, 1, 2)

_GEOM_VEC4 = 5  # per geom in the frame buffer: pos, xmat rows 0-2, rgba
_VIEW_VEC4 = 6  # per view: clip matrix (4 columns), direction to the headlight, tile transform
_TF_VEC4 = 4  # per transformed vertex: world position, world normal, lit colour, headlight colour
_COMMAND_UINTS = 5  # DrawElementsIndirectCommand

# Pass 1 (transform feedback, once per frame): geom frame -> world, view-independent lighting.
_TRANSFORM_SHADER = """
#version 450
layout(location = 0) in vec4 a_pos;     // xyz: geom frame, scaled; w: geom index
layout(location = 1) in vec3 a_normal;  // geom frame
layout(std430, binding = 0) readonly buffer Geoms {
    vec4 lights[N_LIGHT_SLOTS];  // unit vectors towards the directional lights
    vec4 geoms[];                // per geom: pos, xmat rows 0-2, rgba
};
out vec4 t_pos;
out vec4 t_normal;
out vec4 t_lit;   // rgb * (ambient + directional lights)
out vec4 t_head;  // rgb * headlight diffuse
void main() {
    int g = 5 * int(a_pos.w);
    vec3 r0 = geoms[g + 1].xyz;
    vec3 r1 = geoms[g + 2].xyz;
    vec3 r2 = geoms[g + 3].xyz;
    vec3 rgb = geoms[g + 4].rgb;
    vec3 p = a_pos.xyz;
    vec3 n = vec3(dot(r0, a_normal), dot(r1, a_normal), dot(r2, a_normal));
    t_pos = vec4(geoms[g].xyz + vec3(dot(r0, p), dot(r1, p), dot(r2, p)), 1.0);
    t_normal = vec4(n, 0.0);
    t_lit = vec4(rgb * (AMBIENT LIGHT_TERMS), 0.0);
    t_head = vec4(rgb * HEAD_DIFFUSE, 0.0);
}
"""

# Pass 2 (all views, one multi-draw): camera, headlight, tile.
_VIEW_SHADER = """
#version 450
#extension GL_ARB_shader_draw_parameters : require
layout(location = 0) in vec4 a_pos;
layout(location = 1) in vec4 a_normal;
layout(location = 2) in vec4 a_lit;
layout(location = 3) in vec4 a_head;
struct View {
    mat4 clip;  // world -> the view's own clip space (image row 0 at y = -1)
    vec4 head;  // unit vector towards the headlight
    vec4 tile;  // the view's tile in the framebuffer's NDC: centre x, y; scale x, y
};
layout(std430, binding = 1) readonly buffer Views { View views[]; };
out vec3 v_colour;
out float gl_ClipDistance[4];
void main() {
    View v = views[gl_BaseInstanceARB];
    vec4 c = v.clip * a_pos;
    gl_ClipDistance[0] = c.w + c.x;
    gl_ClipDistance[1] = c.w - c.x;
    gl_ClipDistance[2] = c.w + c.y;
    gl_ClipDistance[3] = c.w - c.y;
    gl_Position = vec4(c.xy * v.tile.zw + c.w * v.tile.xy, c.zw);
    v_colour = clamp(a_lit.rgb + a_head.rgb * max(dot(a_normal.xyz, v.head.xyz), 0.0), 0.0, 1.0);
}
"""

_FRAGMENT_SHADER = """
#version 450
in vec3 v_colour;
layout(location = 0) out vec4 f_colour;
void main() {
    f_colour = vec4(v_colour, 1.0);
}
"""


# --- unit meshes (MuJoCo's built-in shapes, render_context.c) ---------------------------------
def _ring(n_slices: int) -> tuple[np.ndarray, np.ndarray]:
    az = 2.0 * np.pi * np.arange(n_slices + 1) / n_slices
    return np.cos(az), np.sin(az)


def _quad_strip(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Triangles (2k, 3, 3) between two rows (k + 1, 3) of points."""
    return np.concatenate(
        [np.stack([a[:-1], a[1:], b[1:]], axis=1), np.stack([a[:-1], b[1:], b[:-1]], axis=1)]
    )


def _sphere_band(n_slices: int, elevations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of a unit sphere between consecutive ``elevations`` (rad): (positions,
    normals), each (k, 3, 3). Rings at ±π/2 collapse to the poles."""
    c, s = _ring(n_slices)
    rings = [
        np.stack([c * math.cos(el), s * math.cos(el), np.full_like(c, math.sin(el))], axis=1)
        for el in elevations
    ]
    tris = np.concatenate([_quad_strip(a, b) for a, b in zip(rings[:-1], rings[1:], strict=True)])
    return tris, tris.copy()


def _unit_sphere(n_slices: int, n_stacks: int) -> tuple[np.ndarray, np.ndarray]:
    # MuJoCo: n_stacks / 2 bands per hemisphere, the one at each pole a fan.
    half = max(n_stacks // 2, 1)
    return _sphere_band(n_slices, 0.5 * np.pi * np.arange(-half, half + 1) / half)


def _unit_cylinder(n_slices: int, caps: bool = True) -> tuple[np.ndarray, np.ndarray]:
    c, s = _ring(n_slices)
    bottom = np.stack([c, s, -np.ones_like(c)], axis=1)
    top = np.stack([c, s, np.ones_like(c)], axis=1)
    radial = np.stack([c, s, np.zeros_like(c)], axis=1)
    pos, nrm = [_quad_strip(bottom, top)], [_quad_strip(radial, radial)]
    if caps:
        for rim, z in ((top, 1.0), (bottom, -1.0)):
            apex = np.broadcast_to([0.0, 0.0, z], rim[:-1].shape)
            pos.append(np.stack([rim[:-1], rim[1:], apex], axis=1))
            nrm.append(np.broadcast_to([0.0, 0.0, z], pos[-1].shape))
    return np.concatenate(pos), np.concatenate(nrm)


def _unit_box() -> tuple[np.ndarray, np.ndarray]:
    pos, nrm = [], []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        for sign in (-1.0, 1.0):
            corners = np.zeros((4, 3))
            corners[:, axis] = sign
            corners[:, u] = [-1, 1, 1, -1]
            corners[:, v] = [-1, -1, 1, 1]
            pos.append(corners[[[0, 1, 2], [0, 2, 3]]])
            normal = np.zeros(3)
            normal[axis] = sign
            nrm.append(np.broadcast_to(normal, pos[-1].shape))
    return np.concatenate(pos), np.concatenate(nrm)


def geom_mesh(
    gtype: int, size: np.ndarray, n_slices: int, n_stacks: int
) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of one geom in its own frame, as MuJoCo draws it.

    Args:
        gtype: ``mjtGeom`` type.
        size: the geom's ``geom_size``.
        n_slices, n_stacks: tessellation of round shapes (MuJoCo's ``vis.quality``).

    Returns:
        positions and unit normals, each (n_triangles, 3, 3), in any winding.

    Raises:
        ValueError: for an unsupported geom type.
    """
    t = mujoco.mjtGeom
    if gtype == t.mjGEOM_PLANE:
        half = [float(s) if s > 0 else _FAR_CLIP for s in size[:2]]
        corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
        corners[:, :2] *= half
        pos = corners[[[0, 1, 2], [0, 2, 3]]]
        return pos, np.broadcast_to([0.0, 0.0, 1.0], pos.shape)
    if gtype == t.mjGEOM_CAPSULE:
        r, h = float(size[0]), float(size[1])
        side_p, side_n = _unit_cylinder(n_slices, caps=False)
        half = max(n_stacks // 2, 1)
        pos, nrm = [side_p * [r, r, h]], [side_n]
        for sign in (-1.0, 1.0):
            p, n = _sphere_band(n_slices, sign * 0.5 * np.pi * np.arange(half + 1) / half)
            pos.append(p * r + [0.0, 0.0, sign * h])
            nrm.append(n)
        return np.concatenate(pos), np.concatenate(nrm)
    if gtype == t.mjGEOM_SPHERE:
        (pos, nrm), scale = _unit_sphere(n_slices, n_stacks), np.full(3, size[0])
    elif gtype == t.mjGEOM_ELLIPSOID:
        (pos, nrm), scale = _unit_sphere(n_slices, n_stacks), np.asarray(size[:3], float)
    elif gtype == t.mjGEOM_CYLINDER:
        (pos, nrm), scale = _unit_cylinder(n_slices), np.array([size[0], size[0], size[1]])
    elif gtype == t.mjGEOM_BOX:
        (pos, nrm), scale = _unit_box(), np.asarray(size[:3], float)
    else:
        raise ValueError(
            f"BatchOmniRenderer cannot draw geom type {mujoco.mjtGeom(gtype).name}; supported: "
            "plane, sphere, capsule, ellipsoid, cylinder, box"
        )
    # Normals transform with the inverse scale, then renormalise (glScalef + GL_NORMALIZE).
    nrm = nrm / scale
    return pos * scale, nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)


#: Levels of detail of round shapes, (slices, stacks): MuJoCo's vision tessellation, then
#: coarser ones whose vertices are subsets of it (so every level uses the same vertices).
LEVELS_OF_DETAIL = (
    TESSELLATION[:2],
    (TESSELLATION[0] // 2, TESSELLATION[1]),
    (TESSELLATION[0] // 4, max(TESSELLATION[1] // 2, 2)),
)
#: A geom is drawn at level 1 when its bounding sphere's projected radius is below this many
#: pixel columns (halving the slices then moves its outline by at most 0.076 × 2 ≈ 0.15 px), at
#: level 2 below this many pixels along either axis (0.29 × 0.5 ≈ 0.15 px).
LOD_RADIUS_PX = (2.0, 0.5)


@dataclass(frozen=True)
class SceneGeometry:
    """The static meshes of every drawn geom, in one vertex and one index array.

    Attributes:
        vertices: (n_vertices, 7) float32: position in the geom frame (scaled by its size), the
            geom's index (as a float, exact), unit normal in the geom frame.
        indices: (n_indices,) uint32, triangles counter-clockwise seen from outside; for each
            level of detail, every drawn geom's triangles in the order of ``geoms``.
        geoms: (n_drawn,) model indices of the drawn geoms, in :func:`draw_order`.
        index_start: (n_levels, n_drawn + 1) where each geom's indices start at each level
            (the last column: where the next level starts).
        same_at_all_levels: (n_drawn,) whether a geom has the same triangles at every level
            (boxes, planes).
    """

    vertices: np.ndarray
    indices: np.ndarray
    geoms: np.ndarray
    index_start: np.ndarray
    same_at_all_levels: np.ndarray


def _outward_triangles(pos: np.ndarray, nrm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The triangles reordered counter-clockwise seen from where their normals point."""
    pos, nrm = np.array(pos, dtype=float), np.array(nrm, dtype=float)
    face = np.cross(pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 0])
    flip = np.einsum("ij,ij->i", face, nrm.sum(axis=1)) < 0
    pos[flip] = pos[flip][:, [0, 2, 1]]
    nrm[flip] = nrm[flip][:, [0, 2, 1]]
    return pos, nrm


def draw_order(model: mujoco.MjModel) -> np.ndarray:
    """The geoms to draw (groups 0–2), grouped by top-level body (a robot, a pack, the world)
    in model order, and within a body by increasing bounding radius.

    A view draws runs of consecutive geoms at one level of detail with one command each; as the
    level of a geom grows with its distance over its size, a body's geoms at any distance then
    form at most one run per level.
    """
    drawn = np.flatnonzero(np.isin(model.geom_group, VISIBLE_GROUPS))
    root = model.body_rootid[model.geom_bodyid[drawn]]
    first_seen = {r: i for i, r in reversed(list(enumerate(root)))}
    rank = np.array([first_seen[r] for r in root])
    return drawn[np.lexsort((drawn, model.geom_rbound[drawn], rank))]


def build_geometry(
    model: mujoco.MjModel, levels: tuple[tuple[int, int], ...] = LEVELS_OF_DETAIL
) -> SceneGeometry:
    """The static meshes of the geoms MuJoCo would draw (groups 0–2) for ``model``.

    Args:
        model: the compiled model.
        levels: (slices, stacks) of round shapes at each level of detail.

    Raises:
        ValueError: for a drawn geom of an unsupported type or with a material.
    """
    verts: list[np.ndarray] = []
    index: list[list[np.ndarray]] = [[] for _ in levels]
    geoms, same = [], []
    n_verts = 0
    for g in draw_order(model):
        if int(model.geom_matid[g]) >= 0:
            raise ValueError(
                f"geom {g} has a material; BatchOmniRenderer draws plain rgba colours only"
            )
        meshes = [
            _outward_triangles(*geom_mesh(int(model.geom_type[g]), model.geom_size[g], *lod))
            for lod in levels
        ]
        flat = np.concatenate(
            [np.concatenate([p.reshape(-1, 3), n.reshape(-1, 3)], axis=1) for p, n in meshes]
        )
        # One vertex table for all levels: a coarse level's vertices are the fine level's.
        unique, inverse = np.unique(np.round(flat, 7), axis=0, return_inverse=True)
        offset = 0
        for level, (p, _) in enumerate(meshes):
            tri = inverse.reshape(-1)[offset : offset + p.shape[0] * 3].reshape(-1, 3)
            offset += p.shape[0] * 3
            # Drop triangles that collapsed (at a pole).
            keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])
            index[level].append(tri[keep].reshape(-1) + n_verts)
        same.append(all(np.array_equal(index[0][-1], i[-1]) for i in index))
        verts.append(np.insert(unique, 3, g, axis=1))
        n_verts += len(unique)
        geoms.append(g)
    if not verts:
        raise ValueError("the model has no geom to draw (groups 0-2)")
    # Level-major order: level l, geom j starts at starts[l * n + j].
    n = len(geoms)
    counts = [len(i) for level in index for i in level]
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    index_start = np.stack(
        [starts[level * n : (level + 1) * n + 1] for level in range(len(levels))]
    )
    return SceneGeometry(
        vertices=np.concatenate(verts).astype(np.float32),
        indices=np.concatenate([i for level in index for i in level]).astype(np.uint32),
        geoms=np.asarray(geoms, dtype=np.int64),
        index_start=index_start,
        same_at_all_levels=np.asarray(same, dtype=bool),
    )


def _frustum(left: float, right: float, bottom: float, top: float, near: float, far: float):
    """OpenGL's ``glFrustum`` matrix (row-major)."""
    return np.array(
        [
            [2 * near / (right - left), 0, (right + left) / (right - left), 0],
            [0, 2 * near / (top - bottom), (top + bottom) / (top - bottom), 0],
            [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0, 0, -1, 0],
        ]
    )


def _program(vertex: str, fragment: str | None = None, feedback: list[str] | None = None) -> int:
    program = GL.glCreateProgram()
    GL.glAttachShader(program, shaders.compileShader(vertex, GL.GL_VERTEX_SHADER))
    if fragment is not None:
        GL.glAttachShader(program, shaders.compileShader(fragment, GL.GL_FRAGMENT_SHADER))
    if feedback:
        names = [ctypes.create_string_buffer(n.encode()) for n in feedback]
        pointers = (ctypes.POINTER(ctypes.c_char) * len(names))(
            *[ctypes.cast(n, ctypes.POINTER(ctypes.c_char)) for n in names]
        )
        GL.glTransformFeedbackVaryings(program, len(names), pointers, GL.GL_INTERLEAVED_ATTRIBS)
    GL.glLinkProgram(program)
    if not GL.glGetProgramiv(program, GL.GL_LINK_STATUS):
        raise RuntimeError(f"shader link failed: {GL.glGetProgramInfoLog(program)!r}")
    return program


def _attributes(buffer: int, layout: list[tuple[int, int]], stride: int) -> None:
    """Float vertex attributes ``(size, byte offset)`` at locations 0, 1, … of ``buffer``."""
    GL.glBindBuffer(GL.GL_ARRAY_BUFFER, buffer)
    for location, (size, offset) in enumerate(layout):
        GL.glEnableVertexAttribArray(location)
        GL.glVertexAttribPointer(
            location, size, GL.GL_FLOAT, GL.GL_FALSE, stride, ctypes.c_void_p(offset)
        )


@_jit
def _frame_views(
    rot: np.ndarray,
    pos: np.ndarray,
    centres: np.ndarray,
    alpha: np.ndarray,
    site_clip_t: np.ndarray,
    site_planes: np.ndarray,
    view_back: np.ndarray,
    rbound: np.ndarray,
    lod_depth: np.ndarray,
    same_at_all_levels: np.ndarray,
    near: float,
    own: np.ndarray,
    index_start: np.ndarray,
    clip_t: np.ndarray,
    head: np.ndarray,
    commands: np.ndarray,
) -> int:
    """Each view's camera, headlight and draw commands (compiled; :func:`_frame_views_numpy`
    is the reference).

    Args:
        rot, pos: (n, 3, 3), (n, 3) the camera sites' frames in the world.
        centres, alpha: (n_drawn, 3) world positions and (n_drawn,) alphas of the drawn geoms.
        site_clip_t: (n_k, 4, 4) each view's clip matrix from its site's frame, transposed.
        site_planes: (n_k, 6, 4) each view's frustum planes in its site's frame (unit normals
            pointing inside).
        view_back: (n_k, 3) each view's backward axis in its site's frame.
        rbound: (n_drawn,) bounding radii (inf: always drawn).
        lod_depth: (n_levels - 1, n_drawn) depths beyond which a geom uses level >= l + 1.
        same_at_all_levels: (n_drawn,) geoms with one mesh at every level (boxes, planes):
            they take the level of the run they are in, so they do not split it.
        near: near clip distance.
        own: (n * n_k, n_drawn) whether a geom belongs to the view's robot.
        index_start: (n_levels, n_drawn + 1) where each geom's indices start at each level.
        clip_t, head: (n, n_k, 4, 4), (n, n_k, 3) outputs: clip matrices from the world
            (transposed), unit vectors towards the headlight.
        commands: (max, 5) output: DrawElementsIndirectCommands (instance count preset).

    Returns:
        The number of commands written: per view, one for each run of consecutive drawn geoms
        at one level of detail (each command costs a few microseconds in llvmpipe).
    """
    n, n_k, n_drawn = rot.shape[0], site_clip_t.shape[0], centres.shape[0]
    n_levels = index_start.shape[0]
    w2s_t = np.zeros((4, 4))
    local = np.empty((n_drawn, 3))
    n_commands = 0
    for i in range(n):
        # world -> site, transposed: [[R, 0], [-(R^T p)^T, 1]]
        for a in range(3):
            for b in range(3):
                w2s_t[a, b] = rot[i, a, b]
            w2s_t[3, a] = -(
                rot[i, 0, a] * pos[i, 0] + rot[i, 1, a] * pos[i, 1] + rot[i, 2, a] * pos[i, 2]
            )
        w2s_t[3, 3] = 1.0
        for g in range(n_drawn):
            dx = centres[g, 0] - pos[i, 0]
            dy = centres[g, 1] - pos[i, 1]
            dz = centres[g, 2] - pos[i, 2]
            for a in range(3):
                local[g, a] = rot[i, 0, a] * dx + rot[i, 1, a] * dy + rot[i, 2, a] * dz
        for k in range(n_k):
            for a in range(4):
                for c in range(4):
                    acc = 0.0
                    for b in range(4):
                        acc += w2s_t[a, b] * site_clip_t[k, b, c]
                    clip_t[i, k, a, c] = acc
            for a in range(3):
                head[i, k, a] = (
                    rot[i, a, 0] * view_back[k, 0]
                    + rot[i, a, 1] * view_back[k, 1]
                    + rot[i, a, 2] * view_back[k, 2]
                )
            view = i * n_k + k
            run_level = -1  # -1: no run; -2: a run of same_at_all_levels geoms only
            run_start = 0
            for g in range(n_drawn + 1):
                level = -1
                if g < n_drawn and alpha[g] > 0.0 and not own[view, g]:
                    r = rbound[g]
                    x, y, z = local[g, 0], local[g, 1], local[g, 2]
                    inside = True
                    for p in range(site_planes.shape[1]):
                        pl = site_planes[k, p]
                        if pl[0] * x + pl[1] * y + pl[2] * z + pl[3] <= -r:
                            inside = False
                            break
                    if inside and same_at_all_levels[g]:
                        level = -2
                    elif inside:
                        depth = (
                            -(view_back[k, 0] * x + view_back[k, 1] * y + view_back[k, 2] * z) - r
                        )
                        depth = max(depth, near)
                        level = 0
                        for lv in range(n_levels - 1):
                            if depth > lod_depth[lv, g]:
                                level = lv + 1
                if level == -2 and run_level != -1:
                    continue  # joins the open run
                if run_level == -2 and level >= 0:
                    run_level = level  # the open run takes this geom's level
                    continue
                if level != run_level:
                    if run_level != -1:
                        lv = max(run_level, 0)
                        first = index_start[lv, run_start]
                        commands[n_commands, 0] = index_start[lv, g] - first
                        commands[n_commands, 2] = first
                        commands[n_commands, 4] = view
                        n_commands += 1
                    run_level = level
                    run_start = g
    return n_commands


def _frame_views_numpy(
    rot: np.ndarray,
    pos: np.ndarray,
    centres: np.ndarray,
    alpha: np.ndarray,
    site_clip_t: np.ndarray,
    site_planes: np.ndarray,
    view_back: np.ndarray,
    rbound: np.ndarray,
    lod_depth: np.ndarray,
    same_at_all_levels: np.ndarray,
    near: float,
    own: np.ndarray,
    index_start: np.ndarray,
    clip_t: np.ndarray,
    head: np.ndarray,
    commands: np.ndarray,
) -> int:
    """:func:`_frame_views` in numpy (the reference, and the fallback without numba)."""
    n, n_k = rot.shape[0], site_clip_t.shape[0]
    w2s_t = np.zeros((n, 4, 4))
    w2s_t[:, :3, :3] = rot
    w2s_t[:, 3, :3] = np.einsum("nji,nj->ni", rot, -pos)
    w2s_t[:, 3, 3] = 1.0
    np.einsum("nab,kbc->nkac", w2s_t, site_clip_t, out=clip_t, casting="same_kind")
    np.einsum("nab,kb->nka", rot, view_back, out=head, casting="same_kind")
    local = np.einsum("nji,ngj->ngi", rot, centres[None] - pos[:, None])  # (n, n_drawn, 3)
    dist = np.einsum("ngj,kpj->nkgp", local, site_planes[:, :, :3]) + site_planes[:, None, :, 3]
    inside = dist.min(axis=3) > -rbound  # (n, n_k, n_drawn)
    depth = -np.einsum("ngj,kj->nkg", local, view_back) - rbound
    depth = np.maximum(depth, near)
    level = (depth[None] > lod_depth[:, None, None]).sum(axis=0)
    code = np.where(inside, level, -1).reshape(n * n_k, -1)
    code[own | (alpha <= 0.0)] = -1
    # Geoms with one mesh at all levels take the level of the previous geom of their run that
    # has levels, else of the next one, else 0.
    pending = (code >= 0) & same_at_all_levels
    code[pending] = -2
    col = np.arange(code.shape[1])
    before = np.maximum.accumulate(np.where(pending, -1, col), axis=1)
    after = np.minimum.accumulate(np.where(pending, code.shape[1], col)[:, ::-1], axis=1)[:, ::-1]
    prev = np.take_along_axis(code, np.maximum(before, 0), axis=1)
    prev[before < 0] = -1
    nxt = np.take_along_axis(code, np.minimum(after, code.shape[1] - 1), axis=1)
    nxt[after >= code.shape[1]] = -1
    code[pending] = np.where(prev >= 0, prev, np.where(nxt >= 0, nxt, 0))[pending]
    padded = np.pad(code, ((0, 0), (1, 1)), constant_values=-1)
    change = padded[:, 1:] != padded[:, :-1]
    view, first = np.nonzero(change & (padded[:, 1:] >= 0))
    last = np.nonzero(change & (padded[:, :-1] >= 0))[1]
    level = padded[view, first + 1]
    cmd = commands[: len(view)]
    cmd[:, 2] = index_start[level, first]
    cmd[:, 0] = index_start[level, last] - cmd[:, 2]
    cmd[:, 4] = view
    return len(view)


class BatchOmniRenderer:
    """Renders all robots' omni strips of a world in one buffer with a few OpenGL calls.

    A drop-in replacement for :class:`~cyber_rodent.vision.rendering.OmniRenderer`: same
    arguments, output, tile layout and errors.

    Args:
        world: the world (its model and data are read at every :meth:`render`).
        config: the camera.

    Raises:
        ValueError: if all strips together do not fit one off-screen buffer, or the model has
            geoms or lights this renderer cannot draw.
    """

    def __init__(self, world: World, config: CameraConfig):
        self.world = world
        self.config = config
        self.projection = OmniProjection(config)
        n = world.config.n_robots
        self.n_robots = n
        self.width, self.buffer_height = strips_buffer_size(config, n)
        m = world.model
        self._closed = True
        self._lights = self._directional_lights(m)
        self.geometry = build_geometry(m)
        n_k = config.n_views
        n_views = n * n_k
        self.n_views = n_views
        drawn = self.geometry.geoms
        self._drawn = drawn
        self._n_drawn = len(drawn)

        # --- per-frame data: one buffer, three sections -----------------------------------
        # [lights | geoms] (SSBO 0), [views] (SSBO 1), [draw commands] (indirect), each
        # section aligned to 256 bytes (every GL implementation's largest offset alignment).
        n_light_slots = max(len(self._lights), 1)
        geoms_bytes = 16 * (n_light_slots + _GEOM_VEC4 * m.ngeom)
        views_bytes = 16 * _VIEW_VEC4 * n_views
        commands_bytes = 4 * _COMMAND_UINTS * n_views * self._n_drawn
        self._views_offset = _align(geoms_bytes)
        self._commands_offset = self._views_offset + _align(views_bytes)
        self._frame = np.zeros(self._commands_offset + commands_bytes, dtype=np.uint8)
        f32 = self._frame[: self._commands_offset].view(np.float32)
        self._light_dir = f32[: 4 * len(self._lights)].reshape(-1, 4)[:, :3]
        geoms = f32[4 * n_light_slots : geoms_bytes // 4].reshape(m.ngeom, _GEOM_VEC4, 4)
        self._geom_pos = geoms[:, 0, :3]
        self._geom_mat = geoms[:, 1:4, :3]
        self._geom_rgba = geoms[:, 4, :]
        views = f32[self._views_offset // 4 : (self._views_offset + views_bytes) // 4]
        views = views.reshape(n, n_k, _VIEW_VEC4, 4)
        self._clip_t = views[:, :, :4, :]  # transposed matrix = GLSL's column-major order
        self._head = views[:, :, 4, :3]
        # Tile of robot i, view k: columns k*w.., rows i*h.. from the framebuffer's bottom.
        views[:, :, 5, 0] = -1.0 + (2.0 * np.arange(n_k) + 1.0) / n_k
        views[:, :, 5, 1] = (-1.0 + (2.0 * np.arange(n) + 1.0) / n)[:, None]
        views[:, :, 5, 2] = 1.0 / n_k
        views[:, :, 5, 3] = 1.0 / n
        self._commands = self._frame[self._commands_offset :].view(np.uint32)
        self._commands = self._commands.reshape(-1, _COMMAND_UINTS)
        self._commands[:, 1] = 1  # instance count

        # --- static view geometry -----------------------------------------------------------
        centres = self.projection.view_centres
        fwd = np.stack([np.cos(centres), np.sin(centres), np.zeros_like(centres)], axis=1)
        up = np.array([0.0, 0.0, 1.0])
        # Eye frame from the camera site's frame, rows right, up, backwards (mjr_lookAt).
        eye = np.zeros((n_k, 4, 4))
        eye[:, 0, :3] = np.cross(fwd, up)
        eye[:, 1, :3] = up
        eye[:, 2, :3] = -fwd
        eye[:, 3, 3] = 1.0
        near = config.near_clip
        half_w = self.projection.half_tan * near
        proj = _frustum(
            -half_w,
            half_w,
            self.projection.v_bottom * near,
            self.projection.v_top * near,
            near,
            _FAR_CLIP,
        )
        proj[1] *= -1.0  # image row 0 at the tile's lowest GL row: read back top row first
        self._site_clip_t = np.ascontiguousarray((proj @ eye).transpose(0, 2, 1))  # transposed
        self._world_to_site_t = np.zeros((n, 4, 4))  # transposed
        self._world_to_site_t[:, 3, 3] = 1.0
        self._view_back = np.ascontiguousarray(-fwd)
        self._cam_site = np.asarray(world.camera_site, dtype=np.int64)
        # Culling: each view's frustum planes in the camera site's frame (w ± x, w ± y, w ± z
        # of its clip matrix, unit normals), the drawn geoms' owners and bounding radii (MuJoCo
        # gives infinite planes 0: always drawn).
        site_clip = self._site_clip_t.transpose(0, 2, 1)
        planes = np.concatenate(
            [site_clip[:, 3:] + site_clip[:, :3], site_clip[:, 3:] - site_clip[:, :3]], axis=1
        )
        self._site_planes = planes / np.linalg.norm(planes[:, :, :3], axis=2, keepdims=True)
        self._rbound = m.geom_rbound[drawn].copy()
        self._rbound[self._rbound <= 0.0] = np.inf
        owner = np.asarray(world.geom_robot, dtype=np.int64)[drawn]
        self._own = owner[None, :] == np.repeat(np.arange(n), n_k)[:, None]  # (n_views, n_drawn)
        # Level of detail from the depth of a geom's nearest point: level >= l beyond the
        # depth at which its projected radius is LOD_RADIUS_PX[l - 1].
        px_u = self.projection.px_per_u
        px_any = max(px_u, self.projection.px_per_v)
        self._lod_depth = np.stack(
            [self._rbound * px_u / LOD_RADIUS_PX[0], self._rbound * px_any / LOD_RADIUS_PX[1]]
        )
        self._views = _frame_views if compiled.AVAILABLE else _frame_views_numpy
        self._update_frame()  # compiles (or loads) the kernel now, not in the first frame

        self._rgba = np.empty((self.buffer_height, self.width, 4), dtype=np.uint8)
        self._pixels = np.empty((self.buffer_height, self.width, 3), dtype=np.uint8)
        self._strips = self._pixels.reshape(n, config.height, self.width, 3)
        self._frame_ptr = self._frame.ctypes.data
        self._rgba_ptr = self._rgba.ctypes.data

        # --- GL ------------------------------------------------------------------------------
        self._gl = _gl_context(self.width, self.buffer_height)
        self._closed = False
        try:
            self._gl.make_current()
            self._init_gl()
            self._raw = _RawGL()
        except Exception:
            self.close()
            raise

    @staticmethod
    def _directional_lights(m: mujoco.MjModel) -> list[int]:
        lights = []
        for j in range(m.nlight):
            if not m.light_active[j]:
                continue
            if int(m.light_type[j]) != mujoco.mjtLightType.mjLIGHT_DIRECTIONAL:
                raise ValueError(
                    f"light {j} is not directional; BatchOmniRenderer supports directional "
                    "lights (and the headlight) only"
                )
            lights.append(j)
        return lights

    def _transform_source(self) -> str:
        m = self.world.model
        head = m.vis.headlight
        active = float(bool(head.active))
        ambient = np.asarray(head.ambient, float) * active
        for j in self._lights:
            ambient = ambient + m.light_ambient[j]

        def vec3(v) -> str:
            return "vec3({:.9g}, {:.9g}, {:.9g})".format(*(float(x) for x in v))

        terms = "".join(
            f" + {vec3(m.light_diffuse[j])} * max(dot(n, lights[{k}].xyz), 0.0)"
            for k, j in enumerate(self._lights)
        )
        return (
            _TRANSFORM_SHADER.replace("N_LIGHT_SLOTS", str(max(len(self._lights), 1)))
            .replace("AMBIENT", vec3(ambient))
            .replace("LIGHT_TERMS", terms)
            .replace("HEAD_DIFFUSE", vec3(np.asarray(head.diffuse, float) * active))
        )

    def _init_gl(self) -> None:
        w, h = self.width, self.buffer_height
        geo = self.geometry
        n_vertices = len(geo.vertices)
        self._n_vertices = n_vertices
        self._transform = _program(
            self._transform_source(), feedback=["t_pos", "t_normal", "t_lit", "t_head"]
        )
        self._draw = _program(_VIEW_SHADER, _FRAGMENT_SHADER)
        self._transform, self._draw = int(self._transform), int(self._draw)
        # Off-screen framebuffer.
        self._fbo = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._fbo)
        self._renderbuffers = GL.glGenRenderbuffers(2)
        for rb, fmt, attachment in zip(
            self._renderbuffers,
            (GL.GL_RGBA8, GL.GL_DEPTH_COMPONENT32F),
            (GL.GL_COLOR_ATTACHMENT0, GL.GL_DEPTH_ATTACHMENT),
            strict=True,
        ):
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, fmt, w, h)
            GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, attachment, GL.GL_RENDERBUFFER, rb)
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"off-screen framebuffer incomplete (status 0x{status:x})")
        GL.glDrawBuffer(GL.GL_COLOR_ATTACHMENT0)
        GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)
        # Buffers: static mesh, index, per-frame data, transformed vertices.
        self._buffers = GL.glGenBuffers(4)
        mesh, index, frame, moved = (int(b) for b in self._buffers)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, mesh)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, geo.vertices.nbytes, geo.vertices, GL.GL_STATIC_DRAW)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, moved)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, 16 * _TF_VEC4 * n_vertices, None, GL.GL_DYNAMIC_COPY)
        GL.glBindBufferBase(GL.GL_TRANSFORM_FEEDBACK_BUFFER, 0, moved)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, frame)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, self._frame.nbytes, None, GL.GL_STREAM_DRAW)
        GL.glBindBufferRange(GL.GL_SHADER_STORAGE_BUFFER, 0, frame, 0, self._views_offset)
        GL.glBindBufferRange(
            GL.GL_SHADER_STORAGE_BUFFER,
            1,
            frame,
            self._views_offset,
            self._commands_offset - self._views_offset,
        )
        GL.glBindBuffer(GL.GL_DRAW_INDIRECT_BUFFER, frame)
        self._vaos = [int(v) for v in GL.glGenVertexArrays(2)]
        GL.glBindVertexArray(self._vaos[0])
        _attributes(mesh, [(4, 0), (3, 16)], geo.vertices.strides[0])
        GL.glBindVertexArray(self._vaos[1])
        _attributes(moved, [(4, 16 * a) for a in range(_TF_VEC4)], 16 * _TF_VEC4)
        GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, index)
        GL.glBufferData(
            GL.GL_ELEMENT_ARRAY_BUFFER, geo.indices.nbytes, geo.indices, GL.GL_STATIC_DRAW
        )
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        # Fixed state.
        GL.glViewport(0, 0, w, h)
        for plane in range(4):
            GL.glEnable(GL.GL_CLIP_DISTANCE0 + plane)
        GL.glDisable(GL.GL_DITHER)
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_MULTISAMPLE)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glFrontFace(GL.GL_CW)  # the flipped projection mirrors the winding
        GL.glClearColor(0.0, 0.0, 0.0, 1.0)
        GL.glClearDepth(1.0)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)

    def _update_frame(self) -> int:
        """Write this frame's data into the upload buffer; returns the number of commands."""
        m, d = self.world.model, self.world.data
        np.copyto(self._geom_pos, d.geom_xpos, casting="same_kind")
        np.copyto(self._geom_mat, d.geom_xmat.reshape(-1, 3, 3), casting="same_kind")
        np.copyto(self._geom_rgba, m.geom_rgba, casting="same_kind")
        if self._lights:
            np.negative(d.light_xdir[self._lights], out=self._light_dir, casting="same_kind")
        return self._views(
            d.site_xmat[self._cam_site].reshape(-1, 3, 3),
            d.site_xpos[self._cam_site],
            d.geom_xpos[self._drawn],
            m.geom_rgba[self._drawn, 3],
            self._site_clip_t,
            self._site_planes,
            self._view_back,
            self._rbound,
            self._lod_depth,
            self.geometry.same_at_all_levels,
            self.config.near_clip,
            self._own,
            self.geometry.index_start,
            self._clip_t,
            self._head,
            self._commands,
        )

    def render(self) -> np.ndarray:
        """Render all strips; returns a (n_robots, height, strip_width, 3) uint8 RGB view.

        The returned array is overwritten by the next call; copy it to keep it.
        """
        if self._closed:
            raise RuntimeError("this BatchOmniRenderer is closed")
        n_commands = self._update_frame()
        self._gl.make_current()
        gl = self._raw
        used = self._commands_offset + 4 * _COMMAND_UINTS * n_commands
        gl.BufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, used, self._frame_ptr)
        # Pass 1: every vertex to the world frame, once.
        gl.Enable(GL.GL_RASTERIZER_DISCARD)
        gl.UseProgram(self._transform)
        gl.BindVertexArray(self._vaos[0])
        gl.BeginTransformFeedback(GL.GL_POINTS)
        gl.DrawArrays(GL.GL_POINTS, 0, self._n_vertices)
        gl.EndTransformFeedback()
        gl.Disable(GL.GL_RASTERIZER_DISCARD)
        # Pass 2: all views.
        gl.UseProgram(self._draw)
        gl.BindVertexArray(self._vaos[1])
        gl.Clear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        gl.MultiDrawElementsIndirect(
            GL.GL_TRIANGLES, GL.GL_UNSIGNED_INT, self._commands_offset, n_commands, 0
        )
        gl.ReadPixels(
            0, 0, self.width, self.buffer_height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, self._rgba_ptr
        )
        cv2.cvtColor(self._rgba, cv2.COLOR_RGBA2RGB, dst=self._pixels)
        return self._strips

    def close(self) -> None:
        """Free the GL context (idempotent)."""
        if not self._closed:
            self._closed = True
            self._gl.free()

    def __enter__(self) -> BatchOmniRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _RawGL:
    """Plain ctypes entry points of the GL calls made every frame.

    PyOpenGL's wrappers (argument conversion, a ``glGetError`` after every call) cost several
    microseconds a call, a sizeable part of a ~1 ms frame; these cost well under one.
    """

    _SIGNATURES = {
        "glBufferSubData": (ctypes.c_uint, ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_void_p),
        "glEnable": (ctypes.c_uint,),
        "glDisable": (ctypes.c_uint,),
        "glUseProgram": (ctypes.c_uint,),
        "glBindVertexArray": (ctypes.c_uint,),
        "glBeginTransformFeedback": (ctypes.c_uint,),
        "glEndTransformFeedback": (),
        "glDrawArrays": (ctypes.c_uint, ctypes.c_int, ctypes.c_int),
        "glClear": (ctypes.c_uint,),
        "glViewport": (ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int),
        "glMultiDrawElementsIndirect": (
            ctypes.c_uint,
            ctypes.c_uint,
            ctypes.c_void_p,
            ctypes.c_int,
            ctypes.c_int,
        ),
        "glReadPixels": (
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_uint,
            ctypes.c_uint,
            ctypes.c_void_p,
        ),
    }

    def __init__(self) -> None:
        for name, args in self._SIGNATURES.items():
            prototype = ctypes.CFUNCTYPE(None, *args)
            try:
                fn = prototype((name, PLATFORM.GL))
            except AttributeError:
                address = PLATFORM.getExtensionProcedure(name.encode())
                if not address:
                    raise RuntimeError(f"OpenGL has no {name}") from None
                fn = prototype(address)
            setattr(self, name[2:], fn)


def _align(n_bytes: int, alignment: int = 256) -> int:
    return -(-n_bytes // alignment) * alignment
