"""The content of a bundle's ``bundle.json``: everything a robot engineer needs, from one source.

Every number comes from the run's resolved :class:`~evolution.runner.RunConfig`, from the
robot's model (:mod:`cyber_rodent.robot`, the run's ``world.robot``), from the command table or
from the robot's compiled MJCF model (sensor positions); the README
(:mod:`evolution.lab.deploy.readme`) is rendered from this dict only, so the two cannot
disagree. The meaning of the rules is docs/design.md §4 (the robot),
§5 (the paper's rules) and §9 (the choices where the paper is silent).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import platform
from importlib import metadata
from typing import Any

import numpy as np

from cyber_rodent.robot import RobotModel
from evolution.controllers import CONTROLLERS, ControllerLayout, resolve
from evolution.input_kernels import row_record
from evolution.runner.config import RunConfig

#: Bundle layout version (``bundle.json`` ``format``); the reference step checks it. Format 2:
#: each controller input states the observation it is computed from (the input table's).
BUNDLE_FORMAT = 2
#: The distributions whose versions a bundle records (torch's is the one that matters: a
#: ``.pt2`` program is loaded with the torch version that wrote it).
RECORDED_DISTRIBUTIONS = ("cyber-rodent", "torch", "numpy", "mujoco")
#: How to load one exported behaviour (the README shows it as runnable code).
LOAD_CALL = "torch.export.load(path).module()"
#: Where pip finds torch's builds with a local version tag (``2.13.0+cpu``: the CPU wheels); a
#: plain version (no tag) comes from PyPI.
TORCH_INDEX = "https://download.pytorch.org/whl/{tag}"
#: The oldest Python that runs ``reference_step.py``.
REFERENCE_PYTHON = "3.10"


def _version(distribution: str) -> str | None:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:  # pragma: no cover - depends on the installation
        return None


def _rounded(values: Any, digits: int = 6) -> list[float]:
    """Model numbers as the MJCF file writes them (float32 in the compiled model)."""
    return [round(float(v), digits) + 0.0 for v in values]


def robot_geometry(robot: RobotModel | None = None) -> dict[str, Any]:
    """Sensor, camera and IR-port poses in the robot frame, read from the compiled robot model.

    Args:
        robot: the robot (default: the paper's, ``cyber_rodent.robot.cyber_rodent()``).

    Returns:
        ``rangefinders`` (per range sensor of the robot's sensor table, in reading order:
        name, angle, range, position, direction), ``camera`` and ``ir_port`` (position,
        direction).
    """
    import mujoco

    from cyber_rodent.robot import cyber_rodent

    robot = robot or cyber_rodent()
    parts = robot.parts
    model = mujoco.MjModel.from_xml_path(str(robot.xml_path()))

    def pose(site: str) -> tuple[list[float], list[float]]:
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
        if i < 0:
            raise ValueError(f"the robot model has no site {site!r}")
        matrix = np.zeros(9)
        mujoco.mju_quat2Mat(matrix, model.site_quat[i])
        position = model.site_pos[i] + model.body_pos[model.site_bodyid[i]]
        return _rounded(position), _rounded(matrix.reshape(3, 3)[:, 2], 4)

    rangefinders = []
    proximity = robot.proximity
    for index, row in enumerate(robot.range_sensors):
        name, angle, reach = row.name, row.bearing_deg, row.limit
        position, direction = pose(row.site_name)
        rangefinders.append(
            {
                "index": index,
                "name": name,
                "angle_deg": float(angle),
                "range_max_m": float(reach),
                "position_m": position,
                "direction": direction,
                "proximity_input": (
                    proximity.index(index) if index in proximity else None
                ),
            }
        )
    camera_position, _ = pose(parts.camera_site)
    port_position, port_direction = pose(parts.ir_port_site)
    return {
        "rangefinders": rangefinders,
        "camera_position_m": camera_position,
        "ir_port": {"position_m": port_position, "direction": port_direction},
    }


def install_record(versions: dict[str, Any]) -> dict[str, Any]:
    """How a robot engineer installs what ``reference_step.py`` needs, as exact commands.

    numpy is pinned to the version that wrote the bundle; torch (only for the ``.pt2``
    programs) to the exact build, from the wheel index that serves builds with its local tag
    (``2.13.0+cpu``: PyTorch's CPU index; PyPI has no ``+cpu`` builds).
    """
    numpy_pin = f"numpy=={versions['numpy']}" if versions.get("numpy") else "numpy"
    numpy_only = f"python3 -m venv .venv && .venv/bin/pip install {numpy_pin}"
    record: dict[str, Any] = {
        "python": f">={REFERENCE_PYTHON}",
        "numpy": numpy_pin,
        "torch": None,
        "torch_index_url": None,
        "torch_note": None,
        "commands": [numpy_only],
        "numpy_only": numpy_only,
        "check": ".venv/bin/python reference_step.py --check",
        "check_all": ".venv/bin/python reference_step.py --check --backend all",
    }
    build = versions.get("torch")
    if build:
        public, _, tag = str(build).partition("+")
        index = TORCH_INDEX.format(tag=tag) if tag else None
        where = f"builds tagged +{tag} come from the PyTorch wheel index {index}, not PyPI" \
            if index else "from PyPI"  # fmt: skip
        install = f".venv/bin/pip install torch=={public}" + (
            f" --index-url {index}" if index else ""
        )
        record.update(
            torch=f"torch=={public}",
            torch_index_url=index,
            torch_note=f"the {build} build ({where}); needed only for the .pt2 programs "
            "(reference_step.py --backend torch)",
            commands=[f"{numpy_only} && {install}"],
        )
    return record


def check_deployable(config: RunConfig) -> ControllerLayout:
    """The run's controller, if a bundle can hold it: a controller whose rule the reference step
    implements, over inputs a robot computes from its observations.

    Raises:
        ValueError: one line naming ``evolution.controller`` or the input that cannot go.
    """
    layout = resolve(config.evolution)
    if not layout.spec.deployable:
        able = ", ".join(name for name, spec in CONTROLLERS.items() if spec.deployable)
        raise ValueError(
            f"evolution.controller = {layout.spec.name!r}: a deployment bundle holds only "
            f"controllers its reference step implements ({able})"
            + ("; this one has per-agent memory the reference step does not carry"
               if layout.state_size else "")
        )  # fmt: skip
    for row in layout.inputs:
        if row.observation is None:
            raise ValueError(
                f"controller input {row.name!r} states no observation a robot computes it "
                "from (ControllerInput.observation): a deployment bundle cannot hold it"
            )
    return layout


def _controller_inputs(
    layout: ControllerLayout, config: RunConfig, max_distance: float
) -> list[dict[str, Any]]:
    """The controller inputs in order (the input table's rows), each with its normalisation
    written out with the run's numbers."""
    evo = config.evolution
    numbers = {
        "max_energy": f"{evo.max_energy:g}",
        "max_recharge_steps": f"{evo.max_recharge_steps}",
        "max_distance": f"{max_distance:.6g}",
    }
    return [row_record(row, i, numbers) for i, row in enumerate(layout.inputs)]


def _survival(config: RunConfig, robot: RobotModel) -> dict[str, Any]:
    """The bookkeeping a robot runs itself: energy, recharging, reflex, time sharing, mating."""
    from cyber_rodent.commands import motor_scale
    from cyber_rodent.survival.energy import recharge_gain

    s, evo = config.survival, config.evolution
    dt = s.control_dt
    reflex_speed = s.reflex_wheel_speed * motor_scale(robot)
    turn = reflex_speed * dt / robot.half_wheel_base
    return {
        "energy": {
            "initial": s.initial_energy,
            "max": s.max_energy,
            "decay_per_step": s.energy_decay,
            "recharge_rate_per_step": s.recharge_rate,
            "decay_while_recharging": s.decay_while_recharging,
            "recharge_gain_per_step": recharge_gain(s),
            "death": "a step's decay that brings the energy to 0 or below kills the agent "
            "(energy set to 0); recharge steps never decay unless decay_while_recharging",
        },
        "recharge": {
            "max_steps": s.max_recharge_steps,
            "dock_bearing_tolerance_deg": s.dock_bearing_tolerance_deg,
            "capture_rule": s.capture_rule,
            "capture": "each docking counts as one captured battery"
            if s.capture_rule == "docking"
            else "a docking counts as a captured battery on its first recharge step (a docking "
            "whose recharge the controller stops at once does not count)",
            "ends": "the recharge controller says stop (decided before the step), or after "
            f"the step that reaches {s.max_recharge_steps} consecutive recharge steps or "
            f"{s.max_energy:g} energy, or at an agent switch; every end starts the reflex",
        },
        "reflex": {
            "after_recharge": True,
            "after_mating": s.mate_reflex,
            "after_switch_while_docked": True,
            "min_steps": s.reflex_min_steps,
            "max_steps": s.reflex_max_steps,
            "wheel_speed_m_s": reflex_speed,
            "turn_per_step_rad": turn,
            "turn_deg": [
                math.degrees(turn * s.reflex_min_steps),
                math.degrees(turn * s.reflex_max_steps),
            ],
            "rule": f"a spin of {s.reflex_min_steps} to {s.reflex_max_steps} steps (uniform) at "
            f"{reflex_speed:g} m/s rim speed, left (-v, +v) or right (+v, -v) with "
            "p = 0.5; the controller's wheel commands are ignored, and the robot can neither "
            "dock nor mate, until it ends",
        },
        "time_sharing": {
            "steps": evo.time_sharing_steps,
            "lifetime_steps": evo.lifetime_steps,
            "agents_per_robot_in_run": evo.subpopulation_size,
            "switch": "to the next agent in round-robin order after "
            f"{evo.time_sharing_steps} steps of the current agent's slot, or when it mates, "
            f"dies or completes its {evo.lifetime_steps}-step lifetime",
        },
        "mating": {
            "ir_port_distance_max_m": s.mate_distance,
            "ir_port_angle_max_deg": s.mate_angle_deg,
            "consecutive_steps": s.mate_consecutive_steps,
            "exchange_duration_s": s.mate_consecutive_steps * dt,
            "signal": "the active agent's chosen behaviour is Mate, and the robot is alive, "
            "not docked and not in its reflex",
            "exchanged": "each side sends its active agent's genome "
            f"({resolve(evo).length} float64, controller_weights layout) and fitness; each "
            "stores the partner's (genome, fitness) and counts one mating; both slots end",
            "partners_per_step": 1,
        },
        "fitness": {
            "time_unit_steps": evo.fitness_time_unit,
            "rule": f"batteries captured / (steps lived / {evo.fitness_time_unit:g}); 0 before "
            "the first step",
        },
    }


def bundle_spec(
    config: RunConfig,
    weights: np.ndarray,
    behaviour_files: dict[str, str],
    values_sha256: dict[str, str],
    *,
    selection: dict[str, Any] | None = None,
    provenance: dict[str, Any] | None = None,
    test_vectors: dict[str, Any] | None = None,
    action_values: bool = True,
) -> dict[str, Any]:
    """The ``bundle.json`` record of a bundle (see :mod:`evolution.lab.deploy`).

    Args:
        config: the run's resolved configuration (every rule's number comes from it).
        weights: (n_agents, genes) the bundled agents' controller weights (39: the paper's).
        behaviour_files: behaviour name → its ``.pt2`` file name.
        values_sha256: behaviour name → checksum of the action values it was exported from.
        selection: how the agents were chosen (:meth:`Selection.note` and counts).
        provenance: where the agents came from (run, checkpoint, per-agent fitness).
        test_vectors: how the bundle's test vectors were recorded
            (:func:`~evolution.lab.deploy.vectors.record_test_vectors`).
        action_values: ``behaviours.npz`` holds the tile-coded action values (else the
            greedy tables only).
    """
    from behaviours.inputs import BEHAVIOUR_NAMES
    from cyber_rodent.commands import COMMAND_SET_VERSION, WHEEL_COMMANDS, command_speeds
    from cyber_rodent.robot import robot_model
    from cyber_rodent.vision.types import CLASS_NAMES, DEFAULT_MAX_DISTANCE

    robot = robot_model(config.world.robot)

    evo, survival, camera = config.evolution, config.survival, config.camera
    layout = check_deployable(config)
    n_inputs = layout.n_inputs
    recharge, selection_genes = layout.block("recharge"), layout.block("selection")
    max_distance = float(DEFAULT_MAX_DISTANCE)
    geometry = robot_geometry(robot)
    columns = {row.arg: i for i, row in enumerate(layout.inputs) if row.observation == "proximity"}
    for finder in geometry["rangefinders"]:
        k = finder["proximity_input"]
        finder["controller_input"] = None if k is None else columns.get(k)
    versions = {name: _version(name) for name in RECORDED_DISTRIBUTIONS}
    try:
        import torch
    except ImportError:  # pragma: no cover - a bundle without programs needs no torch
        versions["torch"] = None
    else:
        versions["torch"] = str(torch.__version__)  # the exact build, e.g. "2.13.0+cpu"
    versions["python"] = platform.python_version()
    behaviour_input = "float64 (batch, 2) in [0, 1]; outside [0, 1] or NaN raises RuntimeError"
    return {
        "format": BUNDLE_FORMAT,
        "package_version": versions["cyber-rodent"],
        "versions": versions,
        "torch": {
            "version": versions["torch"],
            "load": LOAD_CALL,
            "input": behaviour_input,
            "output": "int64 (batch,) wheel command index (commands.names)",
            "note": "torch.export does not promise that another torch version reads these "
            "programs",
        },
        "install": install_record(versions),
        "portable": {
            "spec": "behaviours.json",
            "arrays": "behaviours.npz",
            "action_values": action_values,
            "backends": ["numpy", "table"] if action_values else ["table"],
            "note": "the behaviours without torch: tile-coded action values and greedy tables "
            "(numpy arrays) and their indexing in words and pseudo-code, for a port to another "
            "language; reference_step.py runs them with numpy only",
        },
        "test_vectors": test_vectors or {},
        "control": {"dt_s": survival.control_dt, "rate_hz": 1.0 / survival.control_dt},
        "frame": "robot frame: x forward, y left, z up, origin on the floor under the wheel "
        "axle; metres",
        "conventions": {
            "bearing": "radians in (-pi, pi], 0 straight ahead, positive to the left "
            "(counter-clockwise seen from above)",
            "wheel_order": ["left", "right"],
            "wheel_sign": "positive drives the wheel's rim forward; (-v, +v) spins left "
            "(counter-clockwise), (+v, -v) right",
            "wheel_unit": "wheel rim speed, m/s; motor angular speed = speed / wheel_radius_m "
            "rad/s",
            "wheel_radius_m": robot.wheel_radius,
            "half_wheel_base_m": robot.half_wheel_base,
            "top_speed_m_s": robot.top_speed,
        },
        "sensors": {
            "rangefinders": geometry["rangefinders"],
            "rangefinder_reading": "metres along the sensor's direction from its position; "
            "no hit within range_max_m reads range_max_m",
            "camera": {
                "type": "omnidirectional, 360 degrees horizontally",
                "position_m": geometry["camera_position_m"],
                "elevation_deg": [camera.elevation_min_deg, camera.elevation_max_deg],
                "max_range_m": camera.max_range,
                "classes": list(CLASS_NAMES),
                "targets": {
                    "led": "another robot's green LED ring (its camera axis)",
                    "face": "the centre of another robot's red face plate",
                    "battery": "a blue battery pack's axis",
                },
                "per_class": "the nearest target's bearing (rad, robot frame), distance (m, "
                "horizontal, from the camera axis to the target's vertical axis) and whether "
                "one is seen",
                "min_blob_area_px": list(camera.min_blob_area),
                "noise": dataclasses.asdict(camera.noise),
            },
            "ir_port": geometry["ir_port"],
        },
        "command_set_version": COMMAND_SET_VERSION,
        "controller": {
            "file": "controller_weights.npy",
            "n_agents": int(weights.shape[0]),
            "weights_sha256": hashlib.sha256(weights.tobytes()).hexdigest(),
            "kind": layout.spec.name,
            "input_order": [row.name for row in layout.inputs],
            "inputs": _controller_inputs(layout, config, max_distance),
            "outputs": list(BEHAVIOUR_NAMES),
            "recharge_weights": [recharge.start, recharge.stop],
            "selection_weights": [selection_genes.start, selection_genes.stop],
            "selection_layout": f"output-major (3, {n_inputs}): row = output, column = "
            "input_order",
            "selection_rule": f"activations = W (3 x {n_inputs}) @ inputs; the available "
            "behaviour with the largest activation wins (Mate needs an LED or face in view, "
            "Forage a battery, Search is always available; ties to the lower index)",
            "recharge_rule": f"w0*energy/{evo.max_energy:g} + "
            f"w1*steps/{evo.max_recharge_steps} + w2 <= 0: continue recharging",
            "led_rule": "on iff activation(mate) > activation(forage); dark while recharging",
        },
        "normalisation": {
            "max_energy": float(evo.max_energy),
            "max_recharge_steps": int(evo.max_recharge_steps),
            "max_distance": max_distance,
            "range_sensors": [row.name for row in robot.range_sensors],
            "range_max": [float(robot.range_sensors[i].limit) for i in robot.proximity],
            "proximity_sensors": list(robot.proximity),
            "proximity": "clip(1 - range / range_max, 0, 1)",
            "bearing": "clip((bearing_rad + pi) / (2 pi), 0, 1); unseen: bearing 0 rad (0.5)",
            "distance": f"clip(distance_m / {max_distance:.6g}, 0, 1); unseen: 1",
        },
        "behaviours": {
            "order": list(BEHAVIOUR_NAMES),
            "files": behaviour_files,
            "values_sha256": values_sha256,
            "input": behaviour_input,
            "inputs": {
                "mate": "(bearing, distance), normalised, of the nearest green LED if one is "
                "seen, else of the nearest red face",
                "forage": "(bearing, distance), normalised, of the nearest blue battery pack",
                "search": "(largest, second largest) of the six proximity readings",
            },
        },
        "commands": {
            "names": [c.name for c in WHEEL_COMMANDS],
            "speeds": command_speeds(robot).tolist(),
            "unit": "wheel rim speed, m/s (left, right)",
        },
        "survival": _survival(config, robot),
        "selection": selection or {},
        "provenance": provenance or {},
        "run_config": dataclasses.asdict(config),
    }


__all__ = [
    "BUNDLE_FORMAT",
    "LOAD_CALL",
    "REFERENCE_PYTHON",
    "TORCH_INDEX",
    "bundle_spec",
    "check_deployable",
    "install_record",
    "robot_geometry",
]
