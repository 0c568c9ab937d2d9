"""The geometric vision's per-step rules: each as a compiled kernel and its numpy reference.

:class:`~cyber_rodent.vision.geometric.GeometricVision` answers, every control step and for
every robot, "what is the nearest visible green LED, red face and blue pack?". Three rules do
it, each written twice with the same signature (``docs/design.md`` §3):

* :func:`gather` / :func:`gather_reference`: copy the cameras' and targets' poses out of
  MuJoCo's data;
* :func:`front` / :func:`front_reference`: every target in every camera's frame, its projected
  size in pixels, whether it could be seen at all (range, size, own body, lit LED, active
  pack, plate facing), and the occlusion sample rays with their field-of-view test;
* :func:`nearest` / :func:`nearest_reference`: gather, front, then each class's candidates
  nearest first, casting MuJoCo's ``mj_ray`` at a candidate's samples only until its visibility
  is certain (a target is visible iff ``full_area * hits / samples >= min_area``, or, for a
  small target one of whose samples is hidden before that is certain, iff ``min_area`` of its
  pixels show it: :func:`traced_area`). The compiled
  kernel computes a target's position, projected size and samples only when its search
  reaches it: targets are binned in a uniform grid (:class:`UniformGrid`) and reached ring of
  cells by ring, nearest cells first, and a candidate is tried only once no target left in
  farther cells can be nearer (:func:`nearest`'s docstring gives the bound). Its rays test
  only the geoms near them (:func:`first_hit`). Neither changes the answer: the reference,
  which places and sorts every target and casts ``mj_ray`` over every geom, gives the same
  one bit for bit (``tests/test_kernel_parity.py``). So the cost per robot does not grow with
  the colony at a given density (``benchmarks/colony_scale.py``).

The compiled kernels call MuJoCo's own ``mj_ray`` and ``mju_rayGeom`` through their C entry
points (linked by symbol, so numba can cache the code); the references call ``mj_ray`` through
``ctypes``, so both test occlusion exactly as MuJoCo does. The reference of :func:`front` is
vectorised numpy; its small matrix products may round the last bit differently from the scalar
loops, so the two agree to rounding (``tests/test_kernel_parity.py``).

Every kernel reads and writes named buffers built once by the provider:
:class:`MujocoPoses` (views of ``MjData``), :class:`TargetTable` and :class:`CameraModel`
(constants), :class:`FrontBuffers` (per-step scratch), :class:`SceneIndex` (the grids of
targets and geoms, rebuilt each step) and :class:`NearestTargets` (the answer), bundled as one
:class:`GeometricScene`.
"""

from __future__ import annotations

import ctypes
import glob
import math
import os
import platform
from typing import Any, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt

from cyber_rodent.backend import jit, jit_inline
from cyber_rodent.vision.types import BATTERY, FACE, LED

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]

_TWO_PI = 2.0 * math.pi
#: Class order of :class:`NearestTargets` columns (LED, face, battery).
assert (LED, FACE, BATTERY) == (0, 1, 2)

#: MuJoCo versions whose ``mj_ray`` and ``mju_rayGeom`` C signatures the kernels' prototypes
#: were checked against (the header of 3.17.0: ``mjtNum mj_ray(const mjModel*, const mjData*,
#: const mjtNum pnt[3], const mjtNum vec[3], const mjtByte* geomgroup, mjtBool flg_static,
#: int bodyexclude, int geomid[1], mjtNum normal[3])`` and ``mjtNum mju_rayGeom(const mjtNum
#: pos[3], const mjtNum mat[9], const mjtNum size[3], const mjtNum pnt[3], const mjtNum vec[3],
#: int geomtype, mjtNum normal[3])``), and whose ``mj_ray`` is the nearest hit of the geoms it
#: does not eliminate, each intersected by ``mju_rayGeom`` (primitive geoms), ties to the lowest
#: geom id (:func:`first_hit` relies on it). A wrong prototype corrupts memory.
VERIFIED_MUJOCO = ("3.17.0",)
#: MuJoCo's primitive geom types, the ones ``mju_rayGeom`` intersects (plane, sphere, capsule,
#: ellipsoid, cylinder, box); ``mj_ray`` handles the others itself.
PRIMITIVE_GEOMS = (0, 2, 3, 4, 5, 6)


class MujocoPoses(NamedTuple):
    """Views of the MuJoCo data the kernels read, and the addresses ``mj_ray`` needs."""

    site_xpos: Floats  #: (nsite, 3)
    site_xmat: Floats  #: (nsite, 9)
    geom_xpos: Floats  #: (ngeom, 3)
    geom_xmat: Floats  #: (ngeom, 9)
    model_address: int  #: ``MjModel._address``
    data_address: int  #: ``MjData._address``


class TargetTable(NamedTuple):
    """Constants of the targets (LED, face of every robot, every pack) and their samples.

    T targets, S occlusion samples (stored target by target), n robots.
    """

    camera_site: Ints  #: (n,) site of each robot's omni camera
    target_geom: Ints  #: (T,) geom of each target
    target_cls: Ints  #: (T,) colour class of each target (LED, FACE, BATTERY)
    ids: Ints  #: (T,) 0 .. T - 1: every target, as a list
    own: Bools  #: (n, T) the target belongs to the robot
    #: (n,) each camera's arena (``World.robot_arena``): a robot sees only the targets of its
    #: own arena, as the walls between arenas hide every other (docs/design.md §9.33)
    camera_arena: Ints
    target_arena: Ints  #: (T,) each target's arena (its robot's, or ``World.pack_arena``)
    plate: Bools  #: (T,) a face plate (seen only from the front)
    half_width: Floats  #: (T,) m
    half_height: Floats  #: (T,) m
    rim: Floats  #: (T,) m, cylinder radius seen from above (0 for plates)
    depth_front: Floats  #: (T,) m, a plate's front face ahead of its centre (0 for cylinders)
    depth_back: Floats  #: (T,) m, where its sides begin to stand out of its body (0: cylinders)
    #: (T,) how far behind a plate's front face, per metre beside its edge, a camera still sees
    #: that edge past its body (0 for cylinders)
    edge_slope: Floats
    min_area: Floats  #: (T,) px, the class's smallest detectable blob
    #: (T,) px, a target whose full footprint covers fewer pixels is measured pixel by pixel
    #: if one of its samples is hidden before their estimate is certain and one is seen
    #: (:func:`traced_area`); 0: never
    trace_below: Floats
    sample_target: Ints  #: (S,) target of each sample
    sample_lateral: Floats  #: (S,) m, offset along the target's width axis
    sample_dz: Floats  #: (S,) m, vertical offset
    sample_along: Floats  #: (S,) m, offset along a plate's normal (0 for cylinders)
    sample_geom: Ints  #: (S,) geom a ray must hit first to count
    sample_start: Ints  #: (T,) first sample of each target
    sample_end: Ints  #: (T,) one past its last sample
    inv_samples: Floats  #: (T,) 1 / samples of each target
    class_targets: Ints  #: (3, W) targets of each class, padded with T (never a candidate)
    class_count: Ints  #: (3,) targets of each class
    exclude_body: Ints  #: (n,) body each robot's rays ignore (its own chassis)
    geom_groups: npt.NDArray[np.uint8]  #: (6,) rendered geom groups (the ones that hide)


class CameraModel(NamedTuple):
    """The omni camera's projection (``OmniProjection``) as the kernels need it."""

    view_centres: Floats  #: (n_views,) rad
    max_range: float  #: m
    view_span: float  #: rad per view
    n_views: int
    px_per_u: float  #: pixels per unit of image-plane x
    px_per_v: float  #: pixels per unit of image-plane y
    v_top: float  #: image-plane y of the strip's top edge
    v_bottom: float  #: and of its bottom edge
    tan_el_min: float  #: the elevation band every bearing sees
    tan_el_max: float
    edge_clip: float  #: rad, keeps tan() finite for targets beside the camera
    half_tan: float  #: tan of half a view's horizontal angle
    view_width: float  #: pixel columns per view
    rows: float  #: pixel rows of the strip
    view_cos: Floats  #: (n_views,) cos of each view's axis bearing
    view_sin: Floats  #: (n_views,) and its sin


class FrontBuffers(NamedTuple):
    """Per-step scratch and results of :func:`front` (n robots, T targets, S samples)."""

    cam: Floats  #: (n, 3) camera positions
    rot: Floats  #: (n, 9) camera frames, row-major
    centre: Floats  #: (T, 3) target positions
    gmat: Floats  #: (T, 9) target frames
    local: Floats  #: (n, T, 3) target axes in each camera's frame
    bearing: Floats  #: (n, T) rad
    distance: Floats  #: (n, T) m
    width_px: Floats  #: (n, T) pixel columns whose centre the target covers
    height_px: Floats  #: (n, T) pixel rows whose centre it covers
    full_area: Floats  #: (n, T) px if fully visible: ``width_px * height_px``
    left_px: Floats  #: (n, T) strip column coordinate of its left edge (0 = strip's left)
    right_px: Floats  #: (n, T) and of its right edge (may exceed the strip: it wraps)
    top_px: Floats  #: (n, T) row coordinate of its top edge (0 = strip's top), clipped
    bottom_px: Floats  #: (n, T) and of its bottom edge
    candidate: Bools  #: (n, T) could be seen at all
    diff: Floats  #: (n, T, 3) camera-to-target vectors, world frame
    lateral: Floats  #: (n, T, 3) each target's width axis as seen by each robot
    rays: Floats  #: (n, S, 3) camera-to-sample vectors, world frame (zero: not cast)
    sample_ok: Bools  #: (n, S) sample inside the field of view (and of a candidate)
    order: Ints  #: (3, T) scratch: each class's candidates found so far, nearest first
    ray_geom: npt.NDArray[np.int32]  #: (1,) geom hit by the last ray
    pixel_ray: Floats  #: (3,) camera-to-pixel vector of :func:`traced_area`, world frame


class UniformGrid(NamedTuple):
    """Items (targets or geoms) binned by their (x, y) into square cells, rebuilt each step.

    Cells cover the square [origin, origin + side * cell]²; an item outside it is binned into
    the nearest edge cell, so every item is in exactly one cell.
    """

    origin: float  #: m, the grid's lower x and y
    cell: float  #: m, side of a cell
    side: int  #: cells per row and per column
    members: Ints  #: (K,) the items binned (target or geom indices)
    start: Ints  #: (side² + 1,) where each cell's items begin in ``items``
    cursor: Ints  #: (side²,) scratch of the binning
    items: Ints  #: (K,) the binned items, cell by cell, in ascending order within a cell


