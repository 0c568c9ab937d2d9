"""The static meshes of the drawn geoms: MuJoCo's built-in shapes, built once from the model.

Every drawn geom's unit mesh (MuJoCo's own built-in shapes, ``render_context.c``, at the vision
context's coarse :data:`~cyber_rodent.vision.rendering.TESSELLATION`) is scaled by
``geom_size`` and stored with its normals and the geom's index per vertex, in one vertex table;
index lists at three levels of detail (:data:`LEVELS_OF_DETAIL`) share those vertices. The
geoms are ordered (:func:`draw_order`) so that a view draws each body's visible geoms at one
level with few commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from cyber_rodent.vision.rendering import FAR_CLIP, TESSELLATION

#: Geom groups MuJoCo draws by default (``mjvOption.geomgroup``); group 3 is collision-only.
VISIBLE_GROUPS = (0, 1, 2)


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
    pos: list[np.ndarray] = []
    nrm: list[np.ndarray] = []
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
        half_size = [float(s) if s > 0 else FAR_CLIP for s in size[:2]]
        corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
        corners[:, :2] *= half_size
        quad = corners[[[0, 1, 2], [0, 2, 3]]]
        return quad, np.broadcast_to([0.0, 0.0, 1.0], quad.shape)
    if gtype == t.mjGEOM_CAPSULE:
        r, h = float(size[0]), float(size[1])
        side_p, side_n = _unit_cylinder(n_slices, caps=False)
        n_half = max(n_stacks // 2, 1)
        parts_p, parts_n = [side_p * [r, r, h]], [side_n]
        for sign in (-1.0, 1.0):
            p, n = _sphere_band(n_slices, sign * 0.5 * np.pi * np.arange(n_half + 1) / n_half)
            parts_p.append(p * r + [0.0, 0.0, sign * h])
            parts_n.append(n)
        return np.concatenate(parts_p), np.concatenate(parts_n)
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

