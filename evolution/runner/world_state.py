"""Capture and restore the complete state of the physics world, for bit-identical resumes.

What a control step reads, and so what a checkpoint must restore:

* **MjData, all of it.** ``mjSTATE_INTEGRATION`` (time, qpos, qvel, act, ctrl, warm start,
  applied forces, equality activations) is what ``mj_step`` *integrates from*, but the runner
  also reads what the last substep's forward pass *computed*: vision reads ``site_xpos`` /
  ``geom_xpos``, the range sensors read ``sensordata``, docking reads the contact list. Those
  were computed at the state *before* the last integration, so recomputing them with
  ``mj_forward`` after restoring the integration state gives different (newer) values and a
  different run. We therefore pickle the whole ``MjData`` (MuJoCo's Python bindings support
  it) and copy it back with ``mj_copyData``, into the world's existing ``MjData`` so every view
  the world, the survival mechanics and the vision hold stays valid.
* **The model fields the run changes.** Pack positions (``body_pos``, drawn at reset), the
  docking welds' relative poses (``eq_data``, set at each docking) and the LED colours
  (``geom_rgba``).
* **The Python-side state** of the survival world, the world and the vision provider: their
  numpy arrays (energy, recharge counters, reflexes, mating streaks, LED flags, ...), scalars
  and random generators. These are captured generically (every array, scalar and
  ``numpy.random.Generator`` attribute), so a new state field added to those classes is
  checkpointed without a change here; arrays are restored *in place* because other objects
  hold views of them (an attribute that is not an array yet, such as a provider's "latest
  image" before its first call, is simply assigned).
"""

from __future__ import annotations

import copy
from typing import Any

import mujoco
import numpy as np

from cyber_rodent.survival import StepEvents, SurvivalWorld
from cyber_rodent.vision import VisionProvider

_SCALARS = (bool, int, float, str, type(None), np.generic)
#: Model fields that the world and the survival mechanics change during a run.
MODEL_FIELDS = ("body_pos", "eq_data", "geom_rgba")


def snapshot_attributes(obj: object, skip: tuple[str, ...] = ()) -> dict[str, tuple[str, Any]]:
    """Copies of ``obj``'s numpy arrays, scalars, tuples of scalars and random generators."""
    saved: dict[str, tuple[str, Any]] = {}
    for name, value in vars(obj).items():
        if name in skip:
            continue
        if isinstance(value, np.ndarray):
            saved[name] = ("array", value.copy())
        elif isinstance(value, np.random.Generator):
            saved[name] = ("rng", copy.deepcopy(value.bit_generator.state))
        elif isinstance(value, StepEvents):
            saved[name] = ("events", value.copy())
        elif isinstance(value, _SCALARS) or (
            isinstance(value, tuple) and all(isinstance(v, _SCALARS) for v in value)
        ):
            saved[name] = ("value", value)
    return saved


def restore_attributes(obj: object, saved: dict[str, tuple[str, Any]]) -> None:
    """Write a :func:`snapshot_attributes` snapshot back into ``obj`` (arrays in place).

    Raises:
        ValueError: the snapshot does not fit ``obj`` (a missing attribute, a shape change):
            the checkpoint was written by a different version of the world code.
    """
    current = vars(obj)
    for name, (kind, value) in saved.items():
        if name not in current:
            raise ValueError(f"{type(obj).__name__} has no attribute {name!r} to restore")
        if kind == "array":
            target = current[name]
            if not isinstance(target, np.ndarray):  # e.g. a "latest output" not made yet
                setattr(obj, name, value.copy())
            elif target.shape != value.shape or target.dtype != value.dtype:
                raise ValueError(f"{type(obj).__name__}.{name} has changed shape or type")
            else:
                np.copyto(target, value)
        elif kind == "rng":
            current[name].bit_generator.state = copy.deepcopy(value)
        elif kind == "events":
            target = current[name]
            for slot in StepEvents.__slots__[:-1]:
                np.copyto(getattr(target, slot), getattr(value, slot))
            target.any = value.any
        else:
            setattr(obj, name, value)


def capture_world(survival: SurvivalWorld, vision: VisionProvider) -> dict[str, Any]:
    """The complete state of ``survival`` (its world and physics) and of ``vision``."""
    world = survival.world
    return {
        "mujoco_version": mujoco.__version__,
        "mjdata": world.data,  # pickled by the checkpoint writer (a full copy)
        "model": {name: getattr(world.model, name).copy() for name in MODEL_FIELDS},
        "world": snapshot_attributes(world),
        "survival": snapshot_attributes(survival),
        "vision": snapshot_attributes(vision),
    }


def restore_world(state: dict[str, Any], survival: SurvivalWorld, vision: VisionProvider) -> None:
    """Restore a :func:`capture_world` state into freshly built objects of the same config.

    Raises:
        ValueError: the state was written by another MuJoCo version or does not fit the world.
    """
    if state["mujoco_version"] != mujoco.__version__:
        raise ValueError(
            f"the physics state was written by MuJoCo {state['mujoco_version']}, this is "
            f"MuJoCo {mujoco.__version__}; a bit-identical resume needs the same version"
        )
    world = survival.world
    model = world.model
    for name, value in state["model"].items():
        target = getattr(model, name)
        if target.shape != value.shape:
            raise ValueError(f"model.{name} has shape {target.shape}, the checkpoint {value.shape}")
        target[...] = value
    data = state["mjdata"]
    sizes = ("nq", "nv", "nu", "na", "nbody", "ngeom", "nsite", "neq", "nsensordata")
    theirs = tuple(getattr(data.model, s) for s in sizes)
    ours = tuple(getattr(model, s) for s in sizes)
    if theirs != ours:
        mismatch = {s: (a, b) for s, a, b in zip(sizes, theirs, ours, strict=True) if a != b}
        raise ValueError(f"the physics state is of another model (checkpoint, this): {mismatch}")
    mujoco.mj_copyData(world.data, model, data)
    restore_attributes(world, state["world"])
    restore_attributes(survival, state["survival"])
    restore_attributes(vision, state["vision"])