class RayCulling(NamedTuple):
    """What :func:`first_hit` needs to cast a ray at the geoms near it only (G geoms)."""

    geom_size: Floats  #: (G, 3) ``MjModel.geom_size``
    geom_type: Ints  #: (G,) ``MjModel.geom_type``
    geom_rbound: Floats  #: (G,) m, radius of each geom's bounding sphere
    geom_bodyid: Ints  #: (G,) body of each geom (a ray ignores its robot's chassis body)
    geom_matid: Ints  #: (G,) material of each geom, -1 for none
    geom_rgba: npt.NDArray[np.float32]  #: (G, 4) view of ``MjModel.geom_rgba`` (alpha 0 hides)
    mat_rgba: npt.NDArray[np.float32]  #: (nmat, 4) view of ``MjModel.mat_rgba``
    in_group: Bools  #: (G,) the geom's group is one the rays see (``TargetTable.geom_groups``)
    primitive: Bools  #: (G,) a type ``mju_rayGeom`` intersects (:data:`PRIMITIVE_GEOMS`)
    #: geoms not binned (planes, which are unbounded, and very large geoms: the walls); every
    #: ray tests the planes, and the others whose bounding sphere meets it
    always: Ints
    reach: float  #: m, the largest bounding radius of the binned geoms, plus a margin
    cull: bool  #: use :func:`first_hit`; False: ``mj_ray`` (as fast where geoms are few)


class SceneIndex(NamedTuple):
    """The grids of :func:`nearest`'s search and of its rays, and the search's scratch."""

    targets: UniformGrid  #: every target, by its centre
    geoms: UniformGrid  #: every geom that can hide a target, except ``rays.always``
    rays: RayCulling
    found: Ints  #: (3,) scratch: candidates found per class
    tried: Ints  #: (3,) scratch: candidates tried per class
    done: Bools  #: (3,) scratch: the class's answer is known
    ring: Ints  #: (T,) scratch: the targets of one ring of cells
    near: Ints  #: (G,) scratch: the geoms one ray tests


class NearestTargets(NamedTuple):
    """Each robot's nearest visible LED, face and pack (columns in that order)."""

    bearing: Floats  #: (n, 3) rad, robot frame; 0 where nothing is seen
    distance: Floats  #: (n, 3) m; inf where nothing is seen
    visible: Bools  #: (n, 3)


class MergeRules(NamedTuple):
    """Constants of :func:`merge`: which targets' blobs may join (T targets, G geoms)."""

    target_cls: Ints  #: (T,) colour class of each target
    target_body: Ints  #: (T,) body that carries each target
    target_of_geom: Ints  #: (G,) target of each geom (a pack's ring: its pack's), else -1
    geom_body: Ints  #: (G,) body of each geom
    banded: Bools  #: (T,) the target's colour is cut by a grey band (a pack's ring)
    band_dz: float  #: m, that band's top above the target's centre
    band_radius: float  #: m, the band's radius
    strip_width: float  #: pixel columns of the strip (its wrap)


class MergeBuffers(NamedTuple):
    """Inputs, outputs and scratch of :func:`merge` (n robots, T targets, S samples)."""

    seen: Bools  #: (n, T) detected before merging
    visible_share: Floats  #: (n, T) share of its in-view samples the camera sees
    hit_geom: Ints  #: (n, S) geom each sample's ray hit first, -1 if none or not cast
    merged: Bools  #: (n, T) output: swallowed by a nearer target's blob
    spread: Floats  #: (n, T) output: rad, how far a survivor's blob reaches past its half width
    group: Ints  #: (T,) scratch: union-find parents
    #: (n_packs,) each pack's state (``World.pack_active``; the packs are the last targets): an
    #: inactive pack is dark, so it hides a pack behind it as any other body does
    pack_active: Bools
    listed: Ints  #: (T,) scratch: one robot's seen targets, in ascending order
    nearest: Ints  #: (T,) scratch: the nearest member of each group (by its root)
    members: Ints  #: (T,) scratch: the members of each group (by its root)
    reach: Floats  #: (T,) scratch: how far each group's blob reaches (by its root)


class GeometricScene(NamedTuple):
    """Everything :func:`nearest` reads: the poses, the constants, the LEDs and packs, the
    scratch and the grids."""

    poses: MujocoPoses
    targets: TargetTable
    camera: CameraModel
    led_on: Bools  #: (n,) each robot's LED state (a dark LED is not a green target)
    pack_active: Bools  #: (n_packs,) each pack's state (an inactive pack is not a blue target)
    front: FrontBuffers
    grids: SceneIndex


# --- MuJoCo's ray cast, for compiled code and for the reference ------------------------------
def mujoco_library() -> tuple[str, str]:
    """Path of the MuJoCo shared library the bindings loaded, or ("", why it is unusable)."""
    if mujoco.__version__ not in VERIFIED_MUJOCO:
        return "", (
            f"the mj_ray prototype is verified for mujoco {', '.join(VERIFIED_MUJOCO)}, "
            f"not {mujoco.__version__}"
        )
    if platform.machine().lower() not in ("x86_64", "amd64", "aarch64", "arm64"):
        return "", f"pointer-as-integer calls are not checked on {platform.machine()}"
    here = os.path.dirname(mujoco.__file__)
    found = sorted(glob.glob(os.path.join(here, f"libmujoco.so.{mujoco.__version__}")))
    if not found:
        return "", f"no libmujoco.so.{mujoco.__version__} next to {here}"
    return found[0], ""


_LIBRARY, UNAVAILABLE_REASON = mujoco_library()


def _compiled_mj_ray() -> Any:
    """``mj_ray`` as a numba external function, linked by symbol name (None if unusable).

    Pointers are declared as 64-bit integers (the same registers as ``void*`` in the x86-64 and
    AArch64 calling conventions), so the kernel passes array addresses as plain integers.
    """
    if not _LIBRARY:
        return None
    try:
        import llvmlite.binding as llvm
        from numba import types
    except ImportError:  # pragma: no cover - numba is a dependency
        return None
    llvm.load_library_permanently(_LIBRARY)
    i64 = types.int64
    signature = types.float64(i64, i64, i64, i64, i64, types.uint8, types.int32, i64, i64)
    return types.ExternalFunction("mj_ray", signature)


def _reference_mj_ray() -> Any:
    """``mj_ray`` through ctypes, with the same prototype (None if unusable)."""
    if not _LIBRARY:
        return None
    function = ctypes.CDLL(_LIBRARY).mj_ray
    pointer = ctypes.c_int64
    function.argtypes = [pointer] * 5 + [ctypes.c_uint8, ctypes.c_int32, pointer, pointer]
    function.restype = ctypes.c_double
    return function


def _compiled_ray_geom() -> Any:
    """``mju_rayGeom`` as a numba external function (None if unusable), pointers as integers
    as in :func:`_compiled_mj_ray`."""
    if not _LIBRARY:
        return None
    try:
        from numba import types
    except ImportError:  # pragma: no cover - numba is a dependency
        return None
    i64 = types.int64
    signature = types.float64(i64, i64, i64, i64, i64, types.int32, i64)
    return types.ExternalFunction("mju_rayGeom", signature)


_MJ_RAY = _compiled_mj_ray()
_MJ_RAY_GEOM = _compiled_ray_geom()
_MJ_RAY_REFERENCE = _reference_mj_ray()
_ROW = 24  # bytes of one (3,) float64 point or direction


def _wrap(a: float) -> float:
    """Wrap an angle to [-π, π) (numpy's ``(a + π) % 2π - π``)."""
    return (a + math.pi) % _TWO_PI - math.pi


_wrap_compiled = jit(_wrap)


# --- gather ------------------------------------------------------------------------------------
@jit
def gather(poses: MujocoPoses, targets: TargetTable, front: FrontBuffers) -> None:
    """Copy the cameras' poses (``front.cam``, ``front.rot``) and the targets' poses
    (``front.centre``, ``front.gmat``) out of MuJoCo's data arrays."""
    for i in range(targets.camera_site.shape[0]):
        s = targets.camera_site[i]
        for k in range(3):
            front.cam[i, k] = poses.site_xpos[s, k]
        for k in range(9):
            front.rot[i, k] = poses.site_xmat[s, k]
    for t in range(targets.target_geom.shape[0]):
        g = targets.target_geom[t]
        for k in range(3):
            front.centre[t, k] = poses.geom_xpos[g, k]
        for k in range(9):
            front.gmat[t, k] = poses.geom_xmat[g, k]


def gather_reference(poses: MujocoPoses, targets: TargetTable, front: FrontBuffers) -> None:
    """:func:`gather` in numpy."""
    poses.site_xpos.take(targets.camera_site, axis=0, out=front.cam)
    poses.site_xmat.take(targets.camera_site, axis=0, out=front.rot)
    poses.geom_xpos.take(targets.target_geom, axis=0, out=front.centre)
    poses.geom_xmat.take(targets.target_geom, axis=0, out=front.gmat)


# --- front -------------------------------------------------------------------------------------
def _covered(low: float, high: float) -> float:
    """How many pixel centres (at k + 0.5) lie in [low, high]: a rasteriser fills exactly the
    pixels whose centre the shape covers, so this, not the fractional extent, is the size of a
    small target's blob."""
    return float(max(math.floor(high - 0.5) - math.ceil(low - 0.5) + 1, 0))


_covered_compiled = jit_inline(_covered)


@jit_inline
def _edge_on(targets: TargetTable, t: int, x_cam: float, y_cam: float) -> bool:
    """Whether a camera at (x_cam, y_cam) in plate t's frame sees the side of the plate that
    stands out of its body: beside the plate, and not so far behind its front face that the
    body's side hides that edge (a plan-view test: the body is wider than the plate)."""
    beside: float = abs(y_cam) - targets.half_width[t]
    behind: float = targets.depth_front[t] - x_cam
    reach: float = targets.edge_slope[t] * beside
    return beside > 0.0 and behind <= reach


def covered(low: Floats, high: Floats) -> Floats:
    """:func:`_covered` on arrays (the references use it)."""
    count: Floats = np.maximum(np.floor(high - 0.5) - np.ceil(low - 0.5) + 1.0, 0.0)
    return count


