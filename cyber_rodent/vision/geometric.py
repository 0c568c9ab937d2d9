"""The geometric vision provider: what the omni camera would see, computed from poses.

This is the fast path for long evolution runs (docs/design.md §6). It reports the same quantities
as the rendered camera, so the two are interchangeable (``benchmarks/vision_agreement.py``
measures how well they agree):

* **bearing and distance** of each target's vertical axis, from the MuJoCo state (the
  convention of :mod:`cyber_rodent.vision.targets`);
* **field of view**: a target is seen only through the part of it inside the camera's frustum
  (exact per-view check, the same frustum the renderer uses);
* **occlusion**: one ``mj_multiRay`` per robot casts a few rays at sample points spread over
  every target's coloured part; a sample counts when the first geom its ray hits is the target
  itself. Walls, robots (bodies, posts, mirrors, wheels) and packs all occlude; the robot's own
  body does not (it is hidden from its own camera, as in the rendered image);
* **resolution**: a target is detected only if its expected visible area in the image (its
  projected size in pixels of the configured resolution, times the visible share of its
  samples) reaches the class's ``min_blob_area``, which gives the camera's real range limit;
* a face plate is seen only from the front; a robot never sees its own LED or face;
* a target whose image touches a nearer visible target of the same colour merges into that
  one's blob (colour segmentation cannot separate them) and is not reported separately.

Every index is computed at construction; a call of :meth:`GeometricVision.observe` is a fixed
sequence of small vectorised numpy operations plus one ``mj_multiRay`` per robot, cast only at
the targets that could be seen at all (``benchmarks/vision_cost.py`` measures it).

The hot path (the geometry before the rays, and :meth:`GeometricVision.nearest_targets` with
its lazy rays) runs as a compiled kernel where numba is available
(:mod:`cyber_rodent.vision.geometric_kernel`, ``backend="auto"``); the numpy implementation
(``backend="numpy"``) is the reference the kernel is tested against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from cyber_rodent.vision import geometric_kernel
from cyber_rodent.vision.config import CameraConfig
from cyber_rodent.vision.detections import apply_noise, frame_from_detections
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.vision.targets import TargetShape, target_geometry
from cyber_rodent.vision.types import BATTERY, FACE, LED, VisionFrame
from cyber_rodent.world import World

#: Occlusion samples, as (lateral, vertical) fractions of a target's half width and half
#: height. Packs get 3 × 2 samples: the lower row below and the upper row above the grey
#: electrode ring, so that every sample aims at blue; the upper row at the top rim catches a
#: pack whose top peeks over an obstacle. Faces get 3 × 2 (their top edge peeks over packs);
#: the LED ring is a thin band: three samples across at mid height. A 3 × 3 grid gave the same
#: agreement with the rendered camera (98.7 % vs 98.6 %) for 40 % more rays.
_PACK_SAMPLES = tuple((lat, vert) for vert in (-0.7, 0.96) for lat in (-0.6, 0.0, 0.6))
_FACE_SAMPLES = tuple((lat, vert) for vert in (-0.6, 0.6) for lat in (-0.6, 0.0, 0.6))
_LED_SAMPLES = ((-0.6, 0.0), (0.0, 0.0), (0.6, 0.0))
#: Geom groups that are rendered (mjvOption's default), hence able to hide a target.
_VISIBLE_GROUPS = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)
_EDGE_CLIP = 0.5 * math.pi - 1e-3  # rad, keep tan() finite for targets beside the camera
#: Implementations of the hot path: "auto" (compiled if available), "compiled", "numpy".
BACKENDS = ("auto", "compiled", "numpy")


@dataclass
class _Front:
    """The per-call geometry before any ray is cast (see ``GeometricVision._front``)."""

    cam: np.ndarray  # (n, 3) camera positions
    local: np.ndarray  # (n, T, 3) target axes in each camera's frame
    bearing: np.ndarray  # (n, T)
    distance: np.ndarray  # (n, T)
    width_px: np.ndarray  # (n, T)
    height_px: np.ndarray  # (n, T)
    half_angle: np.ndarray  # (n, T)
    full_area: np.ndarray  # (n, T) pixels if fully visible
    candidate: np.ndarray  # (n, T) could be seen at all (range, size, own, lit, facing)
    rays: np.ndarray  # (n, S, 3) camera-to-sample vectors, world frame
    sample_ok: np.ndarray  # (n, S) sample point inside the field of view


@dataclass
class TargetMeasurements:
    """Every robot's noise-free view of every target, arrays (n_robots, n_targets).

    Attributes:
        visible: detected (in view, in range, unoccluded enough, large enough, lit, facing).
        bearing: rad, robot frame, to the target's axis (whether visible or not).
        distance: m, horizontal, camera axis to target axis.
        area: expected visible pixel area.
        visible_share: fraction of the target's occlusion samples that the camera sees.
        width_px, height_px: projected size of the whole target in pixels.
    """

    visible: np.ndarray
    bearing: np.ndarray
    distance: np.ndarray
    area: np.ndarray
    visible_share: np.ndarray
    width_px: np.ndarray
    height_px: np.ndarray


class GeometricVision:
    """Vision from poses, field of view, range and ray-cast occlusion.

    Args:
        world: the world to observe (bound: every call reads its current ``MjData``).
        config: the camera; the same config makes the rendered provider comparable.
        rng: generator for the noise model; required only if ``config.noise`` is enabled.
    """

    def __init__(
        self,
        world: World,
        config: CameraConfig | None = None,
        rng: np.random.Generator | None = None,
        backend: str = "auto",
    ):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
        if backend == "compiled" and not geometric_kernel.AVAILABLE:
            raise ValueError(
                "backend 'compiled' is unavailable: " + geometric_kernel.unavailable_reason()
            )
        #: "compiled" (the numba kernel, :mod:`~cyber_rodent.vision.geometric_kernel`) or
        #: "numpy" (the reference implementation).
        self.backend = "compiled" if backend != "numpy" and geometric_kernel.AVAILABLE else "numpy"
        self.world = world
        self.config = config or CameraConfig()
        if self.config.noise.enabled and rng is None:
            raise ValueError("config.noise is enabled, so pass rng=np.random.Generator")
        self.rng = rng
        self.projection = OmniProjection(self.config)
        self.geometry = target_geometry(world)
        n, k = world.config.n_robots, world.config.n_packs
        self.n_robots = n
        shapes = self.geometry.shapes
        # Targets: LED of every robot, face of every robot, every pack.
        self.target_geom = np.concatenate(
            [world.led_geom, world.face_geom, world.pack_geom]
        ).astype(np.int64)
        self.target_cls = np.concatenate(
            [np.full(n, LED), np.full(n, FACE), np.full(k, BATTERY)]
        ).astype(np.int64)
        self.target_owner = np.concatenate([np.arange(n), np.arange(n), np.full(k, -1)])
        n_targets = len(self.target_geom)
        shape_of = [shapes[c] for c in self.target_cls]
        self._plate = np.array([s.plate for s in shape_of])
        self._half_width = np.array([s.half_width for s in shape_of])
        #: (T,) m, half width of each target (cylinder radius, half the plate's width).
        self.half_width = self._half_width
        self._half_height = np.array([0.5 * s.height for s in shape_of])
        self._rim = np.array([s.rim_offset for s in shape_of])
        self._half_depth = np.array([s.half_depth for s in shape_of])
        # Flattened occlusion samples: which target, lateral and vertical offset (m).
        s_target, s_lat, s_dz = [], [], []
        for t, shape in enumerate(shape_of):
            for lat, vert in _samples_for(shape):
                s_target.append(t)
                s_lat.append(lat * shape.half_width)
                s_dz.append(vert * 0.5 * shape.height)
        self._s_target = np.array(s_target, dtype=np.int64)
        self._s_lat = np.array(s_lat)[None, :, None]
        self._s_dz = np.array(s_dz)[None, :]
        self._s_geom = self.target_geom[self._s_target]
        n_samples = len(s_target)
        self._sample_to_target = np.zeros((n_samples, n_targets))
        self._sample_to_target[np.arange(n_samples), self._s_target] = 1.0
        self._inv_samples = 1.0 / self._sample_to_target.sum(axis=0)
        self._own = self.target_owner[None, :] == np.arange(n)[:, None]
        self._same_class = self.target_cls[:, None] == self.target_cls[None, :]
        widen_ray_culling_bounds(world.model)
        self._cam_site = np.asarray(world.camera_site, dtype=np.int64)
        self._exclude = [int(b) for b in world.chassis_body]
        # Output buffers of the ray casts (reused every call).
        self._ray_geom = np.zeros(n_samples, dtype=np.int32)
        self._ray_dist = np.zeros(n_samples)
        self._cutoff = float(self.config.max_range) + 1.0
        self._min_area = np.asarray(self.config.min_blob_area, dtype=float)[self.target_cls]
        self._tan_el_min = math.tan(math.radians(self.config.elevation_min_deg))
        self._tan_el_max = math.tan(math.radians(self.config.elevation_max_deg))
        # Buffers of nearest_targets: per-class target columns padded with a never-seen column
        # (index n_targets), so that every class gathers into one (n, 3, width) block.
        per_class = [np.flatnonzero(self.target_cls == c) for c in (LED, FACE, BATTERY)]
        width = max(1, max(len(cols) for cols in per_class))
        self._lazy_class_cols = np.full((3, width), n_targets, dtype=np.intp)
        for c, cols in zip((LED, FACE, BATTERY), per_class, strict=True):
            self._lazy_class_cols[c, : len(cols)] = cols
        self._lazy_class_cols_list = self._lazy_class_cols.tolist()
        self._lazy_masked = np.full((n, n_targets + 1), np.inf)
        self._edge_xy = np.zeros((2, 4, n, n_targets))
        # Per target: its samples' index range (samples are stored target by target).
        starts = np.searchsorted(self._s_target, np.arange(n_targets + 1))
        self._sample_range = list(zip(starts[:-1].tolist(), starts[1:].tolist(), strict=True))
        self._min_area_list = self._min_area.tolist()
        self._inv_list = self._inv_samples.tolist()
        self._s_geom_list = self._s_geom.tolist()
        self._ray_one = np.zeros(1, dtype=np.int32)
        self._kernel_setup()

    def close(self) -> None:
        """Nothing to release (symmetry with the rendered provider)."""

    def __enter__(self) -> GeometricVision:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------------------------
    def observe(self) -> VisionFrame:
        """What every robot sees in the world's current state."""
        t = self.measure_targets()
        bearing, distance, seen = t.bearing, t.distance, t.visible
        apply_noise(self.config.noise, self.rng, bearing, distance, seen)
        robot, target = np.nonzero(seen)
        return frame_from_detections(
            self.n_robots,
            robot,
            self.target_cls[target],
            bearing[robot, target],
            distance[robot, target],
            t.area[robot, target],
        )

    def measure_targets(self) -> TargetMeasurements:
        """Every robot's view of every target (noise-free), before the nearest is chosen.

        Targets are ordered: the LED of each robot, the face of each robot, each pack
        (``target_cls``, ``target_owner`` give class and owning robot). Rays are cast only at
        targets that could be seen at all (another robot's lit LED, a face turned towards the
        camera, anything in range and large enough if fully visible).
        """
        front = self._front()
        cam, candidate, rays, sample_ok = front.cam, front.candidate, front.rays, front.sample_ok
        n = self.n_robots
        m, d = self.world.model, self.world.data
        sample_ok = sample_ok & candidate[:, self._s_target]
        hit = np.zeros_like(sample_ok)
        for i in range(n):
            idx = np.flatnonzero(sample_ok[i])
            k = len(idx)
            if k == 0:
                continue
            mujoco.mj_multiRay(
                m,
                d,
                cam[i],
                rays[i, idx].ravel(),
                _VISIBLE_GROUPS,
                1,
                self._exclude[i],
                self._ray_geom[:k],
                self._ray_dist[:k],
                None,
                k,
                self._cutoff,
            )
            hit[i, idx] = self._ray_geom[:k] == self._s_geom[idx]
        visible_share = (hit @ self._sample_to_target) * self._inv_samples
        area = front.full_area * visible_share
        seen = candidate & (area >= self._min_area)
        seen &= ~self._merged_blobs(
            seen, visible_share, front.local, front.bearing, front.distance, front.half_angle
        )
        return TargetMeasurements(
            visible=seen,
            bearing=front.bearing,
            distance=front.distance,
            area=area,
            visible_share=visible_share,
            width_px=front.width_px,
            height_px=front.height_px,
        )

    def nearest_targets(
        self, bearing: np.ndarray, distance: np.ndarray, visible: np.ndarray
    ) -> None:
        """Each robot's nearest visible target of each class, noise-free, into (n, 3) buffers.

        The same answer as picking, per robot and class, the nearest ``visible`` target of
        :meth:`measure_targets` (ties to the lowest target index; ``distance`` inf and
        ``bearing`` 0 where nothing is seen), bit for bit, but with occlusion rays cast lazily.
        The controller and the behaviours read only these nearest targets, so the full ray pass
        is wasted work in the evolution loop: here each class's candidates are tried nearest
        first, rays are cast only at the nearest untried candidate of each (robot, class), and
        the next one is tried only if that one turns out hidden or too small. Blob merging
        cannot change the answer (only a target with a *nearer* visible one of its colour is
        merged away). Typically one round of at most 15 rays per robot instead of rays at every
        candidate.

        Args:
            bearing, distance: (n_robots, 3) float buffers, filled in place (class order
                LED, FACE, BATTERY).
            visible: (n_robots, 3) bool buffer, filled in place.
        """
        if self.backend == "compiled":
            m, d = self.world.model, self.world.data
            self._gather()
            geometric_kernel.nearest(
                m._address, d._address, *self._kernel_poses, self.world.led_on,
                *self._kernel_rest, *self._kernel_nearest_tail, bearing, distance, visible,
            )  # fmt: skip
            return
        f = self._front_numpy()
        m, d = self.world.model, self.world.data
        n_targets = len(self.target_cls)
        masked = self._lazy_masked
        masked[:, :n_targets].fill(np.inf)
        np.copyto(masked[:, :n_targets], f.distance, where=f.candidate)
        # Each class's candidates nearest first (stable: ties to the lowest target index).
        order = np.argsort(masked[:, self._lazy_class_cols], axis=2, kind="stable").tolist()
        dist = masked.tolist()
        area = f.full_area.tolist()
        ok = f.sample_ok.tolist()
        cam, rays, rng = f.cam, f.rays, self._sample_range
        min_area, inv, s_geom = self._min_area_list, self._inv_list, self._s_geom_list
        class_cols = self._lazy_class_cols_list
        geom_id = self._ray_one
        visible.fill(False)
        distance.fill(np.inf)
        bearing.fill(0.0)
        for i in range(self.n_robots):
            cam_i, rays_i, ok_i, dist_i, area_i = cam[i], rays[i], ok[i], dist[i], area[i]
            exclude = self._exclude[i]
            for c in (LED, FACE, BATTERY):
                cols = class_cols[c]
                for j in order[i][c]:
                    t = cols[j]
                    if dist_i[t] == math.inf:  # no candidate left (or the padding column)
                        break
                    # Visible iff full_area * (hits * inv) >= min_area, as measure_targets
                    # decides; the product grows with the hit count, so rays stop as soon as
                    # the answer is certain either way.
                    full, need, step = area_i[t], min_area[t], inv[t]
                    first, end = rng[t]
                    left = sum(ok_i[first:end])
                    hits = 0
                    seen = full * (hits * step) >= need
                    while not seen and left and full * ((hits + left) * step) >= need:
                        s = first
                        while not ok_i[s]:
                            s += 1
                        first = s + 1
                        left -= 1
                        mujoco.mj_ray(m, d, cam_i, rays_i[s], _VISIBLE_GROUPS, 1, exclude, geom_id)
                        if geom_id[0] == s_geom[s]:
                            hits += 1
                            seen = full * (hits * step) >= need
                    if seen:
                        visible[i, c] = True
                        distance[i, c] = f.distance[i, t]
                        bearing[i, c] = f.bearing[i, t]
                        break

    def _front(self) -> _Front:
        """Everything before the ray casts, shared by :meth:`measure_targets` and
        :meth:`nearest_targets` so that both compute bit-identical numbers (fresh arrays)."""
        if self.backend == "numpy":
            return self._front_numpy()
        k = self._kernel
        self._gather()
        geometric_kernel.front(*self._kernel_poses, self.world.led_on, *self._kernel_rest)
        rays, sample_ok = k["rays"].copy(), k["sample_ok"].copy()
        return _Front(
            k["cam"].copy(), k["local"].copy(), k["bearing"].copy(), k["distance"].copy(),
            k["width_px"].copy(), k["height_px"].copy(), k["half_angle"].copy(),
            k["full_area"].copy(), k["candidate"].copy(), rays, sample_ok,
        )  # fmt: skip

    def _kernel_setup(self) -> None:
        """Constant inputs and reused buffers of the compiled kernel."""
        if self.backend != "compiled":
            return
        n, n_targets, n_samples = self.n_robots, len(self.target_geom), len(self._s_target)
        proj = self.projection
        scalars = np.array(
            [
                self.config.max_range, proj.view_span, self.config.n_views, proj.px_per_u,
                proj.px_per_v, proj.v_top, proj.v_bottom, self._tan_el_min, self._tan_el_max,
                _EDGE_CLIP,
            ],
            dtype=float,
        )  # fmt: skip
        k: dict[str, np.ndarray] = {
            "cam": np.zeros((n, 3)),
            "rot": np.zeros((n, 9)),
            "centre": np.zeros((n_targets, 3)),
            "gmat": np.zeros((n_targets, 9)),
            "local": np.zeros((n, n_targets, 3)),
            "bearing": np.zeros((n, n_targets)),
            "distance": np.zeros((n, n_targets)),
            "width_px": np.zeros((n, n_targets)),
            "height_px": np.zeros((n, n_targets)),
            "half_angle": np.zeros((n, n_targets)),
            "full_area": np.zeros((n, n_targets)),
            "candidate": np.zeros((n, n_targets), dtype=np.bool_),
            "diff": np.zeros((n, n_targets, 3)),
            "lateral": np.zeros((n, n_targets, 3)),
            "rays": np.zeros((n, n_samples, 3)),
            "sample_ok": np.zeros((n, n_samples), dtype=np.bool_),
        }
        self._kernel = k
        consts = (
            np.ascontiguousarray(self._own), np.ascontiguousarray(self._plate, dtype=np.bool_),
            self._half_width.astype(float), self._half_height.astype(float),
            self._rim.astype(float), self._half_depth.astype(float), self._min_area,
            self._s_target, np.ascontiguousarray(self._s_lat.ravel()),
            np.ascontiguousarray(self._s_dz.ravel()), np.asarray(proj.view_centres, float),
            scalars,
        )  # fmt: skip
        outputs = tuple(
            k[name]
            for name in (
                "local", "bearing", "distance", "width_px", "height_px", "half_angle",
                "full_area", "candidate", "diff", "lateral", "rays", "sample_ok",
            )
        )  # fmt: skip
        # The world's LED states are read at each call (between the poses and the constants).
        self._kernel_poses = (k["cam"], k["rot"], k["centre"], k["gmat"])
        self._kernel_rest = (*consts, *outputs)
        class_count = np.array(
            [int(np.sum(self.target_cls == c)) for c in (LED, FACE, BATTERY)], dtype=np.int64
        )
        starts = np.array([a for a, _ in self._sample_range], dtype=np.int64)
        ends = np.array([b for _, b in self._sample_range], dtype=np.int64)
        self._kernel_nearest_tail = (
            np.ascontiguousarray(self._lazy_class_cols, dtype=np.int64), class_count, starts,
            ends, self._inv_samples.astype(float), self._s_geom.astype(np.int64),
            np.asarray(self._exclude, dtype=np.int64), _VISIBLE_GROUPS,
            np.zeros(1, dtype=np.int32), np.zeros(n_targets, dtype=np.int64),
        )  # fmt: skip

    def kernel_arguments(self) -> tuple:
        """The arguments of ``geometric_kernel.gather`` then ``nearest`` (without its three
        outputs), for callers that run the nearest-target pass inside their own compiled code
        (``evolution.runner.step_kernel``). Buffers are this provider's; valid while it lives.

        Raises:
            RuntimeError: if the compiled backend is not in use.
        """
        if self.backend != "compiled":
            raise RuntimeError("kernel_arguments needs the compiled backend")
        m, d = self.world.model, self.world.data
        return (
            d.site_xpos, d.site_xmat, d.geom_xpos, d.geom_xmat,
            np.asarray(self._cam_site, dtype=np.int64),
            np.asarray(self.target_geom, dtype=np.int64), m._address, d._address,
            *self._kernel_poses, self.world.led_on, *self._kernel_rest,
            *self._kernel_nearest_tail,
        )  # fmt: skip

    def _gather(self) -> None:
        """Copy the camera and target poses into the kernel's input buffers."""
        d, k = self.world.data, self._kernel
        d.site_xpos.take(self._cam_site, axis=0, out=k["cam"])
        d.site_xmat.take(self._cam_site, axis=0, out=k["rot"])
        d.geom_xpos.take(self.target_geom, axis=0, out=k["centre"])
        d.geom_xmat.take(self.target_geom, axis=0, out=k["gmat"])

    def _front_numpy(self) -> _Front:
        """The reference implementation of :meth:`_front` (numpy)."""
        d = self.world.data
        n = self.n_robots
        cam = d.site_xpos[self._cam_site]  # (n, 3)
        rot = d.site_xmat[self._cam_site].reshape(n, 3, 3)
        centre = d.geom_xpos[self.target_geom]  # (T, 3)
        gmat = d.geom_xmat[self.target_geom].reshape(-1, 3, 3)
        diff = centre[None, :, :] - cam[:, None, :]  # (n, T, 3) world frame
        rh_world = np.maximum(np.hypot(diff[..., 0], diff[..., 1]), 1e-9)
        # Lateral direction of each target as seen by each robot: perpendicular to the line of
        # sight for cylinders, the plate's own width axis for plates.
        lateral = np.empty_like(diff)
        lateral[..., 0] = -diff[..., 1] / rh_world
        lateral[..., 1] = diff[..., 0] / rh_world
        lateral[..., 2] = 0.0
        lateral[:, self._plate, :] = gmat[self._plate, :, 1][None, :, :]

        # --- each target's axis in the camera frame -----------------------------------
        local = diff @ rot  # local_j = sum_i R_ij diff_i
        bearing = np.arctan2(local[..., 1], local[..., 0])
        distance = np.hypot(local[..., 0], local[..., 1])
        normal_local = gmat[:, :, 0] @ rot  # (n, T, 3) each target's x axis, camera frame
        width_px, height_px, half_angle = self._projected_size(
            local, lateral @ rot, normal_local, bearing, distance
        )
        full_area = width_px * height_px
        candidate = (full_area >= self._min_area) & (distance <= self.config.max_range)
        candidate &= ~self._own
        candidate[:, :n] &= self.world.led_on[None, :]  # a dark LED is not a green target
        # Plates (faces) show only their front: normal (the body's x axis) towards the camera.
        normal = gmat[self._plate, :, 0]  # (P, 3) x axis of each plate
        facing = (diff[:, self._plate, :] * normal[None, :, :]).sum(axis=2) < 0.0
        candidate[:, self._plate] &= facing

        # Occlusion samples: the ray from the camera to each sample point, and whether the point
        # is in the camera's field of view.
        st = self._s_target
        rays = diff[:, st, :] + self._s_lat * lateral[:, st, :]
        rays[..., 2] += self._s_dz
        sample_ok = self._in_frustum(rays @ rot)
        return _Front(
            cam, local, bearing, distance, width_px, height_px, half_angle, full_area,
            candidate, rays, sample_ok,
        )  # fmt: skip

    # ------------------------------------------------------------------------------------
    def _in_frustum(self, local: np.ndarray) -> np.ndarray:
        """Whether points (camera frame, any leading shape, last axis xyz) are in view.

        Points inside the elevation band that every bearing sees pass at once; only the rest
        (rare: things very close to the robot) get the exact per-view frustum test.
        """
        proj = self.projection
        rh = np.maximum(np.hypot(local[..., 0], local[..., 1]), 1e-9)
        tan_el = local[..., 2] / rh
        inside = (tan_el >= self._tan_el_min) & (tan_el <= self._tan_el_max)
        if inside.all():
            return inside
        b = np.arctan2(local[..., 1], local[..., 0])
        _, offset = proj.view_coordinates(b)
        v = tan_el / np.cos(offset)
        return (v >= proj.v_bottom) & (v <= proj.v_top)

    def _projected_size(
        self,
        local: np.ndarray,
        lat_local: np.ndarray,
        normal_local: np.ndarray,
        bearing: np.ndarray,
        distance: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Projected width and height (pixels) of a fully visible target, and half its
        angular width (rad).

        Width: the two lateral edges projected onto the image plane of the view that sees the
        target's axis, plus, for plates, the two faces of the plate (its edge). Height: from
        the far top rim to the near bottom rim (cylinders seen from above), or from top to
        bottom edge (plates), clipped to the strip.
        """
        proj = self.projection
        view, offset = proj.view_coordinates(bearing)
        axis = proj.view_centres[view]
        # The bearings of four edge points at once, one numpy call per operation: left and
        # right edges (axis ± lateral half width), front and back faces (axis ± half depth; a
        # cylinder's depth is 0, which adds exactly 0 width). (2: x/y, 4: edge, n, T) buffer.
        edge = self._edge_xy
        np.multiply(lat_local[..., 0], self._half_width, out=edge[0, 0])
        np.multiply(lat_local[..., 1], self._half_width, out=edge[1, 0])
        np.multiply(normal_local[..., 0], self._half_depth, out=edge[0, 2])
        np.multiply(normal_local[..., 1], self._half_depth, out=edge[1, 2])
        np.negative(edge[:, 0], out=edge[:, 1])
        np.negative(edge[:, 2], out=edge[:, 3])
        edge[0] += local[..., 0]
        edge[1] += local[..., 1]
        b_edge = np.arctan2(edge[1], edge[0])  # (4, n, T): left, right, front, back
        u = np.tan(np.clip(_wrap(b_edge - axis), -_EDGE_CLIP, _EDGE_CLIP))
        du = np.abs(u[0] - u[1])
        du += np.abs(u[2] - u[3])
        cos_off = np.cos(offset)
        depth_far = np.maximum((distance + self._rim) * cos_off, 1e-9)
        depth_near = np.maximum((distance - self._rim) * cos_off, 1e-9)
        v_top = (local[..., 2] + self._half_height) / depth_far
        v_bot = (local[..., 2] - self._half_height) / depth_near
        dv = np.clip(np.minimum(v_top, proj.v_top) - np.maximum(v_bot, proj.v_bottom), 0.0, None)
        half_angle = 0.5 * np.abs(_wrap(b_edge[0] - b_edge[1]))
        return du * proj.px_per_u, dv * proj.px_per_v, half_angle

    def _merged_blobs(
        self,
        seen: np.ndarray,
        visible_share: np.ndarray,
        local: np.ndarray,
        bearing: np.ndarray,
        distance: np.ndarray,
        half_angle: np.ndarray,
    ) -> np.ndarray:
        """Targets whose image touches a nearer visible target of the same colour.

        Colour segmentation cannot separate touching blobs of one colour (a pack peeking out
        behind another pack is one blue blob, measured at the nearer one's distance), so such a
        target is not reported separately. Touching: the farther target is partly hidden and
        its bearing and elevation intervals (far top rim to near bottom rim) overlap the
        nearer one's.
        """
        hidden_part = seen & (visible_share < 1.0)
        if not hidden_part.any():
            return hidden_part
        el_top = np.arctan2(local[..., 2] + self._half_height, distance + self._rim)
        el_bot = np.arctan2(
            local[..., 2] - self._half_height, np.maximum(distance - self._rim, 1e-9)
        )
        sep = np.abs(_wrap(bearing[:, :, None] - bearing[:, None, :]))
        # [i, a, b]: a (nearer, visible) swallows b, which it partly hides.
        touch = sep < half_angle[:, :, None] + half_angle[:, None, :]
        touch &= el_bot[:, :, None] < el_top[:, None, :]
        touch &= el_bot[:, None, :] < el_top[:, :, None]
        touch &= self._same_class[None, :, :]
        touch &= distance[:, :, None] < distance[:, None, :]
        touch &= seen[:, :, None] & hidden_part[:, None, :]
        return touch.any(axis=1)


def _wrap(a: np.ndarray) -> np.ndarray:
    """Wrap angles to [-π, π)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def widen_ray_culling_bounds(model: mujoco.MjModel) -> None:
    """Make ``mj_multiRay``'s body culling conservative, so that it misses no geom.

    ``mj_multiRay`` (MuJoCo 3.17) skips a body when a ray misses a sphere around the body's
    root bounding box, but it places that box at the body's inertial position *without the
    body's rotation*, and the box covers only collision geoms. A robot turned away from the
    camera then loses its face plate and parts of its chassis: on 200 random scenes, 3.4 % of
    the rays to faces passed through geoms that ``mj_ray`` (an exact linear scan) hit. Here every
    body's root box is re-centred on the inertial position and grown until it (a) still contains
    the original box, so collision midphase stays exact, and (b) its half-diagonal reaches every
    geom of the body (visual ones included) in any orientation. After this, ``mj_multiRay``
    agrees with ``mj_ray`` on every ray of those scenes (``tests/test_vision_geometric.py``),
    and simulated trajectories are bit-identical (larger bounds only prune fewer pairs).
    Idempotent.
    """
    for body in range(1, model.nbody):
        root = int(model.body_bvhadr[body])
        if root < 0:
            continue
        centre = model.bvh_aabb[root, :3].copy()
        half = np.abs(centre) + model.bvh_aabb[root, 3:]
        first = int(model.body_geomadr[body])
        geoms = slice(first, first + int(model.body_geomnum[body]))
        reach = np.linalg.norm(model.geom_pos[geoms] - model.body_ipos[body], axis=1)
        radius = float(np.max(reach + model.geom_rbound[geoms], initial=0.0))
        norm = float(np.linalg.norm(half))
        if 0.0 < norm < radius:
            half *= radius / norm
        model.bvh_aabb[root, :3] = 0.0
        model.bvh_aabb[root, 3:] = half


def _samples_for(shape: TargetShape) -> tuple[tuple[float, float], ...]:
    return {BATTERY: _PACK_SAMPLES, FACE: _FACE_SAMPLES, LED: _LED_SAMPLES}[shape.cls]
