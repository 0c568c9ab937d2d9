"""The batch renderer's per-frame CPU rule, as a compiled kernel and its numpy reference.

Once per frame, before anything is drawn, :func:`frame_views` / :func:`frame_views_reference`
(same signature, ``docs/design.md`` §3) compute every view's camera (clip matrix from the world,
headlight direction) and its draw commands: the runs of consecutive drawn geoms whose bounding
sphere meets the view's frustum, minus the observing robot's own geoms and fully transparent
ones, each run at one level of detail chosen from the geoms' projected size. Each command
costs llvmpipe a few microseconds, hence runs rather than one command per geom.

The kernels read and write named buffers built once by
:class:`~cyber_rodent.vision.batch_rendering.renderer.BatchOmniRenderer`: :class:`SceneState`
(views of MuJoCo's model and data), :class:`ViewGeometry` (constants) and :class:`ViewOutputs`
(views of the per-frame upload buffer). The reference's matrix products are numpy ``einsum``
and may round the last bit differently from the scalar loops; the commands are identical
(``tests/test_vision_batch_rendering.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cyber_rodent.backend import jit

Floats = npt.NDArray[np.float64]
Floats32 = npt.NDArray[np.float32]
Ints = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]
Commands = npt.NDArray[np.uint32]


class SceneState(NamedTuple):
    """Views of the MuJoCo state the kernels read every frame."""

    site_xpos: Floats  #: (nsite, 3)
    site_xmat: Floats  #: (nsite, 9)
    geom_xpos: Floats  #: (ngeom, 3)
    geom_rgba: Floats32  #: (ngeom, 4) the model's colours (alpha 0: not drawn)


class ViewGeometry(NamedTuple):
    """Constants of the views and the drawn geoms (n robots, n_k views each, n_drawn geoms)."""

    camera_site: Ints  #: (n,) each robot's ``camera_mount`` site
    drawn: Ints  #: (n_drawn,) model indices of the drawn geoms, in draw order
    site_clip_t: Floats  #: (n_k, 4, 4) each view's clip matrix from its site's frame, transposed
    site_planes: Floats  #: (n_k, 6, 4) frustum planes in the site's frame, unit inward normals
    view_back: Floats  #: (n_k, 3) each view's backward axis in its site's frame
    rbound: Floats  #: (n_drawn,) bounding radii (inf: always drawn)
    lod_depth: Floats  #: (n_levels - 1, n_drawn) depths beyond which a geom uses level >= l + 1
    #: (n_drawn,) geoms with one mesh at every level (boxes, planes): they take the level of
    #: the run they are in, so they do not split it.
    same_at_all_levels: Bools
    near: float  #: near clip distance
    own: Bools  #: (n * n_k, n_drawn) the geom belongs to the view's robot
    index_start: Ints  #: (n_levels, n_drawn + 1) where each geom's indices start at each level


class ViewOutputs(NamedTuple):
    """Where the kernels write (views of the renderer's per-frame upload buffer)."""

    clip_t: Floats32  #: (n, n_k, 4, 4) clip matrices from the world, transposed
    head: Floats32  #: (n, n_k, 3) unit vectors towards the headlight
    commands: Commands  #: (n * n_k * n_drawn, 5) DrawElementsIndirectCommands (instances preset)


@jit
def frame_views(state: SceneState, views: ViewGeometry, out: ViewOutputs) -> int:
    """Each view's camera, headlight and draw commands (compiled).

    Returns:
        The number of commands written: per view, one for each run of consecutive drawn geoms
        at one level of detail.
    """
    site_xpos, site_xmat, geom_xpos, geom_rgba = state
    site_clip_t, site_planes, view_back = views.site_clip_t, views.site_planes, views.view_back
    rbound, lod_depth, near, own = views.rbound, views.lod_depth, views.near, views.own
    same_at_all_levels, index_start = views.same_at_all_levels, views.index_start
    drawn = views.drawn
    clip_t, head, commands = out
    n, n_k, n_drawn = views.camera_site.shape[0], site_clip_t.shape[0], drawn.shape[0]
    n_levels = index_start.shape[0]
    rot = np.empty((3, 3))
    pos = np.empty(3)
    w2s_t = np.zeros((4, 4))
    local = np.empty((n_drawn, 3))
    n_commands = 0
    for i in range(n):
        site = views.camera_site[i]
        for a in range(3):
            pos[a] = site_xpos[site, a]
            for b in range(3):
                rot[a, b] = site_xmat[site, 3 * a + b]
        # world -> site, transposed: [[R, 0], [-(R^T p)^T, 1]]
        for a in range(3):
            for b in range(3):
                w2s_t[a, b] = rot[a, b]
            w2s_t[3, a] = -(rot[0, a] * pos[0] + rot[1, a] * pos[1] + rot[2, a] * pos[2])
        w2s_t[3, 3] = 1.0
        for g in range(n_drawn):
            geom = drawn[g]
            dx = geom_xpos[geom, 0] - pos[0]
            dy = geom_xpos[geom, 1] - pos[1]
            dz = geom_xpos[geom, 2] - pos[2]
            for a in range(3):
                local[g, a] = rot[0, a] * dx + rot[1, a] * dy + rot[2, a] * dz
        for k in range(n_k):
            for a in range(4):
                for c in range(4):
                    acc = 0.0
                    for b in range(4):
                        acc += w2s_t[a, b] * site_clip_t[k, b, c]
                    clip_t[i, k, a, c] = acc
            for a in range(3):
                head[i, k, a] = (
                    rot[a, 0] * view_back[k, 0]
                    + rot[a, 1] * view_back[k, 1]
                    + rot[a, 2] * view_back[k, 2]
                )
            view = i * n_k + k
            run_level = -1  # -1: no run; -2: a run of same_at_all_levels geoms only
            run_start = 0
            for g in range(n_drawn + 1):
                level = -1
                if g < n_drawn and geom_rgba[drawn[g], 3] > 0.0 and not own[view, g]:
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


def frame_views_reference(state: SceneState, views: ViewGeometry, out: ViewOutputs) -> int:
    """:func:`frame_views` in numpy (the reference)."""
    site_clip_t, view_back, rbound = views.site_clip_t, views.view_back, views.rbound
    site_planes, index_start, commands = views.site_planes, views.index_start, out.commands
    rot = state.site_xmat[views.camera_site].reshape(-1, 3, 3)
    pos = state.site_xpos[views.camera_site]
    centres = state.geom_xpos[views.drawn]
    alpha = state.geom_rgba[views.drawn, 3]
    n, n_k = rot.shape[0], site_clip_t.shape[0]
    w2s_t = np.zeros((n, 4, 4))
    w2s_t[:, :3, :3] = rot
    w2s_t[:, 3, :3] = np.einsum("nji,nj->ni", rot, -pos)
    w2s_t[:, 3, 3] = 1.0
    np.einsum("nab,kbc->nkac", w2s_t, site_clip_t, out=out.clip_t, casting="same_kind")
    np.einsum("nab,kb->nka", rot, view_back, out=out.head, casting="same_kind")
    local = np.einsum("nji,ngj->ngi", rot, centres[None] - pos[:, None])  # (n, n_drawn, 3)
    dist = np.einsum("ngj,kpj->nkgp", local, site_planes[:, :, :3]) + site_planes[:, None, :, 3]
    inside = dist.min(axis=3) > -rbound  # (n, n_k, n_drawn)
    depth = -np.einsum("ngj,kj->nkg", local, view_back) - rbound
    depth = np.maximum(depth, views.near)
    level = (depth[None] > views.lod_depth[:, None, None]).sum(axis=0)
    code = np.where(inside, level, -1).reshape(n * n_k, -1)
    code[views.own | (alpha <= 0.0)] = -1
    # Geoms with one mesh at all levels take the level of the previous geom of their run that
    # has levels, else of the next one, else 0.
    pending = (code >= 0) & views.same_at_all_levels
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