@jit_inline
def _view_of(camera: CameraModel, bearing: float) -> tuple[int, float]:
    """The view that sees ``bearing`` and the bearing's offset from that view's axis (the
    scalar :func:`_view_offset`)."""
    span = camera.view_span
    rel = (camera.view_centres[0] - bearing + 0.5 * span) % _TWO_PI
    view = min(int(rel // span), camera.n_views - 1)
    offset: float = 0.5 * span - (rel - view * span)
    return view, offset


@jit_inline
def _corner_column(
    camera: CameraModel, f: FrontBuffers, i: int, t: int, along: float, across: float,
    n0: float, n1: float, a0: float, a1: float, view: int,
) -> float:  # fmt: skip
    """Strip column coordinate of a point of target ``t`` at ``along`` the normal (n0, n1) and
    ``across`` the width axis (a0, a1) from its axis, seen by robot ``i`` through view ``view``
    (the one that sees the axis) or, past its edge, through the neighbouring view."""
    r = f.rot[i]
    p0 = f.diff[i, t, 0] + along * n0 + across * a0
    p1 = f.diff[i, t, 1] + along * n1 + across * a1
    p2 = f.diff[i, t, 2]
    l0 = p0 * r[0] + p1 * r[3] + p2 * r[6]
    l1 = p0 * r[1] + p1 * r[4] + p2 * r[7]
    clip = camera.edge_clip
    rel = _wrap_compiled(math.atan2(l1, l0) - camera.view_centres[view])
    # A corner past the view's edge lies in its neighbour, whose columns continue the strip.
    step = 0
    if rel > 0.5 * camera.view_span:
        step = -1
    elif rel < -0.5 * camera.view_span:
        step = 1
    rel = min(max(rel + step * camera.view_span, -clip), clip)
    x = (view + step) * camera.view_width
    return x + (camera.half_tan - math.tan(rel)) * camera.px_per_u


@jit_inline
def _project(
    targets: TargetTable, camera: CameraModel, f: FrontBuffers, i: int, t: int
) -> float:
    """Target ``t``'s lateral axis and pixel footprint in robot ``i``'s camera; its full area.

    Columns: the target's outline as seen from the camera (a cylinder's two edges across the
    line of sight; a plate's front face if the camera is ahead of it, and the side that stands
    out of its body if the camera is beside it), projected into the view that sees its axis.
    Rows: the far top rim to the near bottom rim (cylinders seen from above) or top to bottom
    edge (plates), clipped to the strip. Its size is the pixel centres that footprint covers,
    as a rasteriser counts them. Reads ``diff``, ``local``, ``bearing`` and ``distance``,
    which :func:`front` wrote.
    """
    g = f.gmat[t]
    d0, d1, d2 = f.diff[i, t, 0], f.diff[i, t, 1], f.diff[i, t, 2]
    l2 = f.local[i, t, 2]
    b, dist = f.bearing[i, t], f.distance[i, t]
    hw = targets.half_width[t]
    view, offset = _view_of(camera, b)
    left, right = math.inf, -math.inf
    if targets.plate[t]:
        a0, a1, a2 = g[1], g[4], g[7]  # the plate's own width axis
        n0, n1 = g[0], g[3]  # its normal
        front_face, back = targets.depth_front[t], targets.depth_back[t]
        x_cam = -(d0 * n0 + d1 * n1 + d2 * g[6])  # the camera in the plate's frame
        y_cam = -(d0 * a0 + d1 * a1 + d2 * a2)
        if x_cam > front_face:  # the front face
            for across in (-hw, hw):
                x = _corner_column(camera, f, i, t, front_face, across, n0, n1, a0, a1, view)
                left, right = min(left, x), max(right, x)
        if _edge_on(targets, t, x_cam, y_cam):  # the side that stands out
            side = hw if y_cam > 0.0 else -hw
            for along in (back, front_face):
                x = _corner_column(camera, f, i, t, along, side, n0, n1, a0, a1, view)
                left, right = min(left, x), max(right, x)
    else:  # the two edges across the line of sight
        rh = max(math.hypot(d0, d1), 1e-9)
        a0, a1, a2 = -d1 / rh, d0 / rh, 0.0
        for across in (-hw, hw):
            x = _corner_column(camera, f, i, t, 0.0, across, 0.0, 0.0, a0, a1, view)
            left, right = min(left, x), max(right, x)
    f.lateral[i, t, 0] = a0
    f.lateral[i, t, 1] = a1
    f.lateral[i, t, 2] = a2
    cos_off = math.cos(offset)
    depth_far = max((dist + targets.rim[t]) * cos_off, 1e-9)
    depth_near = max((dist - targets.rim[t]) * cos_off, 1e-9)
    vt = (l2 + targets.half_height[t]) / depth_far
    vb = (l2 - targets.half_height[t]) / depth_near
    top = min(max((camera.v_top - vt) * camera.px_per_v, 0.0), camera.rows)
    bottom = min(max((camera.v_top - vb) * camera.px_per_v, 0.0), camera.rows)
    w_px = _covered_compiled(left, right) if left <= right else 0.0
    h_px = _covered_compiled(top, bottom)
    f.left_px[i, t] = left
    f.right_px[i, t] = right
    f.top_px[i, t] = top
    f.bottom_px[i, t] = bottom
    f.width_px[i, t] = w_px
    f.height_px[i, t] = h_px
    area: float = w_px * h_px
    f.full_area[i, t] = area
    return area


@jit_inline
def _sample(targets: TargetTable, camera: CameraModel, f: FrontBuffers, i: int, s: int) -> None:
    """Robot ``i``'s ray to occlusion sample ``s`` and whether the point is in its view."""
    r = f.rot[i]
    t = targets.sample_target[s]
    g = f.gmat[t]
    along = targets.sample_along[s]
    x = f.diff[i, t, 0] + targets.sample_lateral[s] * f.lateral[i, t, 0]
    y = f.diff[i, t, 1] + targets.sample_lateral[s] * f.lateral[i, t, 1]
    z = f.diff[i, t, 2] + targets.sample_lateral[s] * f.lateral[i, t, 2]
    x += along * g[0]
    y += along * g[3]
    z += along * g[6]
    z += targets.sample_dz[s]
    f.rays[i, s, 0] = x
    f.rays[i, s, 1] = y
    f.rays[i, s, 2] = z
    c0 = x * r[0] + y * r[3] + z * r[6]
    c1 = x * r[1] + y * r[4] + z * r[7]
    c2 = x * r[2] + y * r[5] + z * r[8]
    rh = max(math.hypot(c0, c1), 1e-9)
    tan_el = c2 / rh
    inside = tan_el >= camera.tan_el_min and tan_el <= camera.tan_el_max
    if not inside:  # near the robot: the exact per-view frustum test
        view, offset = _view_of(camera, math.atan2(c1, c0))
        v = tan_el / math.cos(offset)
        inside = v >= camera.v_bottom and v <= camera.v_top
    f.sample_ok[i, s] = inside


@jit_inline
def _place(
    targets: TargetTable, camera: CameraModel, led_on: Bools, pack_active: Bools,
    f: FrontBuffers, i: int, listed: Ints, count: int,
) -> None:  # fmt: skip
    """Targets ``listed[:count]`` in robot ``i``'s camera frame (``diff``, ``local``,
    ``bearing``, ``distance``), and in ``candidate`` whether each could be seen if it were
    large enough: in range, in the robot's arena, not the robot's own, a lit LED, an active
    pack, a plate whose front or side the camera faces.

    A list, not one target per call: a compiled helper's named buffers are counted as
    references at every call, which costs more than placing one target.
    """
    r = f.rot[i]
    n = f.cam.shape[0]
    first_pack = f.centre.shape[0] - pack_active.shape[0]
    for k in range(count):
        t = listed[k]
        d0 = f.centre[t, 0] - f.cam[i, 0]
        d1 = f.centre[t, 1] - f.cam[i, 1]
        d2 = f.centre[t, 2] - f.cam[i, 2]
        f.diff[i, t, 0] = d0
        f.diff[i, t, 1] = d1
        f.diff[i, t, 2] = d2
        # Camera frame: x_j = sum_k R_kj d_k.
        l0 = d0 * r[0] + d1 * r[3] + d2 * r[6]
        l1 = d0 * r[1] + d1 * r[4] + d2 * r[7]
        f.local[i, t, 0] = l0
        f.local[i, t, 1] = l1
        f.local[i, t, 2] = d0 * r[2] + d1 * r[5] + d2 * r[8]
        dist = math.hypot(l0, l1)
        f.bearing[i, t] = math.atan2(l1, l0)
        f.distance[i, t] = dist
        ok = dist <= camera.max_range and not targets.own[i, t]
        if targets.target_arena[t] != targets.camera_arena[i]:
            ok = False  # behind the walls of another arena
        if t < n and not led_on[t]:
            ok = False  # a dark LED is not a green target
        if t >= first_pack and not pack_active[t - first_pack]:
            ok = False  # an inactive pack is dark: not a blue target
        if ok and targets.plate[t]:  # a plate shows its front, or its side edge-on
            g = f.gmat[t]  # its x axis is the plate's normal, its y axis its width
            x_cam = -(d0 * g[0] + d1 * g[3] + d2 * g[6])
            y_cam = -(d0 * g[1] + d1 * g[4] + d2 * g[7])
            in_front = x_cam > targets.depth_front[t]
            ok = in_front or _edge_on(targets, t, x_cam, y_cam)
        f.candidate[i, t] = ok


@jit
def front(
    targets: TargetTable, camera: CameraModel, led_on: Bools, pack_active: Bools,
    f: FrontBuffers, every_target: bool,
) -> None:  # fmt: skip
    """Fill ``f``'s per-(robot, target) and per-(robot, sample) buffers from its poses.

    With ``every_target`` False, only what costs nothing is filled: each target's position
    (``diff``, ``local``, ``bearing``, ``distance``) and in ``candidate`` whether it could be
    seen *if it were large enough* (in range, in the robot's arena, not the robot's own, a lit
    LED, a plate whose front or side the camera faces). With it True, also each target's
    projected size (a candidate must also be large enough), and the occlusion samples of the
    candidates (a target that cannot be seen gets no rays: its ``rays`` are zero, its
    ``sample_ok`` False).

    A dark LED (``led_on``) and an inactive pack (``pack_active``, the last targets) are no
    target of their colour; they still hide what is behind them (the rays hit their geoms).
    """
    n = f.cam.shape[0]
    n_t = f.centre.shape[0]
    for i in range(n):
        _place(targets, camera, led_on, pack_active, f, i, targets.ids, n_t)
        if every_target:
            for t in range(n_t):
                area = _project(targets, camera, f, i, t)
                f.candidate[i, t] = f.candidate[i, t] and area >= targets.min_area[t]
            for t in range(n_t):
                candidate = f.candidate[i, t]
                for s in range(targets.sample_start[t], targets.sample_end[t]):
                    if candidate:
                        _sample(targets, camera, f, i, s)
                    else:  # no ray is cast at a target that cannot be seen
                        f.rays[i, s, 0] = 0.0
                        f.rays[i, s, 1] = 0.0
                        f.rays[i, s, 2] = 0.0
                        f.sample_ok[i, s] = False


def _view_offset(camera: CameraModel, bearing: Floats) -> tuple[Ints, Floats]:
    """Index of the view that sees each bearing, and the bearing's offset from its centre."""
    span = camera.view_span
    rel = np.mod(camera.view_centres[0] - bearing + 0.5 * span, _TWO_PI)
    view = np.minimum((rel // span).astype(np.int64), camera.n_views - 1)
    return view, 0.5 * span - (rel - view * span)


def front_reference(
    targets: TargetTable, camera: CameraModel, led_on: Bools, pack_active: Bools,
    f: FrontBuffers, every_target: bool,
) -> None:  # fmt: skip
    """:func:`front` in vectorised numpy (it fills every target and sample whatever
    ``every_target``, and ``sample_ok`` only for the candidates)."""
    n = f.cam.shape[0]
    rot = f.rot.reshape(n, 3, 3)
    gmat = f.gmat.reshape(-1, 3, 3)
    plate = targets.plate
    diff = f.diff
    np.subtract(f.centre[None, :, :], f.cam[:, None, :], out=diff)
    rh_world = np.maximum(np.hypot(diff[..., 0], diff[..., 1]), 1e-9)
    # Lateral direction of each target as seen by each robot: perpendicular to the line of
    # sight for cylinders, the plate's own width axis for plates.
    lateral = f.lateral
    lateral[..., 0] = -diff[..., 1] / rh_world
    lateral[..., 1] = diff[..., 0] / rh_world
    lateral[..., 2] = 0.0
    lateral[:, plate, :] = gmat[plate, :, 1][None, :, :]
    local = diff @ rot  # local_j = sum_i R_ij diff_i
    f.local[...] = local
    bearing = np.arctan2(local[..., 1], local[..., 0])
    distance = np.hypot(local[..., 0], local[..., 1])
    f.bearing[...] = bearing
    f.distance[...] = distance
    view, offset = _view_offset(camera, bearing)
    axis = camera.view_centres[view]
    # The outline's corners (along the normal, across the width axis): a cylinder's two edges
    # across the line of sight; a plate's front face if the camera is ahead of it, and the
    # side that stands out of its body if the camera is beside it.
    normal = gmat[:, :, 0]  # (T, 3) each target's x axis (a plate's normal)
    x_cam = -(diff * normal[None, :, :]).sum(axis=2)
    y_cam = -(diff * lateral).sum(axis=2)
    hw = np.broadcast_to(targets.half_width, bearing.shape)
    front_face = np.broadcast_to(targets.depth_front, bearing.shape)
    along = np.zeros((4,) + bearing.shape)
    across = np.zeros((4,) + bearing.shape)
    valid = np.zeros((4,) + bearing.shape, dtype=bool)
    across[0], across[1] = -hw, hw
    valid[0] = valid[1] = ~plate | (x_cam > front_face)
    along[0] = along[1] = np.where(plate, front_face, 0.0)
    along[2] = np.broadcast_to(targets.depth_back, bearing.shape)
    along[3] = front_face
    across[2] = across[3] = np.where(y_cam > 0.0, hw, -hw)
    beside = np.abs(y_cam) - hw
    edge_on = (beside > 0.0) & (front_face - x_cam <= targets.edge_slope * beside)
    valid[2] = valid[3] = plate & edge_on
    corner = np.broadcast_to(diff, (4,) + diff.shape).copy()  # (4, n, T, 3), world frame
    corner[..., :2] += along[..., None] * normal[None, None, :, :2]
    corner[..., :2] += across[..., None] * lateral[None, :, :, :2]
    corner_local = corner @ rot[None, ...]
    b_corner = np.arctan2(corner_local[..., 1], corner_local[..., 0])
    wrapped = np.mod(b_corner - axis + math.pi, _TWO_PI) - math.pi
    # A corner past the view's edge lies in its neighbour, whose columns continue the strip.
    step = np.where(
        wrapped > 0.5 * camera.view_span, -1, np.where(wrapped < -0.5 * camera.view_span, 1, 0)
    )
    rel = np.clip(wrapped + step * camera.view_span, -camera.edge_clip, camera.edge_clip)
    column = (view + step) * camera.view_width + (camera.half_tan - np.tan(rel)) * camera.px_per_u
    left = np.where(valid, column, np.inf).min(axis=0)
    right = np.where(valid, column, -np.inf).max(axis=0)
    cos_off = np.cos(offset)
    depth_far = np.maximum((distance + targets.rim) * cos_off, 1e-9)
    depth_near = np.maximum((distance - targets.rim) * cos_off, 1e-9)
    v_top = (local[..., 2] + targets.half_height) / depth_far
    v_bot = (local[..., 2] - targets.half_height) / depth_near
    top = np.clip((camera.v_top - v_top) * camera.px_per_v, 0.0, camera.rows)
    bottom = np.clip((camera.v_top - v_bot) * camera.px_per_v, 0.0, camera.rows)
    f.left_px[...] = left
    f.right_px[...] = right
    f.top_px[...] = top
    f.bottom_px[...] = bottom
    with np.errstate(invalid="ignore"):  # no corner: inf - inf
        f.width_px[...] = np.where(left <= right, covered(left, right), 0.0)
    f.height_px[...] = covered(top, bottom)
    np.multiply(f.width_px, f.height_px, out=f.full_area)
    candidate = f.candidate
    np.greater_equal(f.full_area, targets.min_area, out=candidate)
    candidate &= distance <= camera.max_range
    candidate &= ~targets.own
    candidate &= targets.camera_arena[:, None] == targets.target_arena[None, :]  # one arena
    candidate[:, :n] &= led_on[None, :]  # a dark LED is not a green target
    candidate[:, candidate.shape[1] - len(pack_active) :] &= pack_active[None, :]  # dark packs
    # Plates (faces) show their front to a camera ahead of them, their side edge-on to one
    # beside them.
    candidate[:, plate] &= (x_cam > front_face)[:, plate] | edge_on[:, plate]
    # Occlusion samples: the ray from the camera to each sample point, and whether the point
    # is in the camera's field of view (the elevation band every bearing sees, else the exact
    # per-view frustum test for points very close to the robot).
    st = targets.sample_target
    rays = f.rays
    np.multiply(targets.sample_lateral[None, :, None], lateral[:, st, :], out=rays)
    rays += diff[:, st, :]
    rays += targets.sample_along[None, :, None] * gmat[st, :, 0][None, :, :]
    rays[..., 2] += targets.sample_dz[None, :]
    ray_local = rays @ rot
    rh = np.maximum(np.hypot(ray_local[..., 0], ray_local[..., 1]), 1e-9)
    tan_el = ray_local[..., 2] / rh
    inside = (tan_el >= camera.tan_el_min) & (tan_el <= camera.tan_el_max)
    if not inside.all():
        _, ray_offset = _view_offset(camera, np.arctan2(ray_local[..., 1], ray_local[..., 0]))
        v = tan_el / np.cos(ray_offset)
        inside = (v >= camera.v_bottom) & (v <= camera.v_top)
    # No ray is cast at a target that cannot be seen.
    np.logical_and(inside, candidate[:, st], out=f.sample_ok)
    rays[~candidate[:, st]] = 0.0


# --- grids and culled rays ---------------------------------------------------------------------
#: m, how much farther than its bounding sphere a geom is still tested by a ray, and how much a
#: search bound is lowered: rounding is some 1e-16 m here, so the margin only makes the tests
#: conservative, never exact to the last bit.
CULL_MARGIN = 1e-6


@jit_inline
def _grid_cell(origin: float, cell: float, side: int, x: float) -> int:
    """The column (or row) of coordinate ``x`` in a grid of ``side`` cells of ``cell`` from
    ``origin``, clamped to the grid (NaN: the first). Scalars, not the grid: a helper's named
    buffers are counted as references at every call."""
    k = (x - origin) / cell
    if not k >= 0.0:
        return 0
    if k >= side:
        return side - 1
    return int(k)


@jit_inline
def _bin(grid: UniformGrid, positions: Floats) -> None:
    """Bin ``grid.members`` by their (x, y) in ``positions`` (a counting sort: the items of a
    cell stay in ascending order)."""
    origin, cell, side = grid.origin, grid.cell, grid.side
    for c in range(side * side + 1):
        grid.start[c] = 0
    for k in range(grid.members.shape[0]):
        item = grid.members[k]
        column = _grid_cell(origin, cell, side, positions[item, 0])
        c = column + side * _grid_cell(origin, cell, side, positions[item, 1])
        grid.start[c + 1] += 1
    for c in range(side * side):
        grid.start[c + 1] += grid.start[c]
        grid.cursor[c] = grid.start[c]
    for k in range(grid.members.shape[0]):
        item = grid.members[k]
        column = _grid_cell(origin, cell, side, positions[item, 0])
        c = column + side * _grid_cell(origin, cell, side, positions[item, 1])
        grid.items[grid.cursor[c]] = item
        grid.cursor[c] += 1


@jit_inline
def _near_geoms(
    poses: MujocoPoses, rays: RayCulling, grid: UniformGrid, near: Ints, p: Floats, v: Floats
) -> int:
    """Into ``near``, the geoms a ray along the segment p + x v, x in [0, 1], may hit first:
    the unbounded ones of ``rays.always`` (planes), and the bounded ones of ``rays.always``
    (walls, one arena's or many arenas') and the binned geoms found in the cells of ``grid``
    the segment passes within ``rays.reach`` of, each only if its bounding sphere (plus
    :data:`CULL_MARGIN`) meets the segment. Returns how many."""
    origin, cell, side = grid.origin, grid.cell, grid.side
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    count = 0
    for k in range(rays.always.shape[0]):
        g = rays.always[k]
        radius = rays.geom_rbound[g]
        if radius > 0.0:  # a bounded geom (a wall): only if its bounding sphere meets the segment
            c0 = poses.geom_xpos[g, 0] - p[0]
            c1 = poses.geom_xpos[g, 1] - p[1]
            c2 = poses.geom_xpos[g, 2] - p[2]
            x = min(max((c0 * v[0] + c1 * v[1] + c2 * v[2]) / vv, 0.0), 1.0)
            q0, q1, q2 = x * v[0] - c0, x * v[1] - c1, x * v[2] - c2
            radius += CULL_MARGIN
            if q0 * q0 + q1 * q1 + q2 * q2 > radius * radius:
                continue
        near[count] = g
        count += 1
    reach = rays.reach
    x0, x1 = p[0], p[0] + v[0]
    first = _grid_cell(origin, cell, side, min(x0, x1) - reach)
    last = _grid_cell(origin, cell, side, max(x0, x1) + reach)
    for column in range(first, last + 1):
        # The part of the segment within reach of this column (an edge column holds
        # everything beyond the grid too).
        low, high = -math.inf, math.inf
        if column > 0:
            low = origin + column * cell - reach
        if column < side - 1:
            high = origin + (column + 1) * cell + reach
        a, b = 0.0, 1.0
        if v[0] != 0.0:
            a, b = (low - x0) / v[0], (high - x0) / v[0]
            a, b = max(min(a, b), 0.0), min(max(a, b), 1.0)
            if a > b:
                continue
        elif not low <= x0 <= high:
            continue
        ya, yb = p[1] + a * v[1], p[1] + b * v[1]
        bottom = _grid_cell(origin, cell, side, min(ya, yb) - reach)
        top = _grid_cell(origin, cell, side, max(ya, yb) + reach)
        for row in range(bottom, top + 1):
            c = column + side * row
            for slot in range(grid.start[c], grid.start[c + 1]):
                g = grid.items[slot]
                # Does the segment come within the geom's bounding sphere?
                c0 = poses.geom_xpos[g, 0] - p[0]
                c1 = poses.geom_xpos[g, 1] - p[1]
                c2 = poses.geom_xpos[g, 2] - p[2]
                x = min(max((c0 * v[0] + c1 * v[1] + c2 * v[2]) / vv, 0.0), 1.0)
                q0, q1, q2 = x * v[0] - c0, x * v[1] - c1, x * v[2] - c2
                radius = rays.geom_rbound[g] + CULL_MARGIN
                if q0 * q0 + q1 * q1 + q2 * q2 <= radius * radius:
                    near[count] = g
                    count += 1
    return count


@jit_inline
def _nearest_of(
    poses: MujocoPoses, rays: RayCulling, near: Ints, count: int, exclude: int, pnt: np.int64,
    vec: np.int64,
) -> tuple[float, int, bool]:  # fmt: skip
    """``mj_ray``'s own test (``mju_rayGeom``) of the geoms ``near[:count]`` on the ray from
    ``pnt`` along ``vec`` (addresses), eliminating those ``mj_ray`` eliminates (body
    ``exclude``, transparent geoms or materials, groups the rays do not see): the nearest hit
    (x in units of ``vec``, -1 if none) and its geom, ties to the lower geom id, and whether a
    geom found is no primitive (then only ``mj_ray`` can answer)."""
    base_pos = np.int64(poses.geom_xpos.ctypes.data)
    base_mat = np.int64(poses.geom_xmat.ctypes.data)
    base_size = np.int64(rays.geom_size.ctypes.data)
    row_size, frame_size = np.int64(_ROW), np.int64(3 * _ROW)
    best, best_geom, fallback = -1.0, -1, False
    for k in range(count):
        g = near[k]
        if rays.geom_bodyid[g] == exclude or not rays.in_group[g]:
            continue
        mat = rays.geom_matid[g]
        alpha = rays.geom_rgba[g, 3] if mat < 0 else rays.mat_rgba[mat, 3]
        if alpha == 0:
            continue
        if not rays.primitive[g]:
            fallback = True
            continue
        x = _MJ_RAY_GEOM(
            base_pos + g * row_size, base_mat + g * frame_size, base_size + g * row_size, pnt,
            vec, np.int32(rays.geom_type[g]), np.int64(0),
        )  # fmt: skip
        if x >= 0.0 and (best < 0.0 or x < best or (x == best and g < best_geom)):
            best, best_geom = x, g
    return best, best_geom, fallback


@jit_inline
def first_hit(
    poses: MujocoPoses, grids: SceneIndex, groups: npt.NDArray[np.uint8], exclude: int,
    p: Floats, v: Floats, pnt: np.int64, vec: np.int64, hit: npt.NDArray[np.int32],
) -> int:  # fmt: skip
    """The geom that ``mj_ray`` hits first on the ray p + x v (``pnt``, ``vec``: the
    addresses of ``p`` and ``v``), ignoring body ``exclude``: the same geom, found by testing
    only the geoms near the segment x in [0, 1]. Also written to ``hit[0]``.

    ``mj_ray`` returns the nearest hit of every geom it does not eliminate (the excluded body,
    transparent geoms or materials, groups not in ``groups``), each intersected by
    ``mju_rayGeom``, ties to the lowest geom id. Here the geoms tested are those of
    :func:`_near_geoms`: every geom whose bounding sphere meets the segment, and the planes. A
    geom whose bounding sphere misses the segment has no surface point on it, so if the
    nearest hit found lies on the segment (x <= 1) no other geom can be hit before it, and it
    is ``mj_ray``'s answer. The rays of the geometric vision aim at a point inside their
    target, so they hit something on the segment; if not (or a geom found is no primitive),
    ``mj_ray`` itself answers.
    """
    rays = grids.rays
    count = _near_geoms(poses, rays, grids.geoms, grids.near, p, v)
    best, best_geom, fallback = _nearest_of(poses, rays, grids.near, count, exclude, pnt, vec)
    if fallback or best < 0.0 or best > 1.0:
        _MJ_RAY(
            poses.model_address, poses.data_address, pnt, vec, np.int64(groups.ctypes.data),
            np.uint8(1), np.int32(exclude), np.int64(hit.ctypes.data), np.int64(0),
        )  # fmt: skip
    else:
        hit[0] = best_geom
    return int(hit[0])


@jit_inline
def _cast(
    poses: MujocoPoses, grids: SceneIndex, groups: npt.NDArray[np.uint8], exclude: int,
    p: Floats, v: Floats, pnt: np.int64, vec: np.int64, hit: npt.NDArray[np.int32], cull: bool,
) -> int:  # fmt: skip
    """The geom ``mj_ray`` hits first on the ray p + x v (``pnt``, ``vec``: their addresses),
    ignoring body ``exclude``: :func:`first_hit`'s answer where ``cull`` (the grids binned),
    else ``mj_ray``'s own; the same geom. Also written to ``hit[0]``."""
    if cull:
        return first_hit(poses, grids, groups, exclude, p, v, pnt, vec, hit)
    _MJ_RAY(
        poses.model_address, poses.data_address, pnt, vec, np.int64(groups.ctypes.data),
        np.uint8(1), np.int32(exclude), np.int64(hit.ctypes.data), np.int64(0),
    )  # fmt: skip
    return int(hit[0])


# --- rangefinders in a world of many arenas ---------------------------------------------------
class RangeFinders(NamedTuple):
    """The rangefinders :func:`ranges` reads (R of them, each a site's ``rangefinder`` sensor)
    and the grid of the geoms their rays may hit (every group: the sensor sees them all)."""

    site: Ints  #: (R,) the sensor's site
    exclude: Ints  #: (R,) the body its ray ignores (its site's body, as MuJoCo's sensor does)
    address: Ints  #: (R,) where its reading goes in ``sensordata``
    length: float  #: m, the part of every ray searched through the grid (an arena's diagonal)
    geoms: UniformGrid  #: every geom except ``rays.always``, binned at each call
    rays: RayCulling
    near: Ints  #: (G,) scratch: the geoms one ray tests
    groups: npt.NDArray[np.uint8]  #: (6,) every geom group (``mj_ray``'s fallback sees all)
    unit: Floats  #: (R, 3) scratch: each ray's direction, its site's z axis
    segment: Floats  #: (3,) scratch: the searched part of one ray
    hit: npt.NDArray[np.int32]  #: (1,) scratch: the geom ``mj_ray`` hit


@jit
def ranges(poses: MujocoPoses, finders: RangeFinders, sensordata: Floats) -> None:
    """Every rangefinder's reading into ``sensordata``, as MuJoCo's sensor stage computes it:
    ``mj_ray`` from the site along its z axis, every geom group, static geoms included, the
    site's body excluded; the distance to the nearest surface, -1 if none.

    The geoms tested are those near the ray's first ``finders.length`` metres
    (:func:`_near_geoms`), each with ``mj_ray``'s own test on the unit direction (so the
    distance is ``mj_ray``'s, bit for bit); a geom not tested has no surface point on that
    part of the ray, so a hit found there is the nearest. A ray with no hit there (it leaves
    its arena over a wall) or near a geom that is no primitive is ``mj_ray``'s. MuJoCo's scan
    tests every geom of the world for each of the 8 rays of each robot, a cost per robot that
    grows with the colony; this one grows with the geoms near each ray.
    """
    _bin(finders.geoms, poses.geom_xpos)
    length = finders.length
    unit, segment = finders.unit, finders.segment
    row_size = np.int64(_ROW)
    sites_ptr, unit_ptr = np.int64(poses.site_xpos.ctypes.data), np.int64(unit.ctypes.data)
    groups_ptr, hit_ptr = np.int64(finders.groups.ctypes.data), np.int64(finders.hit.ctypes.data)
    for r in range(finders.site.shape[0]):
        s = finders.site[r]
        for k in range(3):
            unit[r, k] = poses.site_xmat[s, 3 * k + 2]
            segment[k] = length * unit[r, k]
        pnt, vec = sites_ptr + s * row_size, unit_ptr + r * row_size
        exclude = finders.exclude[r]
        count = _near_geoms(
            poses, finders.rays, finders.geoms, finders.near, poses.site_xpos[s], segment
        )
        best, _, fallback = _nearest_of(poses, finders.rays, finders.near, count, exclude, pnt, vec)
        if fallback or best < 0.0 or best > length:
            best = _MJ_RAY(
                poses.model_address, poses.data_address, pnt, vec, groups_ptr, np.uint8(1),
                np.int32(exclude), hit_ptr, np.int64(0),
            )  # fmt: skip
        sensordata[finders.address[r]] = best


def ranges_reference(poses: MujocoPoses, finders: RangeFinders, sensordata: Floats) -> None:
    """:func:`ranges` as MuJoCo's sensor stage does it: ``mj_ray`` (through ``ctypes``) over
    every geom, for each rangefinder."""
    unit = finders.unit
    np.copyto(unit, poses.site_xmat[finders.site][:, 2::3])
    sites_ptr, unit_ptr = poses.site_xpos.ctypes.data, unit.ctypes.data
    groups_ptr, hit_ptr = finders.groups.ctypes.data, finders.hit.ctypes.data
    for r, s in enumerate(finders.site.tolist()):
        sensordata[finders.address[r]] = _MJ_RAY_REFERENCE(
            poses.model_address, poses.data_address, sites_ptr + s * _ROW, unit_ptr + r * _ROW,
            groups_ptr, 1, int(finders.exclude[r]), hit_ptr, 0,
        )  # fmt: skip


# --- the pixels of a small target ----------------------------------------------------------------
#: m, how far past a target's far side a pixel's ray reaches (its length only bounds the geoms
#: :func:`first_hit` tests; the geom hit is ``mj_ray``'s at any length).
TRACE_MARGIN = 0.05


def _centre_out(k: int) -> int:
    """The k-th offset of 0, +1, -1, +2, -2, ...: a footprint's pixels are tried from its
    middle out, so a lazy count finds the pixels of an unhidden target first."""
    return (k + 1) // 2 if k % 2 == 1 else -(k // 2)


def _pixel_vector(
    camera: CameraModel, rot: Floats, column: int, row: int, reach: float, out: Floats
) -> None:
    """The vector from a camera (frame ``rot``, row-major) through the centre of pixel
    (``column``, ``row``) of its strip, reaching ``reach`` m horizontally, in the world frame,
    into ``out``. The strip wraps: ``column`` may lie outside it.

    In view coordinates (x forward, y left, z up) the pixel's centre is at (1, tan(rel), v):
    tan(rel) from its column (:class:`~cyber_rodent.vision.projection.OmniProjection`'s
    ``column_u`` negated), v from its row."""
    strip = int(camera.n_views * camera.view_width)
    c = column % strip
    view = int(c // camera.view_width)
    x = c - view * camera.view_width + 0.5
    tan_rel = camera.half_tan - x / camera.px_per_u
    v = camera.v_top - (row + 0.5) / camera.px_per_v
    cv, sv = camera.view_cos[view], camera.view_sin[view]
    dx = cv - sv * tan_rel
    dy = sv + cv * tan_rel
    scale = reach / math.sqrt(1.0 + tan_rel * tan_rel)
    for k in range(3):
        out[k] = scale * (rot[3 * k] * dx + rot[3 * k + 1] * dy + rot[3 * k + 2] * v)


def _footprint(camera: CameraModel, f: FrontBuffers, i: int, t: int) -> tuple[int, int, int, int]:
    """The first and last column and row of the pixel centres target ``t``'s footprint covers
    in robot ``i``'s strip (:func:`_project` wrote its edges); columns may lie outside the
    strip, which wraps."""
    c0 = math.ceil(f.left_px[i, t] - 0.5)
    c1 = math.floor(f.right_px[i, t] - 0.5)
    r0 = max(math.ceil(f.top_px[i, t] - 0.5), 0)
    r1 = min(math.floor(f.bottom_px[i, t] - 0.5), int(camera.rows) - 1)
    return c0, c1, r0, r1


_centre_out_compiled = jit_inline(_centre_out)
_pixel_vector_compiled = jit_inline(_pixel_vector)
_footprint_compiled = jit_inline(_footprint)


@jit_inline
def _traced(
    scene: GeometricScene, i: int, t: int, need: float, lazy: bool, cull: bool
) -> float:
    """How many pixels of target ``t``'s footprint show it to robot ``i``: a ray through each
    covered pixel centre, middle out, counts when the first geom it hits is the target's, as a
    rasteriser draws the nearest surface at a pixel's centre. With ``lazy``, the count stops
    once it reaches ``need`` or cannot. The rays are :func:`first_hit`'s with ``cull`` (the
    grids binned), else ``mj_ray``'s: the same geom."""
    poses, targets, camera, f = scene.poses, scene.targets, scene.camera, scene.front
    c0, c1, r0, r1 = _footprint_compiled(camera, f, i, t)
    if c1 < c0 or r1 < r0:
        return 0.0
    total = (c1 - c0 + 1) * (r1 - r0 + 1)
    reach = f.distance[i, t] + 2.0 * targets.half_width[t] + TRACE_MARGIN
    mid_c, mid_r = (c0 + c1) // 2, (r0 + r1) // 2
    n_c = 2 * max(mid_c - c0, c1 - mid_c) + 1
    n_r = 2 * max(mid_r - r0, r1 - mid_r) + 1
    goal = targets.target_geom[t]
    exclude = targets.exclude_body[i]
    rot = f.rot[i]
    row_size = np.int64(_ROW)
    pnt = np.int64(f.cam.ctypes.data) + i * row_size
    vec = np.int64(f.pixel_ray.ctypes.data)
    shown, tried = 0, 0
    for a in range(n_r):
        r = mid_r + _centre_out_compiled(a)
        if r < r0 or r > r1:
            continue
        for b in range(n_c):
            c = mid_c + _centre_out_compiled(b)
            if c < c0 or c > c1:
                continue
            _pixel_vector_compiled(camera, rot, c, r, reach, f.pixel_ray)
            hit = _cast(
                poses, scene.grids, targets.geom_groups, exclude, f.cam[i], f.pixel_ray, pnt,
                vec, f.ray_geom, cull,
            )  # fmt: skip
            tried += 1
            if hit == goal:
                shown += 1
            if lazy and (shown >= need or shown + total - tried < need):
                return float(shown)
    return float(shown)


def _traced_reference(
    scene: GeometricScene, i: int, t: int, need: float, lazy: bool, cull: bool
) -> float:
    """:func:`_traced` in Python, its rays through ``ctypes``' ``mj_ray`` (``cull`` is
    ignored: the geom hit is the same)."""
    poses, targets, camera, f = scene.poses, scene.targets, scene.camera, scene.front
    c0, c1, r0, r1 = _footprint(camera, f, i, t)
    if c1 < c0 or r1 < r0:
        return 0.0
    total = (c1 - c0 + 1) * (r1 - r0 + 1)
    reach = float(f.distance[i, t] + 2.0 * targets.half_width[t] + TRACE_MARGIN)
    mid_c, mid_r = (c0 + c1) // 2, (r0 + r1) // 2
    goal = int(targets.target_geom[t])
    rows = [mid_r + _centre_out(a) for a in range(2 * max(mid_r - r0, r1 - mid_r) + 1)]
    columns = [mid_c + _centre_out(b) for b in range(2 * max(mid_c - c0, c1 - mid_c) + 1)]
    pnt = f.cam.ctypes.data + i * _ROW
    shown, tried = 0, 0
    for r in (r for r in rows if r0 <= r <= r1):
        for c in (c for c in columns if c0 <= c <= c1):
            _pixel_vector(camera, f.rot[i], c, r, reach, f.pixel_ray)
            _MJ_RAY_REFERENCE(
                poses.model_address, poses.data_address, pnt, f.pixel_ray.ctypes.data,
                targets.geom_groups.ctypes.data, 1, int(targets.exclude_body[i]),
                f.ray_geom.ctypes.data, 0,
            )  # fmt: skip
            tried += 1
            shown += int(f.ray_geom[0] == goal)
            if lazy and (shown >= need or shown + total - tried < need):
                return float(shown)
    return float(shown)


@jit
def traced_area(scene: GeometricScene, robots: Ints, target_ids: Ints, out: Floats) -> None:
    """``out[k]``: the pixels of target ``target_ids[k]`` that robot ``robots[k]`` sees, each
    pixel's ray cast (:func:`_traced`); :func:`front` must have placed them. The full pass
    measures with it the small targets that :func:`nearest` traces."""
    for k in range(robots.shape[0]):
        out[k] = _traced(scene, robots[k], target_ids[k], 0.0, False, False)


def traced_area_reference(
    scene: GeometricScene, robots: Ints, target_ids: Ints, out: Floats
) -> None:
    """:func:`traced_area` in Python."""
    for k in range(robots.shape[0]):
        out[k] = _traced_reference(scene, int(robots[k]), int(target_ids[k]), 0.0, False, False)


# --- nearest -----------------------------------------------------------------------------------
@jit_inline
def nearest(scene: GeometricScene, out: NearestTargets) -> None:
    """:func:`gather`, then each robot's nearest visible target of each class.

    Each class's possible targets are tried nearest first (ties to the lower index); a target's
    position, then its projected size, its samples and its occlusion rays are computed only
    when it is reached, and the rays stop as soon as its visibility is certain either way.

    Targets are reached through a uniform grid (``scene.grids.targets``), ring of cells by ring
    around the robot's cell (rings 0 and 1 at once). A target in a cell k + 1 or more rings out
    lies more than k cells away along x or y, so its horizontal distance h exceeds k * cell; in
    the camera's frame, tilted by theta from the vertical, its distance is at least
    h cos(theta) - |dz| sin(theta), dz its height above the camera. So once ring k is placed,
    every candidate up to k * cell * cos(theta) - max|dz| sin(theta) (less
    :data:`CULL_MARGIN`) is certainly nearer than any target not placed yet, and is tried; the
    search ends at the first visible candidate, when that bound passes the camera's range, or
    when the rings cover the grid. The targets tried and their order are those of trying every
    candidate nearest first: the answer is the same. In the paper's field the grid is 2 x 2
    cells, so every target is placed before any is tried. The rays are :func:`first_hit`'s
    where the world has many geoms (``grids.rays.cull``), else ``mj_ray``'s: the same geom.

    Named buffers are counted as references at every call of a compiled helper, which costs
    more than the work of one target: the helpers here take lists (:func:`_place`) or run
    once per candidate or ray.
    """
    poses, targets, f, grids = scene.poses, scene.targets, scene.front, scene.grids
    camera = scene.camera
    gather(poses, targets, f)
    _bin(grids.targets, f.centre)
    _bin(grids.geoms, poses.geom_xpos)
    n = f.cam.shape[0]
    n_t = f.centre.shape[0]
    n_s = f.rays.shape[1]
    z_low, z_high = math.inf, -math.inf
    for t in range(n_t):
        z_low, z_high = min(z_low, f.centre[t, 2]), max(z_high, f.centre[t, 2])
    # mj_ray reads 3 doubles at each point/direction address. Addresses are signed 64-bit:
    # numba would turn uintp + int64 into a float.
    cam_ptr, rays_ptr = np.int64(f.cam.ctypes.data), np.int64(f.rays.ctypes.data)
    row_size = np.int64(_ROW)
    cull = grids.rays.cull
    grid = grids.targets
    side = grid.side
    ring_list, found, tried, done = grids.ring, grids.found, grids.tried, grids.done
    order = f.order
    distance = f.distance
    for i in range(n):
        for c in range(3):
            out.visible[i, c] = False
            out.distance[i, c] = np.inf
            out.bearing[i, c] = 0.0
            found[c] = 0
            tried[c] = 0
            done[c] = targets.class_count[c] == 0
        cx = _grid_cell(grid.origin, grid.cell, side, f.cam[i, 0])
        cy = _grid_cell(grid.origin, grid.cell, side, f.cam[i, 1])
        cos_tilt = f.rot[i, 8]
        sin_tilt = math.sqrt(max(1.0 - cos_tilt * cos_tilt, 0.0))
        dz = max(z_high - f.cam[i, 2], f.cam[i, 2] - z_low, 0.0)
        rings = max(cx, side - 1 - cx, cy, side - 1 - cy)
        exclude = targets.exclude_body[i]
        # Ring 0 alone bounds nothing (its bound is below 0): the search starts with rings 0
        # and 1 together.
        ring = 1
        while not (done[0] and done[1] and done[2]):
            # The targets of the ring's cells (rows ``ring`` away whole, the rows between
            # only at their two ends; the first time, every cell within 1), of the classes
            # still open.
            listed = 0
            for row in range(max(cy - ring, 0), min(cy + ring, side - 1) + 1):
                whole = ring == 1 or row == cy - ring or row == cy + ring
                for column in range(max(cx - ring, 0), min(cx + ring, side - 1) + 1):
                    if not whole and column != cx - ring and column != cx + ring:
                        continue
                    c = column + side * row
                    for slot in range(grid.start[c], grid.start[c + 1]):
                        t = grid.items[slot]
                        if not done[targets.target_cls[t]]:
                            ring_list[listed] = t
                            listed += 1
            _place(targets, camera, scene.led_on, scene.pack_active, f, i, ring_list, listed)
            # Each candidate joins its class's list, by distance then index.
            for k in range(listed):
                t = ring_list[k]
                if not f.candidate[i, t]:
                    continue
                cls = targets.target_cls[t]
                d = distance[i, t]
                p = found[cls]
                while p > tried[cls]:
                    u = order[cls, p - 1]
                    if distance[i, u] < d or (distance[i, u] == d and u < t):
                        break
                    order[cls, p] = u
                    p -= 1
                order[cls, p] = t
                found[cls] += 1
            everything = ring >= rings
            bound = -math.inf
            if cos_tilt > 0.0:
                bound = ring * grid.cell * cos_tilt - dz * sin_tilt - CULL_MARGIN
            for c in range(3):
                while not done[c] and tried[c] < found[c]:
                    t = order[c, tried[c]]
                    if not (everything or distance[i, t] <= bound):
                        break
                    tried[c] += 1
                    full, need = _project(targets, camera, f, i, t), targets.min_area[t]
                    if not full >= need:  # too small to be seen even in full
                        f.candidate[i, t] = False
                        continue
                    # A small target with a sample hidden before its samples' estimate is
                    # certain, and one seen, is measured pixel by pixel (``traced``).
                    small = full < targets.trace_below[t]
                    traced = False
                    step = targets.inv_samples[t]
                    first, end = targets.sample_start[t], targets.sample_end[t]
                    left = 0
                    for s in range(first, end):
                        _sample(targets, camera, f, i, s)
                        left += f.sample_ok[i, s]
                    hits = 0
                    seen = full * (hits * step) >= need
                    while (
                        not seen and left > 0 and (traced or full * ((hits + left) * step) >= need)
                    ):
                        s = first
                        while not f.sample_ok[i, s]:
                            s += 1
                        first = s + 1
                        left -= 1
                        pnt, vec = cam_ptr + i * row_size, rays_ptr + (i * n_s + s) * row_size
                        hit = _cast(
                            poses, grids, targets.geom_groups, exclude, f.cam[i],
                            f.rays[i, s], pnt, vec, f.ray_geom, cull,
                        )  # fmt: skip
                        if hit == targets.sample_geom[s]:
                            hits += 1
                            seen = traced or full * (hits * step) >= need
                        elif small:
                            traced = True
                            seen = hits > 0
                    if seen and traced:
                        seen = _traced(scene, i, t, need, True, cull) >= need
                    if seen:
                        out.visible[i, c] = True
                        out.distance[i, c] = distance[i, t]
                        out.bearing[i, c] = f.bearing[i, t]
                        done[c] = True
                if everything or bound > camera.max_range:
                    done[c] = True
            ring += 1


def nearest_reference(scene: GeometricScene, out: NearestTargets) -> None:
    """:func:`nearest` in numpy and Python, with the same lazy ray order."""
    poses, targets, f = scene.poses, scene.targets, scene.front
    gather_reference(poses, targets, f)
    front_reference(targets, scene.camera, scene.led_on, scene.pack_active, f, False)
    n, n_t = f.candidate.shape
    n_s = f.rays.shape[1]
    masked = np.full((n, n_t + 1), np.inf)  # one padding column, never a candidate
    np.copyto(masked[:, :n_t], f.distance, where=f.candidate)
    # Each class's candidates nearest first (stable: ties to the lowest target index).
    order = np.argsort(masked[:, targets.class_targets], axis=2, kind="stable")
    cam_ptr, rays_ptr = f.cam.ctypes.data, f.rays.ctypes.data
    groups_ptr, geom_ptr = targets.geom_groups.ctypes.data, f.ray_geom.ctypes.data
    out.visible.fill(False)
    out.distance.fill(np.inf)
    out.bearing.fill(0.0)
    for i in range(n):
        for c in range(3):
            for j in order[i, c]:
                t = int(targets.class_targets[c, j])
                if masked[i, t] == math.inf:  # no candidate left (or the padding column)
                    break
                full, need, step = f.full_area[i, t], targets.min_area[t], targets.inv_samples[t]
                small, traced = bool(full < targets.trace_below[t]), False
                samples = range(int(targets.sample_start[t]), int(targets.sample_end[t]))
                in_view = [s for s in samples if f.sample_ok[i, s]]
                hits = 0
                seen = full * (hits * step) >= need
                while (
                    not seen
                    and in_view
                    and (traced or full * ((hits + len(in_view)) * step) >= need)
                ):
                    s = in_view.pop(0)
                    _MJ_RAY_REFERENCE(
                        poses.model_address, poses.data_address, cam_ptr + i * _ROW,
                        rays_ptr + (i * n_s + s) * _ROW, groups_ptr, 1,
                        int(targets.exclude_body[i]), geom_ptr, 0,
                    )  # fmt: skip
                    if f.ray_geom[0] == targets.sample_geom[s]:
                        hits += 1
                        seen = traced or full * (hits * step) >= need
                    elif small:
                        traced = True
                        seen = hits > 0
                if seen and traced:
                    seen = _traced_reference(scene, i, t, need, True, False) >= need
                if seen:
                    out.visible[i, c] = True
                    out.distance[i, c] = f.distance[i, t]
                    out.bearing[i, c] = f.bearing[i, t]
                    break


# --- merge -------------------------------------------------------------------------------------
@jit_inline
def _rim_row(
    camera: CameraModel, f: FrontBuffers, i: int, t: int, dz: float, rim: float
) -> float:
    """Row coordinate, in robot i's strip, of the point ``dz`` above target t's centre on the
    rim ``rim`` farther than its axis (negative: nearer)."""
    _, offset = _view_of(camera, f.bearing[i, t])
    depth = max((f.distance[i, t] + rim) * math.cos(offset), 1e-9)
    row: float = (camera.v_top - (f.local[i, t, 2] + dz) / depth) * camera.px_per_v
    return row


@jit_inline
def _sag(x: float, centre: float, half: float) -> float:
    """How far (0 at the middle, 1 at the ends) an ellipse's edge has fallen at column x."""
    q = (x - centre) / half
    return 1.0 - math.sqrt(min(max(1.0 - q * q, 0.0), 1.0))


@jit_inline
def _touch(
    targets: TargetTable, camera: CameraModel, rules: MergeRules, f: FrontBuffers, i: int,
    a: int, b: int,
) -> bool:  # fmt: skip
    """Whether the footprints of target a and of the farther target b (its upper band, for a
    pack) touch in robot i's strip (see :func:`merge`)."""
    width = rules.strip_width
    shift = width * np.rint(
        ((f.left_px[i, b] + f.right_px[i, b]) - (f.left_px[i, a] + f.right_px[i, a]))
        / (2.0 * width)
    )
    left_a, right_a, top_a = f.left_px[i, a], f.right_px[i, a], f.top_px[i, a]
    left_b, right_b, top_b = f.left_px[i, b] - shift, f.right_px[i, b] - shift, f.top_px[i, b]
    bottom_a, bottom_b = f.bottom_px[i, a], f.bottom_px[i, b]
    if left_b > right_a + 1.5 or left_a > right_b + 1.5:
        return False
    if top_b > bottom_a + 1.5 or top_a > bottom_b + 1.5:
        return False
    hh, r = targets.half_height, targets.rim
    bottom_half_b = 0.5 * (bottom_b - _rim_row(camera, f, i, b, -hh[b], r[b]))
    if rules.banded[b]:
        near = _rim_row(camera, f, i, b, rules.band_dz, -rules.band_radius)
        far = _rim_row(camera, f, i, b, rules.band_dz, rules.band_radius)
        bottom_b = min(near, bottom_b)
        bottom_half_b = 0.5 * (near - far)
    bottom_half_b = 0.0 if targets.plate[b] else max(bottom_half_b, 0.0)
    top_half_a = 0.0
    if not targets.plate[a]:
        top_half_a = max(0.5 * (_rim_row(camera, f, i, a, hh[a], -r[a]) - top_a), 0.0)
    cols = math.ceil(left_b - 0.5) <= math.floor(right_a - 0.5) + 1
    cols = cols and math.ceil(left_a - 0.5) <= math.floor(right_b - 0.5) + 1
    rows = math.ceil(top_b - 0.5) <= math.floor(bottom_a - 0.5) + 1
    rows = rows and math.ceil(top_a - 0.5) <= math.floor(bottom_b - 0.5) + 1
    if not (cols and rows):
        return False
    low, high = max(left_a, left_b), min(right_a, right_b)
    if not (top_b < top_a and low <= high):
        return True
    centre_a, centre_b = 0.5 * (left_a + right_a), 0.5 * (left_b + right_b)
    half_a = max(0.5 * (right_a - left_a), 1e-9)
    half_b = max(0.5 * (right_b - left_b), 1e-9)
    gap = math.inf
    for x in (low, high, min(max(centre_a, low), high), min(max(centre_b, low), high)):
        edge_a = top_a + top_half_a * _sag(x, centre_a, half_a)
        edge_b = bottom_b - bottom_half_b * _sag(x, centre_b, half_b)
        gap = min(gap, math.ceil(edge_a - 0.5) - math.floor(edge_b - 0.5))
    return gap <= 1.0


@jit_inline
def _hidden_by_another(
    targets: TargetTable, rules: MergeRules, f: FrontBuffers, m: MergeBuffers, i: int, a: int,
    b: int,
) -> bool:  # fmt: skip
    """Whether something other than targets of b's colour, b's own body or a's body hides one
    of b's samples from robot i (an inactive pack is not of any target's colour)."""
    first_pack = m.seen.shape[1] - m.pack_active.shape[0]
    for s in range(targets.sample_start[b], targets.sample_end[b]):
        g = m.hit_geom[i, s]
        if not f.sample_ok[i, s] or g < 0:
            continue
        hit = rules.target_of_geom[g]
        if hit >= 0 and rules.target_cls[hit] == rules.target_cls[b]:
            if hit < first_pack or m.pack_active[hit - first_pack]:
                continue
        body = rules.geom_body[g]
        if body != rules.target_body[b] and body != rules.target_body[a]:
            return True
    return False


@jit
def merge(
    targets: TargetTable, camera: CameraModel, rules: MergeRules, f: FrontBuffers,
    m: MergeBuffers,
) -> None:  # fmt: skip
    """Which seen targets' blobs join a nearer seen target's of their colour (``m.merged``),
    and how far each survivor's blob spreads (``m.spread``).

    Colour segmentation cannot separate touching blobs of one colour (two packs side by side,
    or a pack peeking out behind another, make one blue blob, measured at the nearer one's
    distance), so only the nearest target of each connected group is reported. The farther
    target b of a pair joins the nearer a when

    * their pixel footprints (``front``'s covered columns and rows) overlap or are
      8-neighbours; seen from above, a cylinder's top edge is the upper half of its top rim's
      ellipse and its bottom edge the lower half of its bottom rim's, so the corners of its box
      are empty. A pack's part that must touch is its upper band: below it, its own grey
      electrode ring cuts it off, so a pack whose lower band alone touches a nearer pack still
      shows its upper band as a blob of its own;
    * b is wholly in view, or hidden in part only by targets of its colour, by its own body (a
      pack's ring) or by a's body (the post an LED ring surrounds): if something else hides it
      (a third robot's chassis between two faces, an inactive pack, which is dark), that
      occluder may stand between their pixels, and they stay apart.

    Groups are joined transitively, as pixels are; the survivor of a group is its nearest
    member (ties: the lower index).
    """
    n, n_t = m.seen.shape
    group, listed = m.group, m.listed
    for i in range(n):
        k = 0
        for t in range(n_t):
            group[t] = t
            m.merged[i, t] = False
            m.spread[i, t] = 0.0
            if m.seen[i, t]:
                listed[k] = t
                k += 1
        # Pairs of seen targets only: the work grows with what a robot sees, not with the
        # colony (the seen list is in ascending order, as the targets are).
        joined = False
        for ia in range(k):
            a = listed[ia]
            for ib in range(k):
                b = listed[ib]
                if rules.target_cls[a] != rules.target_cls[b]:
                    continue
                if not f.distance[i, a] < f.distance[i, b]:
                    continue
                if not _touch(targets, camera, rules, f, i, a, b):
                    continue
                partly_hidden = m.visible_share[i, b] < 1.0
                if partly_hidden and _hidden_by_another(targets, rules, f, m, i, a, b):
                    continue
                ra, rb = a, b
                while group[ra] != ra:
                    ra = group[ra]
                while group[rb] != rb:
                    rb = group[rb]
                group[max(ra, rb)] = min(ra, rb)
                joined = True
        if not joined:
            continue
        # Every group's root is its lowest member, a seen target; its nearest member (ties:
        # the lower index) survives.
        for j in range(k):
            t = listed[j]
            root = t
            while group[root] != root:
                root = group[root]
            group[t] = root
            m.nearest[root], m.members[root], m.reach[root] = -1, 0, 0.0
        for j in range(k):
            t = listed[j]
            root = group[t]
            m.members[root] += 1
            if m.nearest[root] < 0 or f.distance[i, t] < f.distance[i, m.nearest[root]]:
                m.nearest[root] = t
        px_angle = _TWO_PI / rules.strip_width
        for j in range(k):
            t = listed[j]
            root = group[t]
            if m.members[root] < 2:
                continue
            nearest = m.nearest[root]
            if t != nearest:
                m.merged[i, t] = True
            half = 0.5 * (f.right_px[i, t] - f.left_px[i, t]) * px_angle
            off = abs(_wrap_compiled(f.bearing[i, t] - f.bearing[i, nearest])) + half
            m.reach[root] = max(m.reach[root], off)
        for j in range(k):
            root = listed[j]
            if group[root] != root or m.members[root] < 2:
                continue
            nearest = m.nearest[root]
            own = 0.5 * (f.right_px[i, nearest] - f.left_px[i, nearest]) * px_angle
            m.spread[i, nearest] = max(m.reach[root] - own, 0.0)


def merge_reference(
    targets: TargetTable, camera: CameraModel, rules: MergeRules, f: FrontBuffers,
    m: MergeBuffers,
) -> None:  # fmt: skip
    """:func:`merge` in numpy: every pair's tests at once, then the groups in Python."""
    m.merged.fill(False)
    m.spread.fill(0.0)
    seen, cls, distance = m.seen, rules.target_cls, f.distance
    pairs = seen[:, :, None] & seen[:, None, :]
    pairs &= cls[None, :, None] == cls[None, None, :]
    pairs &= distance[:, :, None] < distance[:, None, :]
    robot, a, b = np.nonzero(pairs)
    if not len(robot):
        return
    width = rules.strip_width
    mid_a = f.left_px[robot, a] + f.right_px[robot, a]
    mid_b = f.left_px[robot, b] + f.right_px[robot, b]
    shift = width * np.rint((mid_b - mid_a) / (2.0 * width))
    left_a, right_a, top_a = f.left_px[robot, a], f.right_px[robot, a], f.top_px[robot, a]
    left_b, right_b = f.left_px[robot, b] - shift, f.right_px[robot, b] - shift
    top_b, bottom_a, bottom_b = f.top_px[robot, b], f.bottom_px[robot, a], f.bottom_px[robot, b]
    near = (left_b <= right_a + 1.5) & (left_a <= right_b + 1.5)
    near &= (top_b <= bottom_a + 1.5) & (top_a <= bottom_b + 1.5)

    def rim_row(t: Ints, dz: Floats | float, rim: Floats | float) -> Floats:
        _, offset = _view_offset(camera, f.bearing[robot, t])
        depth = np.maximum((distance[robot, t] + rim) * np.cos(offset), 1e-9)
        row: Floats = (camera.v_top - (f.local[robot, t, 2] + dz) / depth) * camera.px_per_v
        return row

    hh, r, plate = targets.half_height, targets.rim, targets.plate
    bottom_half_b = 0.5 * (bottom_b - rim_row(b, -hh[b], r[b]))
    banded = rules.banded[b]
    near_band = rim_row(b, rules.band_dz, -rules.band_radius)
    far_band = rim_row(b, rules.band_dz, rules.band_radius)
    bottom_b = np.where(banded, np.minimum(near_band, bottom_b), bottom_b)
    bottom_half_b = np.where(banded, 0.5 * (near_band - far_band), bottom_half_b)
    bottom_half_b = np.where(plate[b], 0.0, np.maximum(bottom_half_b, 0.0))
    top_half_a = np.where(
        plate[a], 0.0, np.maximum(0.5 * (rim_row(a, hh[a], -r[a]) - top_a), 0.0)
    )
    cols = (np.ceil(left_b - 0.5) <= np.floor(right_a - 0.5) + 1) & (
        np.ceil(left_a - 0.5) <= np.floor(right_b - 0.5) + 1
    )
    rows = (np.ceil(top_b - 0.5) <= np.floor(bottom_a - 0.5) + 1) & (
        np.ceil(top_a - 0.5) <= np.floor(bottom_b - 0.5) + 1
    )
    touch = near & cols & rows
    low, high = np.maximum(left_a, left_b), np.minimum(right_a, right_b)
    above = touch & (top_b < top_a) & (low <= high)
    centre_a, centre_b = 0.5 * (left_a + right_a), 0.5 * (left_b + right_b)
    half_a = np.maximum(0.5 * (right_a - left_a), 1e-9)
    half_b = np.maximum(0.5 * (right_b - left_b), 1e-9)
    gap = np.full(len(robot), np.inf)
    for x in (low, high, np.clip(centre_a, low, high), np.clip(centre_b, low, high)):
        sag_a = 1.0 - np.sqrt(np.clip(1.0 - ((x - centre_a) / half_a) ** 2, 0.0, 1.0))
        sag_b = 1.0 - np.sqrt(np.clip(1.0 - ((x - centre_b) / half_b) ** 2, 0.0, 1.0))
        edge_a = top_a + top_half_a * sag_a
        edge_b = bottom_b - bottom_half_b * sag_b
        gap = np.minimum(gap, np.ceil(edge_a - 0.5) - np.floor(edge_b - 0.5))
    touch &= ~above | (gap <= 1.0)
    # Something of another colour, neither b's body nor a's, hides one of b's samples.
    start, end = targets.sample_start[b], targets.sample_end[b]
    samples = start[:, None] + np.arange(int((end - start).max()))[None, :]
    valid = samples < end[:, None]
    samples = np.where(valid, samples, 0)
    geom = m.hit_geom[robot[:, None], samples]
    cast = valid & f.sample_ok[robot[:, None], samples] & (geom >= 0)
    geom = np.maximum(geom, 0)
    hit = rules.target_of_geom[geom]
    same_colour = (hit >= 0) & (cls[np.maximum(hit, 0)] == cls[b][:, None])
    first_pack = seen.shape[1] - len(m.pack_active)
    dark = hit >= first_pack  # an inactive pack hides like any other body
    dark[dark] = ~m.pack_active[hit[dark] - first_pack]
    same_colour &= ~dark
    body = rules.geom_body[geom]
    foreign = cast & ~same_colour
    foreign &= body != rules.target_body[b][:, None]
    foreign &= body != rules.target_body[a][:, None]
    apart = (m.visible_share[robot, b] < 1.0) & foreign.any(axis=1)
    edges = touch & ~apart
    px_angle = _TWO_PI / width
    for i in np.unique(robot[edges]).tolist():
        group = np.arange(seen.shape[1])
        mine = edges & (robot == i)
        for t, u in zip(a[mine].tolist(), b[mine].tolist(), strict=True):
            rt, ru = t, u
            while group[rt] != rt:
                rt = int(group[rt])
            while group[ru] != ru:
                ru = int(group[ru])
            group[max(rt, ru)] = min(rt, ru)
        while not np.array_equal(group[group], group):
            group = group[group]
        for root in np.unique(group[seen[i]]).tolist():
            members = np.flatnonzero((group == root) & seen[i])
            if len(members) < 2:
                continue
            nearest = members[np.argmin(distance[i, members])]
            m.merged[i, members[members != nearest]] = True
            half = 0.5 * (f.right_px[i, members] - f.left_px[i, members]) * px_angle
            turn = f.bearing[i, members] - f.bearing[i, nearest]
            off = np.abs(np.mod(turn + math.pi, _TWO_PI) - math.pi) + half
            own = 0.5 * (f.right_px[i, nearest] - f.left_px[i, nearest]) * px_angle
            m.spread[i, nearest] = max(float(off.max()) - own, 0.0)


__all__ = [
    "UNAVAILABLE_REASON",
    "PRIMITIVE_GEOMS",
    "VERIFIED_MUJOCO",
    "CameraModel",
    "FrontBuffers",
    "GeometricScene",
    "MergeBuffers",
    "MergeRules",
    "MujocoPoses",
    "NearestTargets",
    "RangeFinders",
    "RayCulling",
    "SceneIndex",
    "TargetTable",
    "UniformGrid",
    "first_hit",
    "front",
    "front_reference",
    "gather",
    "gather_reference",
    "merge",
    "merge_reference",
    "nearest",
    "nearest_reference",
    "ranges",
    "ranges_reference",
]
