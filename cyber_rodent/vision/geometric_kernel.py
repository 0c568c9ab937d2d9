"""Compiled (numba) kernel of the geometric vision's hot path, ray casts included.

The evolution runner asks :class:`~cyber_rodent.vision.geometric.GeometricVision` for every
robot's nearest visible LED, face and pack once per control step, 1.2 million times per
paper-scale run. In numpy that is about a hundred small-array operations on (robots × targets)
arrays plus a Python loop over the lazy occlusion rays: microseconds of interpreter overhead each,
for a few hundred flops. Here the same computation is one compiled call:

* :func:`front` is ``GeometricVision._front_numpy`` (targets in each camera's frame, projected
  size, candidates, occlusion sample rays and their field-of-view test) as scalar loops;
* :func:`nearest` is the front followed by ``GeometricVision.nearest_targets``' lazy ray loop,
  calling MuJoCo's own ``mj_ray`` through its C entry point, so the occlusion test is exactly
  MuJoCo's.

The numpy implementation stays the reference: ``tests/test_vision_kernel.py`` checks that both
give the same visibility and the same numbers (to rounding: numpy's small matrix products may
round differently) on random scenes. The provider falls back to numpy where numba or the MuJoCo
shared library is unavailable (``GeometricVision(backend=...)``).

Compiled functions are cached on disk (numba's ``cache=True``, next to this file), so a new
process pays the compilation (a few seconds) only once per installation.
"""

from __future__ import annotations

import glob
import math
import os
import platform

import mujoco
import numpy as np

from cyber_rodent import compiled
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE", "front", "gather", "nearest", "unavailable_reason"]

_TWO_PI = 2.0 * math.pi


#: MuJoCo versions whose ``mj_ray`` C signature the kernel's prototype was checked against (the
#: header of 3.17.0: ``mjtNum mj_ray(const mjModel*, const mjData*, const mjtNum pnt[3],
#: const mjtNum vec[3], const mjtByte* geomgroup, mjtBool flg_static, int bodyexclude,
#: int geomid[1], mjtNum normal[3])``). A wrong prototype corrupts memory, so other versions
#: use the numpy path until checked.
VERIFIED_MUJOCO = ("3.17.0",)


def _load_mj_ray():
    """Make MuJoCo's ``mj_ray`` callable from compiled code, by symbol name.

    The library is the one next to the ``mujoco`` package, already loaded by the bindings;
    it is registered with LLVM so that the compiled kernel links ``mj_ray`` by name. Pointers
    are declared as 64-bit integers (the same registers as ``void*`` in the x86-64 and AArch64
    calling conventions), so the kernel passes array addresses as plain integers; because the
    code refers to the symbol and not to an address of this process, numba can cache it.

    Returns:
        (the numba external function or None, why it is unavailable).
    """
    if not compiled.AVAILABLE:  # pragma: no cover
        return None, "numba is not installed"
    if mujoco.__version__ not in VERIFIED_MUJOCO:
        return None, (
            f"the kernel's mj_ray prototype is verified for mujoco {', '.join(VERIFIED_MUJOCO)}, "
            f"not {mujoco.__version__}"
        )
    if platform.machine().lower() not in ("x86_64", "amd64", "aarch64", "arm64"):
        return None, f"pointer-as-integer calls are not checked on {platform.machine()}"
    here = os.path.dirname(mujoco.__file__)
    found = sorted(glob.glob(os.path.join(here, f"libmujoco.so.{mujoco.__version__}")))
    if not found:
        return None, f"no libmujoco.so.{mujoco.__version__} next to {here}"
    import llvmlite.binding as llvm
    from numba import types

    llvm.load_library_permanently(found[0])
    i64 = types.int64
    signature = types.float64(
        i64,  # const mjModel* m
        i64,  # const mjData* d
        i64,  # const mjtNum pnt[3]
        i64,  # const mjtNum vec[3]
        i64,  # const mjtByte* geomgroup
        types.uint8,  # mjtBool flg_static
        types.int32,  # int bodyexclude
        i64,  # int geomid[1]
        i64,  # mjtNum normal[3] (0 = NULL: not computed)
    )
    return types.ExternalFunction("mj_ray", signature), ""


