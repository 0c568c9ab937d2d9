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
* **resolution**: a target is detected only if its expected visible area in the image (the
  pixel centres its outline covers at the configured resolution, as a rasteriser fills them,
  times the visible share of its samples) reaches the class's ``min_blob_area``, which gives
  the camera's real range limit; a small target that a nearer body partly hides is instead
  measured pixel by pixel, a ray through each pixel centre of its footprint
  (``CameraConfig.trace_below``, docs/design.md §6);
* a face plate is seen from the front, and edge-on from the side where it stands out of the
  chassis; a robot never sees its own LED or face; a dark LED and an inactive pack
  (``World.pack_active``) are no target, but still hide what is behind them;
* targets of one colour whose pixels touch merge into one blob, reported at the nearest of them
  (colour segmentation cannot separate them; ``docs/design.md`` §6 gives the rule).

Every index is computed at construction; a call of :meth:`GeometricVision.observe` is a fixed
sequence of small vectorised numpy operations plus one ``mj_multiRay`` per robot, cast only at
the targets that could be seen at all (``benchmarks/vision_cost.py`` measures it).

The per-step rules (gathering the poses, the geometry before the rays, and
:meth:`GeometricVision.nearest_targets` with its lazy rays) live in
:mod:`cyber_rodent.vision.kernels`, each as a compiled kernel and a numpy reference; the
``backend`` given at construction picks one (``docs/design.md`` §3). The full pass of
:meth:`GeometricVision.measure_targets` (every target, ``mj_multiRay``, blob merging), which
``observe()`` and the noisy-vision path use, runs the chosen ``front`` kernel and then numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.vision import kernels
from cyber_rodent.vision.config import CameraConfig, camera_for_field
from cyber_rodent.vision.detections import (
    apply_noise,
    frame_from_detections,
    load_noise_state,
    noise_state,
)
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.vision.targets import TargetShape, target_geometry
from cyber_rodent.vision.types import BATTERY, FACE, LED, VisionFrame
from cyber_rodent.world import World

