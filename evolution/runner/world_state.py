"""The complete state of the physics world as plain data, for bit-identical resumes.

What a control step reads, and so what a checkpoint must restore (docs/design.md §10):

* **MuJoCo's integration state**, ``mj_getState(..., mjSTATE_INTEGRATION)``: time, qpos,
  qvel, act, actuator history, warm start, plugin state, ctrl, applied forces, equality
  activations (the docking welds), mocap poses and userdata. ``mj_step`` integrates from these
  alone: its own forward pass recomputes everything else first.
* **The derived arrays the runner reads before the next** ``mj_step`` (:data:`DERIVED_FIELDS`).
  Vision reads ``site_xpos`` / ``site_xmat`` / ``geom_xpos`` / ``geom_xmat``, the range
  sensors read ``sensordata``. The last substep's forward pass computed them at the state
  *before* its integration, so recomputing them with ``mj_forward`` at the restored state
  gives different (newer) numbers and a different run. Rather than track which ones the
  world, the vision and the sensors happen to read, every fixed-size array of ``MjData``
  (MuJoCo's ``MJDATA_POINTERS``: positions, frames, inertias, velocities, accelerations,
  forces, sensor values, mass matrix and its factors, sleep flags) that the integration state
  does not hold is saved, and written back over what ``mj_forward`` computed. Two members of
  that list are left out: ``plugin`` and ``plugin_data``, plugin instance ids and pointers,
  which the model fixes and which must never be written. Contacts and constraint rows (the
  variable-size arena) are not saved: the runner reads the contact list only within a step,
  after that step's physics, and ``mj_step`` rebuilds it; ``mj_forward`` at restore makes it
  consistent with the restored state for any other reader.
* **The model fields the run changes** (:data:`MODEL_FIELDS`): pack positions (``body_pos``,
  drawn at reset), the docking welds' relative poses (``eq_data``, set at each docking) and the
  LED and pack colours (``geom_rgba``; a pack is dark while inactive,
  ``WorldConfig.pack_reactivation_steps``).
* **The Python-side state** of the survival world (``SurvivalWorld.state()``: energy,
  recharge counters, reflexes, mating streaks, LEDs, the packs' reactivation countdowns, its
  generator) and of the vision provider (``state()``: its noise generator).

Restore order: model fields, ``mj_setState``, ``mj_forward``, the derived arrays, then the
survival world and the vision provider. Everything is written into the world's existing
``MjData`` and arrays, so every view the world, the survival mechanics, the vision and the
compiled kernels hold stays valid. A resume needs the MuJoCo version that wrote the state.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import mujoco
import numpy as np

from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.vision import VisionProvider
from cyber_rodent.world import World
from evolution.checkpoint import restore_array

#: The ``mj_getState`` / ``mj_setState`` selection: everything ``mj_step`` integrates from.
INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION
#: Model fields that the world and the survival mechanics change during a run (``geom_rgba``:
#: the LEDs, and the packs while inactive).
MODEL_FIELDS = ("body_pos", "eq_data", "geom_rgba")
#: ``MjData``'s fixed-size arrays (MuJoCo's ``MJDATA_POINTERS`` list) less the integration
#: state and the plugin ids and pointers; a test checks it against the installed MuJoCo.
DERIVED_FIELDS = (
    "qacc", "act_dot", "sensordata", "tree_asleep",
    "xpos", "xquat", "xmat", "xipos", "ximat", "xanchor", "xaxis",
    "geom_xpos", "geom_xmat", "site_xpos", "site_xmat", "cam_xpos", "cam_xmat",
    "light_xpos", "light_xdir", "subtree_com", "cdof", "cinert",
    "flexvert_xpos", "flexelem_aabb", "flexelem_krot", "flex_hessian_valid",
    "flexvert_hessian", "flexedge_hessian", "flexedge_J", "flexedge_length", "flexvert_J",
    "flexvert_length", "bvh_aabb_dyn", "flexvert_lambda", "flexvert_conage",
    "ten_wrapadr", "ten_wrapnum", "ten_J", "ten_length", "wrap_obj", "wrap_xpos",
    "actuator_length", "moment_rownnz", "moment_rowadr", "moment_colind", "actuator_moment",
    "crb", "M", "qLD", "qLDiagInv", "bvh_active",
    "tree_awake", "body_awake", "body_awake_ind", "parent_awake_ind", "dof_awake_ind",
    "flexedge_velocity", "ten_velocity", "actuator_velocity", "cvel", "cdof_dot",
    "qfrc_bias", "qfrc_spring", "qfrc_damper", "qfrc_gravcomp", "qfrc_fluid", "qfrc_adhesion",
    "qfrc_passive", "subtree_linvel", "subtree_angmom", "qH", "qHDiagInv", "qDeriv", "qLU",
    "actuator_force", "qfrc_actuator", "qfrc_smooth", "qacc_smooth", "qfrc_constraint",
    "qfrc_inverse", "cacc", "cfrc_int", "cfrc_ext",
)  # fmt: skip


@runtime_checkable
class ResumableVision(Protocol):
    """A vision provider whose mutable state (its noise generator) a checkpoint can carry."""

    def state(self) -> dict[str, Any]: ...

    def load_state(self, state: dict[str, Any]) -> None: ...


def physics_state(world: World) -> dict[str, Any]:
    """The MuJoCo side of ``world``: integration state, derived arrays, changed model fields."""
    model, data = world.model, world.data
    integration = np.empty(mujoco.mj_stateSize(model, INTEGRATION))
    mujoco.mj_getState(model, data, integration, INTEGRATION)
    return {
        "mujoco_version": mujoco.__version__,
        "integration": integration,
        "derived": {name: getattr(data, name).copy() for name in DERIVED_FIELDS},
        "model": {name: getattr(model, name).copy() for name in MODEL_FIELDS},
    }


def load_physics_state(world: World, state: dict[str, Any]) -> None:
    """Restore a :func:`physics_state` into ``world`` (a world of the same config), in place.

    Raises:
        ValueError: the state was written by another MuJoCo version or does not fit the world.
    """
    if state["mujoco_version"] != mujoco.__version__:
        raise ValueError(
            f"the physics state was written by MuJoCo {state['mujoco_version']}, this is "
            f"MuJoCo {mujoco.__version__}; a bit-identical resume needs the same version"
        )
    model, data = world.model, world.data
    derived, fields = state["derived"], state["model"]
    if sorted(derived) != sorted(DERIVED_FIELDS) or sorted(fields) != sorted(MODEL_FIELDS):
        raise ValueError("the physics state names other MjData or model fields")
    integration = state["integration"]
    size = mujoco.mj_stateSize(model, INTEGRATION)
    if not (
        isinstance(integration, np.ndarray)
        and integration.dtype == np.float64
        and integration.shape == (size,)
    ):
        raise ValueError(f"the integration state does not fit this model ({size} numbers)")
    for name in MODEL_FIELDS:
        restore_array(getattr(model, name), fields[name], f"model.{name}")
    mujoco.mj_setState(model, data, integration, INTEGRATION)
    mujoco.mj_forward(model, data)
    for name in DERIVED_FIELDS:
        restore_array(getattr(data, name), derived[name], f"data.{name}")


def capture_world(survival: SurvivalWorld, vision: VisionProvider) -> dict[str, Any]:
    """The complete state of ``survival`` (its world and physics) and of ``vision``."""
    return {
        "physics": physics_state(survival.world),
        "survival": survival.state(),
        "vision": _resumable(vision).state(),
    }


def restore_world(state: dict[str, Any], survival: SurvivalWorld, vision: VisionProvider) -> None:
    """Restore a :func:`capture_world` state into freshly built objects of the same config.

    Raises:
        ValueError: the state was written by another MuJoCo version or does not fit the world.
    """
    load_physics_state(survival.world, state["physics"])
    survival.load_state(state["survival"])
    _resumable(vision).load_state(state["vision"])


def _resumable(vision: VisionProvider) -> ResumableVision:
    if not isinstance(vision, ResumableVision):
        raise TypeError(f"{type(vision).__name__} has no state()/load_state() for checkpoints")
    return vision


__all__ = [
    "DERIVED_FIELDS",
    "MODEL_FIELDS",
    "ResumableVision",
    "capture_world",
    "load_physics_state",
    "physics_state",
    "restore_world",
]
