"""Per-step perception of every robot, into preallocated buffers: vision, proximity, inputs.

Each control step the runner needs, per robot, the nearest green LED, red face and blue pack
(bearing, distance, seen), the six proximity readings, the behaviours' inputs
(:class:`behaviours.BehaviourInputs`) and the controller's normalised distances. The public
functions that compute these (``VisionProvider.observe``, :func:`behaviours.behaviour_inputs`)
allocate a new frame, blob lists and a dozen small arrays per call: harmless for a user, but a
measurable share of the runner's per-step budget (it steps 1.2 million times per run). This
module computes the *same numbers* into buffers it owns:

* with the geometric provider and no vision noise (the default) it calls
  :meth:`GeometricVision.nearest_targets`, which casts occlusion rays only until each class's
  nearest visible target is certain;
* with the geometric provider and vision noise it calls
  :meth:`GeometricVision.measure_targets` and the same noise model
  (:func:`cyber_rodent.vision.detections.apply_noise`) as ``observe`` does, then picks each
  class's nearest detection with ``argmin`` (ties to the lowest target index, as
  ``frame_from_detections``' stable sort does), skipping the blob lists nobody reads here;
* any other provider (the rendered camera) goes through ``observe()``;
* the behaviour inputs follow :mod:`behaviours.inputs` operation for operation (same divisions,
  same clipping), so they are bit-identical.

``tests/test_evolution_runner_perception.py`` checks both equalities on random scenes; if either
public function changes, that test fails rather than the runner drifting silently.
"""

from __future__ import annotations

import math

import numpy as np

from behaviours import BehaviourInputs
from cyber_rodent.constants import PROXIMITY_SIX
from cyber_rodent.vision import BATTERY, FACE, LED, N_CLASSES, GeometricVision, VisionProvider
from cyber_rodent.vision.detections import apply_noise
from cyber_rodent.vision.types import DEFAULT_MAX_DISTANCE
from cyber_rodent.world import World
from evolution.runner import perception_kernel

_TWO_PI = 2 * math.pi


def _as_slice(indices: tuple[int, ...] | np.ndarray) -> slice | np.ndarray:
    """A slice for contiguous ascending indices (a view, no copy), else the index array."""
    arr = np.asarray(indices, dtype=np.intp)
    if len(arr) and np.array_equal(arr, np.arange(arr[0], arr[0] + len(arr))):
        return slice(int(arr[0]), int(arr[0]) + len(arr))
    return arr