_MJ_RAY, _REASON = _load_mj_ray()

#: The compiled kernel can be used (numba present and ``mj_ray`` found).
AVAILABLE = _MJ_RAY is not None


def unavailable_reason() -> str:
    """Why :data:`AVAILABLE` is False ("" if it is True)."""
    return _REASON


@_jit
def _wrap(a: float) -> float:
    """Wrap an angle to [-π, π) (numpy's ``(a + π) % 2π - π``)."""
    return (a + math.pi) % _TWO_PI - math.pi


@_jit
def front(
    cam,
    rot,
    centre,
    gmat,
    led_on,
    own,
    plate,
    half_width,
    half_height,
    rim,
    half_depth,
    min_area,
    s_target,
    s_lat,
    s_dz,
    view_centres,
    scalars,
    local,
    bearing,
    distance,
    width_px,
    height_px,
    half_angle,
    full_area,
    candidate,
    diff,
    lateral,
    rays,
    sample_ok,
):
    """Fill the front buffers for every (robot, target) and (robot, sample).

    Args:
        cam: (n, 3) camera positions; rot: (n, 9) camera frames (row-major ``site_xmat``).
        centre: (T, 3) target geom positions; gmat: (T, 9) their frames.
        led_on: (n,) bool; own: (n, T) bool, the target belongs to the robot.
        plate, half_width, half_height, rim, half_depth, min_area: (T,) target constants.
        s_target: (S,) target of each occlusion sample; s_lat, s_dz: (S,) its offsets (m).
        view_centres: (n_views,) rad.
        scalars: (10,) max_range, view_span, n_views, px_per_u, px_per_v, v_top, v_bottom,
            tan_el_min, tan_el_max, edge_clip.
        local .. candidate: (n, T[, 3]) outputs as in ``_Front``; diff, lateral: (n, T, 3)
            scratch; rays: (n, S, 3) and sample_ok: (n, S) outputs.
    """
    max_range = scalars[0]
    span = scalars[1]
    n_views = int(scalars[2])
    px_per_u = scalars[3]
    px_per_v = scalars[4]
    v_top = scalars[5]
    v_bottom = scalars[6]
    tan_el_min = scalars[7]
    tan_el_max = scalars[8]
    edge_clip = scalars[9]
    n = cam.shape[0]
    n_t = centre.shape[0]
    n_s = s_target.shape[0]
    for i in range(n):
        r = rot[i]
        for t in range(n_t):
            d0 = centre[t, 0] - cam[i, 0]
            d1 = centre[t, 1] - cam[i, 1]
            d2 = centre[t, 2] - cam[i, 2]
            diff[i, t, 0] = d0
            diff[i, t, 1] = d1
            diff[i, t, 2] = d2
            g = gmat[t]
            if plate[t]:
                a0, a1, a2 = g[1], g[4], g[7]  # the plate's own width axis
            else:  # perpendicular to the line of sight
                rh = max(math.hypot(d0, d1), 1e-9)
                a0, a1, a2 = -d1 / rh, d0 / rh, 0.0
            lateral[i, t, 0] = a0
            lateral[i, t, 1] = a1
            lateral[i, t, 2] = a2
            # Camera frame: x_j = sum_k R_kj d_k.
            l0 = d0 * r[0] + d1 * r[3] + d2 * r[6]
            l1 = d0 * r[1] + d1 * r[4] + d2 * r[7]
            l2 = d0 * r[2] + d1 * r[5] + d2 * r[8]
            local[i, t, 0] = l0
            local[i, t, 1] = l1
            local[i, t, 2] = l2
            la0 = a0 * r[0] + a1 * r[3] + a2 * r[6]
            la1 = a0 * r[1] + a1 * r[4] + a2 * r[7]
            nx, ny, nz = g[0], g[3], g[6]  # the target's x axis (a plate's normal)
            nl0 = nx * r[0] + ny * r[3] + nz * r[6]
            nl1 = nx * r[1] + ny * r[4] + nz * r[7]
            b = math.atan2(l1, l0)
            dist = math.hypot(l0, l1)
            bearing[i, t] = b
            distance[i, t] = dist
            # Projected size (see GeometricVision._projected_size).
            rel = (view_centres[0] - b + 0.5 * span) % _TWO_PI
            view = min(int(rel // span), n_views - 1)
            offset = 0.5 * span - (rel - view * span)
            axis = view_centres[view]
            hw, hd = half_width[t], half_depth[t]
            ex, ey = la0 * hw, la1 * hw
            fx, fy = nl0 * hd, nl1 * hd
            b_left = math.atan2(ey + l1, ex + l0)
            b_right = math.atan2(-ey + l1, -ex + l0)
            b_front = math.atan2(fy + l1, fx + l0)
            b_back = math.atan2(-fy + l1, -fx + l0)
            u_left = math.tan(min(max(_wrap(b_left - axis), -edge_clip), edge_clip))
            u_right = math.tan(min(max(_wrap(b_right - axis), -edge_clip), edge_clip))
            u_front = math.tan(min(max(_wrap(b_front - axis), -edge_clip), edge_clip))
            u_back = math.tan(min(max(_wrap(b_back - axis), -edge_clip), edge_clip))
            du = abs(u_left - u_right)
            du += abs(u_front - u_back)
            cos_off = math.cos(offset)
            depth_far = max((dist + rim[t]) * cos_off, 1e-9)
            depth_near = max((dist - rim[t]) * cos_off, 1e-9)
            vt = (l2 + half_height[t]) / depth_far
            vb = (l2 - half_height[t]) / depth_near
            dv = max(min(vt, v_top) - max(vb, v_bottom), 0.0)
            half_angle[i, t] = 0.5 * abs(_wrap(b_left - b_right))
            w_px = du * px_per_u
            h_px = dv * px_per_v
            width_px[i, t] = w_px
            height_px[i, t] = h_px
            area = w_px * h_px
            full_area[i, t] = area
            ok = area >= min_area[t] and dist <= max_range and not own[i, t]
            if t < n and not led_on[t]:
                ok = False  # a dark LED is not a green target
            if ok and plate[t]:  # a plate shows only its front
                ok = d0 * nx + d1 * ny + d2 * nz < 0.0
            candidate[i, t] = ok
        for s in range(n_s):
            t = s_target[s]
            x = diff[i, t, 0] + s_lat[s] * lateral[i, t, 0]
            y = diff[i, t, 1] + s_lat[s] * lateral[i, t, 1]
            z = diff[i, t, 2] + s_lat[s] * lateral[i, t, 2]
            z += s_dz[s]
            rays[i, s, 0] = x
            rays[i, s, 1] = y
            rays[i, s, 2] = z
            c0 = x * r[0] + y * r[3] + z * r[6]
            c1 = x * r[1] + y * r[4] + z * r[7]
            c2 = x * r[2] + y * r[5] + z * r[8]
            rh = max(math.hypot(c0, c1), 1e-9)
            tan_el = c2 / rh
            inside = tan_el >= tan_el_min and tan_el <= tan_el_max
            if not inside:  # near the robot: the exact per-view frustum test
                rel = (view_centres[0] - math.atan2(c1, c0) + 0.5 * span) % _TWO_PI
                view = min(int(rel // span), n_views - 1)
                offset = 0.5 * span - (rel - view * span)
                v = tan_el / math.cos(offset)
                inside = v >= v_bottom and v <= v_top
            sample_ok[i, s] = inside


# Compiled lazily at the first call; the provider calls it only when AVAILABLE.
@_jit
def nearest(
    maddr,
    daddr,
    cam,
    rot,
    centre,
    gmat,
    led_on,
    own,
    plate,
    half_width,
    half_height,
    rim,
    half_depth,
    min_area,
    s_target,
    s_lat,
    s_dz,
    view_centres,
    scalars,
    local,
    bearing,
    distance,
    width_px,
    height_px,
    half_angle,
    full_area,
    candidate,
    diff,
    lateral,
    rays,
    sample_ok,
    class_cols,
    class_count,
    sample_start,
    sample_end,
    inv_samples,
    s_geom,
    exclude,
    groups,
    geom_id,
    order,
    out_bearing,
    out_distance,
    out_visible,
):
    """The front, then each robot's nearest visible target of each class with lazy rays
    (``GeometricVision.nearest_targets``' algorithm; outputs (n, 3))."""
    front(
        cam, rot, centre, gmat, led_on, own, plate, half_width, half_height, rim,
        half_depth, min_area, s_target, s_lat, s_dz, view_centres, scalars, local,
        bearing, distance, width_px, height_px, half_angle, full_area, candidate, diff,
        lateral, rays, sample_ok,
    )  # fmt: skip
    n = cam.shape[0]
    n_s = rays.shape[1]
    # mj_ray reads 3 doubles at each point/direction address (24 bytes per row). The
    # addresses are signed 64-bit: numba would turn uintp + int64 into a float.
    cam_ptr, rays_ptr = np.int64(cam.ctypes.data), np.int64(rays.ctypes.data)
    groups_ptr, geom_ptr = np.int64(groups.ctypes.data), np.int64(geom_id.ctypes.data)
    row = np.int64(24)
    null = np.int64(0)
    for i in range(n):
        for c in range(3):
            out_visible[i, c] = False
            out_distance[i, c] = np.inf
            out_bearing[i, c] = 0.0
            # This class's candidates, nearest first (stable: ties to the lower index).
            k = 0
            for j in range(class_count[c]):
                t = class_cols[c, j]
                if not candidate[i, t]:
                    continue
                p = k
                while p > 0 and distance[i, order[p - 1]] > distance[i, t]:
                    order[p] = order[p - 1]
                    p -= 1
                order[p] = t
                k += 1
            for j in range(k):
                t = order[j]
                # Visible iff full_area * (hits * inv) >= min_area; stop as soon as the
                # answer is certain either way.
                full, need, step = full_area[i, t], min_area[t], inv_samples[t]
                first, end = sample_start[t], sample_end[t]
                left = 0
                for s in range(first, end):
                    left += sample_ok[i, s]
                hits = 0
                seen = full * (hits * step) >= need
                while not seen and left > 0 and full * ((hits + left) * step) >= need:
                    s = first
                    while not sample_ok[i, s]:
                        s += 1
                    first = s + 1
                    left -= 1
                    _MJ_RAY(
                        maddr, daddr, cam_ptr + i * row, rays_ptr + (i * n_s + s) * row,
                        groups_ptr, np.uint8(1), np.int32(exclude[i]), geom_ptr, null,
                    )  # fmt: skip
                    if geom_id[0] == s_geom[s]:
                        hits += 1
                        seen = full * (hits * step) >= need
                if seen:
                    out_visible[i, c] = True
                    out_distance[i, c] = distance[i, t]
                    out_bearing[i, c] = bearing[i, t]
                    break


@_jit
def gather(
    site_xpos, site_xmat, geom_xpos, geom_xmat, cam_site, target_geom, cam, rot, centre, gmat
):
    """Copy the cameras' poses (``cam`` (n, 3), ``rot`` (n, 9)) and the targets' poses
    (``centre`` (T, 3), ``gmat`` (T, 9)) out of MuJoCo's data arrays (what
    ``GeometricVision._gather`` does with ``take``)."""
    for i in range(cam_site.shape[0]):
        s = cam_site[i]
        for k in range(3):
            cam[i, k] = site_xpos[s, k]
        for k in range(9):
            rot[i, k] = site_xmat[s, k]
    for t in range(target_geom.shape[0]):
        g = target_geom[t]
        for k in range(3):
            centre[t, k] = geom_xpos[g, k]
        for k in range(9):
            gmat[t, k] = geom_xmat[g, k]
