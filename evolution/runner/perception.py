"""Per-step perception of every robot, into buffers it owns: what each robot sees and senses.

Each control step the runner needs, per robot, the nearest green LED, red face and blue pack
(bearing, distance, seen), the range readings, the six proximities, the behaviours' inputs and
the controller's normalised distances. :class:`Perception` owns those buffers (the named
tuples of :mod:`behaviours.kernels`) and the rule that fills them,
:func:`behaviours.kernels.map_inputs` or its numpy reference (``backend``).

Where the nearest targets come from depends on the vision provider:

* the geometric provider without noise (the default): its lazy nearest-target kernel,
  :func:`cyber_rodent.vision.kernels.nearest`; the runner then runs sensing, deciding and
  acting as one compiled call (:func:`evolution.kernels.sense_decide_act`) on these buffers,
  and :meth:`Perception.update` is not called;
* the geometric provider with vision noise (the hardware-like profile): the full pass
  :meth:`GeometricVision.measure_targets`, the noise model of ``observe()``
  (:func:`cyber_rodent.vision.detections.apply_noise`), then each class's nearest detection
  (``argmin``, ties to the lowest target index, as ``frame_from_detections``' stable sort) —
  numpy, in :meth:`Perception.update`;
* any other provider (the rendered camera): ``observe()``, in :meth:`Perception.update`.

Range-sensor noise (the hardware-like profile) is applied to the saturated readings before the
input mapping, also in :meth:`Perception.update`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from behaviours.kernels import (
    BehaviourInputs,
    InputBuffers,
    InputRules,
    RangeSensors,
    map_inputs,
    map_inputs_reference,
)
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.vision import BATTERY, FACE, LED, N_CLASSES, GeometricVision, VisionProvider
from cyber_rodent.vision.detections import apply_noise
from cyber_rodent.vision.kernels import NearestTargets
from cyber_rodent.vision.types import DEFAULT_MAX_DISTANCE
from cyber_rodent.world import World


class Perception:
    """What every robot perceives at the current physics state, in reused buffers.

    Args:
        world: the physical world.
        vision: its vision provider.
        max_distance: metres normalised to 1 (the inputs' convention: the field's diagonal).
        range_noise: optional sensor noise (``cyber_rodent.profiles.RangeSensorNoise``) applied
            to the saturated range readings.
        backend: ``"numba"`` or ``"numpy"``: which implementation of the input mapping runs.

    Attributes:
        nearest: (n, 3) nearest LED / face / pack per robot: bearing (rad; 0 where not seen),
            distance (m; inf where not seen), visible.
        sensors: the range readings (``sensors.ranges``: (n, 8), saturated, noisy if
            ``range_noise``).
        inputs: proximities (n, 6), normalised bearings and distances (n, 3; the controller's
            face / LED / battery distances) and the behaviours' inputs (``inputs.behaviour``).
        rules: the input mapping's constants.
        fused: sensing can run inside the runner's compiled step (geometric vision without
            noise, no range noise): :meth:`update` is then not needed.
    """

    def __init__(
        self,
        world: World,
        vision: VisionProvider,
        max_distance: float = DEFAULT_MAX_DISTANCE,
        range_noise: Any = None,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        n = world.config.n_robots
        self.world = world
        self.vision = vision
        self.range_noise = range_noise
        columns = np.asarray(world.robot.proximity, dtype=np.int64)
        ranges = np.zeros((n, world.range_max.shape[1]))
        self.sensors = RangeSensors(
            # With noise the mapping reads the noisy readings (saturation leaves them as they
            # are: the noise model clips to [0, range]).
            raw=world.range_sensordata if range_noise is None else ranges,
            range_max=world.range_max,
            ranges=ranges,
            proximity_columns=columns,
            proximity_max=np.ascontiguousarray(world.range_max[:, columns]),
        )
        self.geometric = isinstance(vision, GeometricVision)
        self.noisy_vision = bool(vision.config.noise.enabled)  # configs are frozen
        if self.geometric:
            assert isinstance(vision, GeometricVision)
            self.nearest = vision.nearest
        else:
            self.nearest = NearestTargets(
                bearing=np.zeros((n, N_CLASSES)),
                distance=np.full((n, N_CLASSES), np.inf),
                visible=np.zeros((n, N_CLASSES), dtype=np.bool_),
            )
        self.inputs = InputBuffers(
            proximity=np.zeros((n, len(columns))),
            norm_bearing=np.full((n, N_CLASSES), 0.5),
            norm_distance=np.ones((n, N_CLASSES)),
            behaviour=BehaviourInputs(
                mate=np.zeros((n, 2)),
                forage=np.zeros((n, 2)),
                search=np.zeros((n, 2)),
                mate_available=np.zeros(n, dtype=np.bool_),
                forage_available=np.zeros(n, dtype=np.bool_),
            ),
        )
        self.rules = InputRules(float(max_distance), LED, FACE, BATTERY)
        self.fused = self.geometric and not self.noisy_vision and range_noise is None
        self.backend = check_backend(backend)
        self._map_inputs = bind(
            pick(self.backend, map_inputs, map_inputs_reference),
            self.sensors, self.nearest, self.rules, self.inputs,
        )  # fmt: skip
        if self.geometric and self.noisy_vision:
            self._prepare_noisy(vision)  # type: ignore[arg-type]

    def _prepare_noisy(self, vision: GeometricVision) -> None:
        n = self.world.config.n_robots
        n_targets = len(vision.target_cls)
        # Distances and bearings of all targets plus one padding column that is never seen
        # (distance inf, bearing 0): each class's targets are gathered into one (n, 3, width)
        # block, classes with fewer targets (or none: a world without packs) padded with it.
        self._masked = np.full((n, n_targets + 1), np.inf)
        self._bearings = np.zeros((n, n_targets + 1))
        self._class_cols = vision.targets.class_targets
        self._row_index = np.arange(n)[:, None]
        self._class_index = np.arange(N_CLASSES)[None, :]

    def update(self) -> InputBuffers:
        """Sense the current state; fill every buffer; return :attr:`inputs`."""
        self.see()
        if self.range_noise is not None:
            self.world.range_readings(out=self.sensors.ranges)
            self.range_noise.apply(self.sensors.ranges)
        self._map_inputs()
        return self.inputs

    def see(self) -> NearestTargets:
        """Fill :attr:`nearest` from the vision provider (see the module docstring)."""
        vision = self.vision
        if isinstance(vision, GeometricVision):
            if not self.noisy_vision:
                return vision.nearest_targets()
            self._nearest_noisy(vision)
            return self.nearest
        frame = vision.observe()
        np.copyto(self.nearest.bearing, frame.bearing)
        np.copyto(self.nearest.distance, frame.distance)
        np.copyto(self.nearest.visible, frame.visible)
        return self.nearest

    def _nearest_noisy(self, vision: GeometricVision) -> None:
        """``GeometricVision.observe`` without the blob lists: measure, add noise, pick."""
        t = vision.measure_targets()
        apply_noise(vision.config.noise, vision.rng, t.bearing, t.distance, t.visible)
        masked, bearings = self._masked[:, :-1], self._bearings[:, :-1]
        masked.fill(np.inf)
        np.copyto(masked, t.distance, where=t.visible)
        bearings.fill(0.0)  # not seen: bearing 0, the frame's convention
        np.copyto(bearings, t.bearing, where=t.visible)
        near = np.argmin(self._masked[:, self._class_cols], axis=2)  # within each class
        column = self._class_cols[self._class_index, near]  # (n, 3) target columns
        out = self.nearest
        np.copyto(out.distance, self._masked[self._row_index, column])
        np.copyto(out.bearing, self._bearings[self._row_index, column])
        np.less(out.distance, np.inf, out=out.visible)


__all__ = ["Perception"]