class Perception:
    """What every robot perceives at the current physics state, in reused buffers.

    Args:
        world: the physical world.
        vision: its vision provider.
        max_distance: metres normalised to 1 (the inputs' convention: the field's diagonal).

    Attributes:
        bearing: (n, 3) rad, nearest LED / face / pack per robot; 0 where not seen.
        distance: (n, 3) m; ``inf`` where not seen.
        visible: (n, 3) bool.
        proximity: (n, 6) proximity readings ``1 - range / range_max`` of the 5 front + 1 back
            sensors (``PROXIMITY_SIX`` order), larger = closer.
        norm_distance: (n, 3) distances normalised to [0, 1], 1 where not seen (the
            controller's face / LED / battery inputs).
        inputs: the behaviours' inputs (a :class:`BehaviourInputs` over buffers of this object).
    """

    def __init__(
        self, world: World, vision: VisionProvider, max_distance: float = DEFAULT_MAX_DISTANCE
    ) -> None:
        n = world.config.n_robots
        self.world = world
        self.vision = vision
        self.max_distance = float(max_distance)
        self.bearing = np.zeros((n, N_CLASSES))
        self.distance = np.full((n, N_CLASSES), np.inf)
        self.visible = np.zeros((n, N_CLASSES), dtype=bool)
        self.ranges = np.zeros((n, world.range_max.shape[1]))
        self.proximity = np.zeros((n, len(PROXIMITY_SIX)))
        self.norm_distance = np.ones((n, N_CLASSES))
        self._norm_bearing = np.full((n, N_CLASSES), 0.5)
        self._sorted = np.zeros((n, len(PROXIMITY_SIX)))
        self._led_seen = self.visible[:, LED]
        self._prox = _as_slice(PROXIMITY_SIX)
        self._prox_max = np.ascontiguousarray(world.range_max[:, self._prox])
        self._prox_columns = np.asarray(PROXIMITY_SIX, dtype=np.int64)
        self._raw = world.range_sensordata
        #: Optional sensor noise (``cyber_rodent.profiles.RangeSensorNoise``) applied to the
        #: raw range readings; None (the default) costs one attribute test per step.
        self.range_noise = None
        self.inputs = BehaviourInputs(
            mate=np.zeros((n, 2)),
            forage=np.zeros((n, 2)),
            search=np.zeros((n, 2)),
            mate_available=np.zeros(n, dtype=bool),
            forage_available=np.zeros(n, dtype=bool),
        )
        self._geometric = isinstance(vision, GeometricVision)
        self._vision_noise = vision.config.noise.enabled  # configs are frozen
        if self._geometric:
            self._prepare_geometric(vision)  # type: ignore[arg-type]

    def _prepare_geometric(self, vision: GeometricVision) -> None:
        n = self.bearing.shape[0]
        n_targets = len(vision.target_cls)
        # Distances and bearings of all targets plus one padding column that is never seen
        # (distance inf, bearing 0): each class's targets are gathered into one (n, 3, width)
        # block, classes with fewer targets (or none: a world without packs) padded with it.
        self._masked = np.full((n, n_targets + 1), np.inf)
        self._bearings = np.zeros((n, n_targets + 1))
        per_class = [np.flatnonzero(vision.target_cls == c) for c in range(N_CLASSES)]
        width = max(1, max(len(cols) for cols in per_class))
        self._class_cols = np.full((N_CLASSES, width), n_targets, dtype=np.intp)
        for c, cols in enumerate(per_class):
            self._class_cols[c, : len(cols)] = cols
        self._nearest = np.zeros((n, N_CLASSES), dtype=np.intp)
        self._column = np.zeros((n, N_CLASSES), dtype=np.intp)
        self._row_index = np.arange(n)[:, None]
        self._class_index = np.arange(N_CLASSES)[None, :]

    # ------------------------------------------------------------------------------------
    def update(self) -> BehaviourInputs:
        """Sense the current state; fill every buffer; return :attr:`inputs`."""
        if self._geometric:
            self._observe_geometric()
        else:
            frame = self.vision.observe()
            np.copyto(self.bearing, frame.bearing)
            np.copyto(self.distance, frame.distance)
            np.copyto(self.visible, frame.visible)
        if self.range_noise is None and perception_kernel.AVAILABLE:
            inp = self.inputs
            perception_kernel.map_inputs(
                self._raw, self.world.range_max, self.ranges, self._prox_columns,
                self._prox_max, self.bearing, self.distance, self.visible, self.max_distance,
                LED, FACE, BATTERY, self.proximity, self._norm_bearing, self.norm_distance,
                inp.mate, inp.forage, inp.search, inp.mate_available, inp.forage_available,
            )  # fmt: skip
            return inp
        self._proximity()
        self._map_inputs()
        return self.inputs

    def kernel_arguments(self) -> tuple:
        """Perception's part of ``step_kernel.sense_decide_act``'s arguments: the nearest
        target buffers, then ``perception_kernel.map_inputs``' arguments after them; () where
        the step-by-step path is needed (rendered or noisy vision, range noise, no numba)."""
        if not (
            self._geometric
            and not self._vision_noise
            and self.range_noise is None
            and perception_kernel.AVAILABLE
        ):
            return ()
        inp = self.inputs
        return (
            self.bearing, self.distance, self.visible, self._raw, self.world.range_max,
            self.ranges, self._prox_columns, self._prox_max, self.max_distance, LED, FACE,
            BATTERY, self.proximity, self._norm_bearing, self.norm_distance, inp.mate,
            inp.forage, inp.search, inp.mate_available, inp.forage_available,
        )  # fmt: skip

    def _observe_geometric(self) -> None:
        """``GeometricVision.observe`` without the blob lists (see the module docstring)."""
        vision: GeometricVision = self.vision  # type: ignore[assignment]
        if not self._vision_noise:
            # Noise-free (the default): only the nearest target of each class matters, so the
            # occlusion rays are cast lazily (bit-identical to the full pass, see its tests).
            vision.nearest_targets(self.bearing, self.distance, self.visible)
            return
        t = vision.measure_targets()
        apply_noise(vision.config.noise, vision.rng, t.bearing, t.distance, t.visible)
        masked, bearings = self._masked[:, :-1], self._bearings[:, :-1]
        masked.fill(np.inf)
        np.copyto(masked, t.distance, where=t.visible)
        bearings.fill(0.0)  # not seen: bearing 0, the frame's convention
        np.copyto(bearings, t.bearing, where=t.visible)
        nearest, column = self._nearest, self._column
        np.argmin(self._masked[:, self._class_cols], axis=2, out=nearest)  # within each class
        np.copyto(column, self._class_cols[self._class_index, nearest])  # (n, 3) target columns
        np.copyto(self.distance, self._masked[self._row_index, column])
        np.copyto(self.bearing, self._bearings[self._row_index, column])
        np.less(self.distance, np.inf, out=self.visible)

    def _proximity(self) -> None:
        ranges = self.world.range_readings(out=self.ranges)
        if self.range_noise is not None:
            self.range_noise.apply(ranges)
        p = self.proximity
        np.divide(ranges[:, self._prox], self._prox_max, out=p)
        np.subtract(1.0, p, out=p)
        np.clip(p, 0.0, 1.0, out=p)

    def _map_inputs(self) -> None:
        """:func:`behaviours.behaviour_inputs`, operation for operation, into the buffers."""
        inp = self.inputs
        nb, nd = self._norm_bearing, self.norm_distance
        # normalise_bearing: clip((bearing + pi) / (2 pi), 0, 1); unseen targets have bearing 0,
        # hence 0.5, exactly the "ahead" the behaviours use for an unseen target.
        np.add(self.bearing, math.pi, out=nb)
        np.divide(nb, _TWO_PI, out=nb)
        np.clip(nb, 0.0, 1.0, out=nb)
        # clip(distance / max, 0, 1); unseen targets have distance inf, hence 1.
        np.divide(self.distance, self.max_distance, out=nd)
        np.clip(nd, 0.0, 1.0, out=nd)
        led_seen = self._led_seen
        mate = inp.mate
        mate[:, 0] = nb[:, FACE]
        mate[:, 1] = nd[:, FACE]
        np.copyto(mate[:, 0], nb[:, LED], where=led_seen)
        np.copyto(mate[:, 1], nd[:, LED], where=led_seen)
        inp.forage[:, 0] = nb[:, BATTERY]
        inp.forage[:, 1] = nd[:, BATTERY]
        s = self._sorted
        np.copyto(s, self.proximity)
        s.sort(axis=1)
        inp.search[:, 0] = s[:, -1]
        inp.search[:, 1] = s[:, -2]
        np.logical_or(led_seen, self.visible[:, FACE], out=inp.mate_available)
        np.copyto(inp.forage_available, self.visible[:, BATTERY])