#: Occlusion samples, as (lateral, vertical) fractions of a target's half width and half
#: height, spread over the target's whole width (±0.9: a sliver beside an occluder is seen in
#: the image, so it must be sampled), centre first so that the lazy pass finds a visible
#: target with its first ray. Packs get 3 × 2 samples: the lower row below and the upper row
#: above the grey electrode ring, so that every sample aims at blue; the upper row at the top
#: rim catches a pack whose top peeks over an obstacle. Faces get 3 × 2 (their top edge peeks
#: over packs); the LED ring is a thin band: three samples across at mid height. Five across
#: (adding ±0.5) agreed no better with the rendered camera on the hard scenes.
_ACROSS = (0.0, -0.9, 0.9)
_PACK_SAMPLES = tuple((lat, vert) for vert in (0.96, -0.7) for lat in _ACROSS)
_FACE_SAMPLES = tuple((lat, vert) for vert in (0.7, -0.7) for lat in _ACROSS)
_LED_SAMPLES = tuple((lat, 0.0) for lat in _ACROSS)
#: m, how far inside a plate's front face its samples lie (a ray aimed exactly at the face
#: could graze past it).
_PLATE_SAMPLE_INSET = 1e-4
#: Geom groups that are rendered (mjvOption's default), hence able to hide a target.
VISIBLE_GROUPS = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)
_EDGE_CLIP = 0.5 * math.pi - 1e-3  # rad, keep tan() finite for targets beside the camera
#: m, cell side of the grid that the nearest-target search reaches targets through: half the
#: paper's field, so the paper's world is 2 x 2 cells and its search places every target at
#: once; in a larger field at the paper's density a cell holds about 2 targets.
SEARCH_CELL = C.FIELD_SIZE / 2
#: m, cell side of the grid that the search's rays find the geoms near them in: a few robots'
#: widths, so a ray tests tens of geoms, not every geom of the colony.
RAY_CELL = 0.5
#: m, geoms with a larger bounding radius (the walls), and planes (unbounded), are tested by
#: every ray instead of being binned.
_ALWAYS_RBOUND = 0.5
#: m, how much farther than an arena's diagonal a rangefinder's ray is searched through the grid
#: (``culled_rangefinders``): beyond it, ``mj_ray`` answers.
RANGE_SEARCH_MARGIN = 0.5
#: From this many geoms on, the search's rays test only the geoms near them; with fewer,
#: ``mj_ray``'s scan of every geom costs no more (the paper's world has 67 geoms).
CULL_FROM_GEOMS = 200


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
        candidate: could be seen at all (in range, large enough if fully visible, not the
            robot's own, a lit LED, an active pack, a face plate facing or beside the camera),
            before occlusion.
        blob_spread: rad, how far the blob of a visible target that swallowed touching
            targets of its colour reaches beyond the target's own angular half width (0 for
            every other target): the rendered blob's bearing lies anywhere within it.
    """

    visible: np.ndarray
    bearing: np.ndarray
    distance: np.ndarray
    area: np.ndarray
    visible_share: np.ndarray
    width_px: np.ndarray
    height_px: np.ndarray
    candidate: np.ndarray
    blob_spread: np.ndarray


class GeometricVision:
    """Vision from poses, field of view, range and ray-cast occlusion.

    Args:
        world: the world to observe (bound: every call reads its current ``MjData``).
        config: the camera (default: :func:`~cyber_rodent.vision.config.camera_for_field` of
            the world's field); the same config makes the rendered provider comparable.
        rng: generator for the noise model; required only if ``config.noise`` is enabled.
        backend: ``"numba"`` (compiled kernels) or ``"numpy"`` (their references).

    Attributes:
        scene: the named buffers of :func:`cyber_rodent.vision.kernels.nearest` (poses,
            constants, LED states, scratch), for callers that run it in their own kernel.
        nearest: the :class:`~cyber_rodent.vision.kernels.NearestTargets` buffers that
            :meth:`nearest_targets` fills.
    """

    def __init__(
        self,
        world: World,
        config: CameraConfig | None = None,
        rng: np.random.Generator | None = None,
        backend: Backend = DEFAULT_BACKEND,
    ):
        self.backend = check_backend(backend)
        if kernels.UNAVAILABLE_REASON:
            raise ValueError("geometric vision cannot cast rays: " + kernels.UNAVAILABLE_REASON)
        self.world = world
        self.config = config or camera_for_field(world.config.field_size)
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
        plate = np.array([s.plate for s in shape_of], dtype=np.bool_)
        #: (T,) m, half width of each target (cylinder radius, half the plate's width).
        self.half_width = np.array([s.half_width for s in shape_of], dtype=float)
        # Flattened occlusion samples: which target, lateral and vertical offset (m).
        # A plate's samples lie just inside its front face: seen edge-on, only the front of its
        # sides stands out of its body.
        s_target, s_lat, s_dz, s_along = [], [], [], []
        for t, shape in enumerate(shape_of):
            for lat, vert in _samples_for(shape):
                s_target.append(t)
                s_lat.append(lat * shape.half_width)
                s_dz.append(vert * 0.5 * shape.height)
                s_along.append(max(shape.depth_front - _PLATE_SAMPLE_INSET, 0.0))
        sample_target = np.array(s_target, dtype=np.int64)
        n_samples = len(s_target)
        inv_samples = 1.0 / np.bincount(sample_target, minlength=n_targets).astype(float)
        # Target of each geom (-1 for geoms that are no target); a pack's electrode ring counts
        # as its pack's (it only splits the pack's blue, see kernels.merge).
        target_of_geom = np.full(world.model.ngeom, -1, dtype=np.int64)
        target_of_geom[self.target_geom] = np.arange(len(self.target_geom))
        target_of_geom[world.electrode_geom] = 2 * n + np.arange(k)
        pack = shapes[BATTERY]
        self.merge_rules = kernels.MergeRules(
            target_cls=self.target_cls,
            target_body=world.model.geom_bodyid[self.target_geom].astype(np.int64),
            target_of_geom=target_of_geom,
            geom_body=world.model.geom_bodyid.astype(np.int64),
            banded=(self.target_cls == BATTERY) & (pack.gap_top > pack.gap_bottom),
            band_dz=pack.gap_top - 0.5 * (pack.z_bottom + pack.z_top),
            band_radius=pack.gap_radius,
            strip_width=float(self.config.strip_width),
        )
        widen_ray_culling_bounds(world.model)
        self._exclude = [int(b) for b in world.chassis_body]
        # Output buffers of the full pass's ray casts (reused every call).
        self._ray_geom = np.zeros(n_samples, dtype=np.int32)
        self._ray_dist = np.zeros(n_samples)
        self._cutoff = float(self.config.max_range) + 1.0
        # Per class: its target columns, padded with a never-seen column (index n_targets).
        per_class = [np.flatnonzero(self.target_cls == c) for c in (LED, FACE, BATTERY)]
        width = max(1, max(len(cols) for cols in per_class))
        class_targets = np.full((3, width), n_targets, dtype=np.int64)
        for c, cols in zip((LED, FACE, BATTERY), per_class, strict=True):
            class_targets[c, : len(cols)] = cols
        starts = np.searchsorted(sample_target, np.arange(n_targets + 1)).astype(np.int64)
        m, d = world.model, world.data
        self.targets = kernels.TargetTable(
            camera_site=np.asarray(world.camera_site, dtype=np.int64),
            target_geom=self.target_geom,
            target_cls=self.target_cls,
            ids=np.arange(n_targets, dtype=np.int64),
            own=np.ascontiguousarray(self.target_owner[None, :] == np.arange(n)[:, None]),
            camera_arena=np.asarray(world.robot_arena, dtype=np.int64),
            target_arena=np.concatenate(
                [world.robot_arena, world.robot_arena, world.pack_arena]
            ).astype(np.int64),
            plate=plate,
            half_width=self.half_width,
            half_height=np.array([0.5 * s.height for s in shape_of], dtype=float),
            rim=np.array([s.rim_offset for s in shape_of], dtype=float),
            depth_front=np.array([s.depth_front for s in shape_of], dtype=float),
            depth_back=np.array([s.depth_back for s in shape_of], dtype=float),
            edge_slope=np.array([s.edge_slope for s in shape_of], dtype=float),
            min_area=np.asarray(self.config.min_blob_area, dtype=float)[self.target_cls],
            trace_below=np.asarray(self.config.trace_below, dtype=float)[self.target_cls],
            sample_target=sample_target,
            sample_lateral=np.array(s_lat, dtype=float),
            sample_dz=np.array(s_dz, dtype=float),
            sample_along=np.array(s_along, dtype=float),
            sample_geom=self.target_geom[sample_target],
            sample_start=np.ascontiguousarray(starts[:-1]),
            sample_end=np.ascontiguousarray(starts[1:]),
            inv_samples=inv_samples,
            class_targets=class_targets,
            class_count=np.array([len(cols) for cols in per_class], dtype=np.int64),
            exclude_body=np.asarray(self._exclude, dtype=np.int64),
            geom_groups=VISIBLE_GROUPS,
        )
        proj = self.projection
        self.camera = kernels.CameraModel(
            view_centres=np.asarray(proj.view_centres, dtype=float),
            max_range=float(self.config.max_range),
            view_span=float(proj.view_span),
            n_views=int(self.config.n_views),
            px_per_u=float(proj.px_per_u),
            px_per_v=float(proj.px_per_v),
            v_top=float(proj.v_top),
            v_bottom=float(proj.v_bottom),
            tan_el_min=math.tan(math.radians(self.config.elevation_min_deg)),
            tan_el_max=math.tan(math.radians(self.config.elevation_max_deg)),
            edge_clip=_EDGE_CLIP,
            half_tan=float(proj.half_tan),
            view_width=float(self.config.view_width),
            rows=float(self.config.height),
            view_cos=np.cos(np.asarray(proj.view_centres, dtype=float)),
            view_sin=np.sin(np.asarray(proj.view_centres, dtype=float)),
        )
        shape_nt = (n, n_targets)
        self.front = kernels.FrontBuffers(
            cam=np.zeros((n, 3)),
            rot=np.zeros((n, 9)),
            centre=np.zeros((n_targets, 3)),
            gmat=np.zeros((n_targets, 9)),
            local=np.zeros((n, n_targets, 3)),
            bearing=np.zeros(shape_nt),
            distance=np.zeros(shape_nt),
            width_px=np.zeros(shape_nt),
            height_px=np.zeros(shape_nt),
            full_area=np.zeros(shape_nt),
            left_px=np.zeros(shape_nt),
            right_px=np.zeros(shape_nt),
            top_px=np.zeros(shape_nt),
            bottom_px=np.zeros(shape_nt),
            candidate=np.zeros(shape_nt, dtype=np.bool_),
            diff=np.zeros((n, n_targets, 3)),
            lateral=np.zeros((n, n_targets, 3)),
            rays=np.zeros((n, n_samples, 3)),
            sample_ok=np.zeros((n, n_samples), dtype=np.bool_),
            order=np.zeros((3, n_targets), dtype=np.int64),
            ray_geom=np.zeros(1, dtype=np.int32),
            pixel_ray=np.zeros(3),
        )
        poses = kernels.MujocoPoses(
            d.site_xpos, d.site_xmat, d.geom_xpos, d.geom_xmat, m._address, d._address
        )
        self.grids = scene_index(world, n_targets, self.targets.geom_groups)
        self.scene = kernels.GeometricScene(
            poses, self.targets, self.camera, world.led_on, world.pack_active, self.front,
            self.grids,
        )  # fmt: skip
        self.nearest = kernels.NearestTargets(
            bearing=np.zeros((n, 3)),
            distance=np.full((n, 3), np.inf),
            visible=np.zeros((n, 3), dtype=np.bool_),
        )
        self._gather = bind(
            pick(self.backend, kernels.gather, kernels.gather_reference),
            poses, self.targets, self.front,
        )  # fmt: skip
        self._front = bind(
            pick(self.backend, kernels.front, kernels.front_reference),
            self.targets, self.camera, world.led_on, world.pack_active, self.front, True,
        )  # fmt: skip
        self._nearest = bind(
            pick(self.backend, kernels.nearest, kernels.nearest_reference), self.scene, self.nearest
        )
        self._traced_area = pick(self.backend, kernels.traced_area, kernels.traced_area_reference)
        self.merging = kernels.MergeBuffers(
            seen=np.zeros(shape_nt, dtype=np.bool_),
            visible_share=np.zeros(shape_nt),
            hit_geom=np.full((n, n_samples), -1, dtype=np.int64),
            merged=np.zeros(shape_nt, dtype=np.bool_),
            spread=np.zeros(shape_nt),
            group=np.zeros(n_targets, dtype=np.int64),
            pack_active=world.pack_active,
            listed=np.zeros(n_targets, dtype=np.int64),
            nearest=np.zeros(n_targets, dtype=np.int64),
            members=np.zeros(n_targets, dtype=np.int64),
            reach=np.zeros(n_targets),
        )
        self._merge = bind(
            pick(self.backend, kernels.merge, kernels.merge_reference),
            self.targets, self.camera, self.merge_rules, self.front, self.merging,
        )  # fmt: skip

    def close(self) -> None:
        """Nothing to release (symmetry with the rendered provider)."""

    def __enter__(self) -> GeometricVision:
        return self

    def __exit__(self, *exc: object) -> None:
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
        camera, an active pack, anything in range and large enough if fully visible).
        """
        self._gather()
        self._front()
        f = self.front
        # Fresh arrays: callers keep the measurements and the noise model edits them in place.
        bearing, distance = f.bearing.copy(), f.distance.copy()
        candidate, full_area = f.candidate.copy(), f.full_area.copy()
        n = self.n_robots
        m, d = self.world.model, self.world.data
        sample_ok = f.sample_ok & candidate[:, self.targets.sample_target]
        hit = np.zeros_like(sample_ok)
        # The geom each sample's ray hit first (-1: none, or no ray cast).
        hit_geom = self.merging.hit_geom
        hit_geom.fill(-1)
        sample_geom = self.targets.sample_geom
        for i in range(n):
            idx = np.flatnonzero(sample_ok[i])
            k = len(idx)
            if k == 0:
                continue
            mujoco.mj_multiRay(
                m,
                d,
                f.cam[i],
                f.rays[i, idx].ravel(),
                VISIBLE_GROUPS,
                1,
                self._exclude[i],
                self._ray_geom[:k],
                self._ray_dist[:k],
                None,
                k,
                self._cutoff,
            )
            hit[i, idx] = self._ray_geom[:k] == sample_geom[idx]
            hit_geom[i, idx] = self._ray_geom[:k]
        # Hits per target: its samples are consecutive (exact integer sums, as a product with
        # the samples' 0/1 target matrix would give, without its targets x samples work).
        hits = np.add.reduceat(hit, self.targets.sample_start, axis=1, dtype=float)
        visible_share = hits * self.targets.inv_samples
        area = full_area * visible_share
        traced = candidate & self._traced(sample_ok, hit, full_area)
        robots, traced_targets = np.nonzero(traced)
        if len(robots):
            pixels = np.zeros(len(robots))
            self._traced_area(self.scene, robots, traced_targets, pixels)
            area[robots, traced_targets] = pixels
        seen = candidate & (area >= self.targets.min_area)
        np.copyto(self.merging.seen, seen)
        np.copyto(self.merging.visible_share, visible_share)
        self._merge()
        seen &= ~self.merging.merged
        return TargetMeasurements(
            visible=seen,
            bearing=bearing,
            distance=distance,
            area=area,
            visible_share=visible_share,
            width_px=f.width_px.copy(),
            height_px=f.height_px.copy(),
            candidate=candidate,
            blob_spread=self.merging.spread.copy(),
        )

    def _traced(
        self, sample_ok: np.ndarray, hit: np.ndarray, full_area: np.ndarray
    ) -> np.ndarray:
        """(n, T): the targets measured pixel by pixel. A small target (footprint under
        ``trace_below``) that could reach its class's area if every sample in view were seen,
        one of whose samples, read in order, is hidden before the samples' estimate (footprint
        × seen share) reaches that area, and one of whose samples is seen: the targets whose
        samples :meth:`nearest_targets` reads lazily and then traces (``kernels.nearest``).

        Only the few (robot, target) pairs that are small and have a sample seen and one hidden
        are read sample by sample."""
        tt = self.targets
        traced = np.zeros(full_area.shape, dtype=bool)
        small = full_area < tt.trace_below
        if not small.any():
            return traced
        read = np.add.reduceat(sample_ok, tt.sample_start, axis=1, dtype=np.int64)
        seen = np.add.reduceat(hit & sample_ok, tt.sample_start, axis=1, dtype=np.int64)
        reachable = full_area * (read * tt.inv_samples) >= tt.min_area
        for i, t in zip(*np.nonzero(small & reachable & (seen > 0) & (seen < read)), strict=True):
            full, need, step = full_area[i, t], tt.min_area[t], tt.inv_samples[t]
            shown = 0
            for s in range(int(tt.sample_start[t]), int(tt.sample_end[t])):
                if not sample_ok[i, s]:
                    continue
                if not hit[i, s]:
                    traced[i, t] = True  # hidden before the estimate was certain
                    break
                shown += 1
                if full * (shown * step) >= need:
                    break  # certain before any hidden sample was read
        return traced

    def nearest_targets(self) -> kernels.NearestTargets:
        """Each robot's nearest visible target of each class, noise-free: :attr:`nearest`.

        The same answer as picking, per robot and class, the nearest ``visible`` target of
        :meth:`measure_targets` (ties to the lowest target index; ``distance`` inf and
        ``bearing`` 0 where nothing is seen), bit for bit, but with occlusion rays cast lazily.
        The controller and the behaviours read only these nearest targets, so the full ray pass
        is wasted work in the evolution loop: here each class's candidates are tried nearest
        first, rays are cast only at the nearest untried candidate of each (robot, class), and
        the next one is tried only if that one turns out hidden or too small. Blob merging
        cannot change the answer (only a target with a *nearer* visible one of its colour is
        merged away).

        Returns:
            :attr:`nearest`, (n_robots, 3) buffers in class order LED, FACE, BATTERY, filled
            in place (overwritten by the next call).
        """
        self._nearest()
        return self.nearest

    def state(self) -> dict[str, Any]:
        """The provider's checkpoint state (:func:`~cyber_rodent.vision.detections.noise_state`)."""
        return noise_state(self.rng)

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state` into this provider."""
        load_noise_state(self.rng, state)


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


def uniform_grid(field_size: float, cell: float, members: np.ndarray) -> kernels.UniformGrid:
    """A grid of cells of side ``cell`` over a square of side ``field_size`` (centred on the
    origin: the field, or the layout of several arenas, ``WorldConfig.extent``), for binning
    ``members``."""
    side = max(1, math.ceil(field_size / cell - 1e-9))
    members = np.ascontiguousarray(members, dtype=np.int64)
    return kernels.UniformGrid(
        origin=-field_size / 2,
        cell=float(cell),
        side=int(side),
        members=members,
        start=np.zeros(side * side + 1, dtype=np.int64),
        cursor=np.zeros(side * side, dtype=np.int64),
        items=np.zeros(len(members), dtype=np.int64),
    )


def ray_culling(world: World, groups: np.ndarray) -> tuple[kernels.RayCulling, np.ndarray]:
    """What culled rays need of ``world`` (:class:`kernels.RayCulling`) for geoms of a group in
    ``groups``, and the geoms to bin in a grid: all of those but planes and large geoms (the
    walls of every arena), which the rays test without the grid (planes always, the others
    where their bounding sphere meets the ray: ``kernels.first_hit``)."""
    m = world.model
    group = np.clip(m.geom_group, 0, len(groups) - 1)
    in_group = groups[group] != 0
    rbound = np.asarray(m.geom_rbound, dtype=float)
    always = in_group & ((rbound <= 0) | (rbound > _ALWAYS_RBOUND))
    binned = np.flatnonzero(in_group & ~always)
    reach = float(rbound[binned].max(initial=0.0)) + kernels.CULL_MARGIN
    rays = kernels.RayCulling(
        geom_size=m.geom_size,
        geom_type=m.geom_type.astype(np.int64),
        geom_rbound=rbound,
        geom_bodyid=m.geom_bodyid.astype(np.int64),
        geom_matid=m.geom_matid.astype(np.int64),
        geom_rgba=m.geom_rgba,
        mat_rgba=m.mat_rgba,
        in_group=np.ascontiguousarray(in_group),
        primitive=np.isin(m.geom_type, kernels.PRIMITIVE_GEOMS),
        always=np.flatnonzero(always).astype(np.int64),
        reach=reach,
        cull=bool(m.ngeom >= CULL_FROM_GEOMS),
    )
    return rays, binned


def scene_index(world: World, n_targets: int, groups: np.ndarray) -> kernels.SceneIndex:
    """The grids of the nearest-target search (``kernels.nearest``) for ``world``: its targets
    in cells of :data:`SEARCH_CELL`, and the geoms its rays may hit (those in a group of
    ``groups``) in cells of :data:`RAY_CELL` (:func:`ray_culling`). The grids cover every
    arena (``WorldConfig.extent``)."""
    rays, binned = ray_culling(world, groups)
    size = world.config.extent  # the field, or every arena's (WorldConfig.arenas)
    return kernels.SceneIndex(
        targets=uniform_grid(size, SEARCH_CELL, np.arange(n_targets)),
        geoms=uniform_grid(size, RAY_CELL, binned),
        rays=rays,
        found=np.zeros(3, dtype=np.int64),
        tried=np.zeros(3, dtype=np.int64),
        done=np.zeros(3, dtype=np.bool_),
        ring=np.zeros(n_targets, dtype=np.int64),
        near=np.zeros(world.model.ngeom, dtype=np.int64),
    )


def culled_rangefinders(world: World) -> kernels.RangeFinders | None:
    """The buffers of ``kernels.ranges``, which computes the world's rangefinder readings as
    MuJoCo's sensor stage does, testing only the geoms near each ray; None where MuJoCo's own
    scan is as good or the world has other sensors: one arena (the paper's world keeps
    MuJoCo's sensor stage), fewer than :data:`CULL_FROM_GEOMS` geoms, a sensor that is no
    site's rangefinder, or no usable ``mj_ray`` (``kernels.UNAVAILABLE_REASON``).

    Each ray is searched through the grid over one arena's diagonal plus a margin
    (``RangeFinders.length``): from inside an arena a level ray meets a wall within it."""
    m = world.model
    if world.config.arenas == 1 or m.ngeom < CULL_FROM_GEOMS or kernels.UNAVAILABLE_REASON:
        return None
    site_sensor = (m.sensor_type == mujoco.mjtSensor.mjSENS_RANGEFINDER) & (
        m.sensor_objtype == mujoco.mjtObj.mjOBJ_SITE
    )
    if not site_sensor.all():
        return None
    site = m.sensor_objid.astype(np.int64)
    every_group = np.ones(len(VISIBLE_GROUPS), dtype=np.uint8)
    rays, binned = ray_culling(world, every_group)
    return kernels.RangeFinders(
        site=site,
        exclude=m.site_bodyid[site].astype(np.int64),
        address=m.sensor_adr.astype(np.int64),
        length=float(world.config.diagonal + RANGE_SEARCH_MARGIN),
        geoms=uniform_grid(world.config.extent, RAY_CELL, binned),
        rays=rays,
        near=np.zeros(m.ngeom, dtype=np.int64),
        groups=every_group,
        unit=np.zeros((len(site), 3)),
        segment=np.zeros(3),
        hit=np.zeros(1, dtype=np.int32),
    )


def _samples_for(shape: TargetShape) -> tuple[tuple[float, float], ...]:
    return {BATTERY: _PACK_SAMPLES, FACE: _FACE_SAMPLES, LED: _LED_SAMPLES}[shape.cls]
