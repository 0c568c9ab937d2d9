"""The ``README.md`` of a deployment bundle, rendered from its ``bundle.json`` record only.

Rendering from the record (:func:`evolution.lab.deploy.spec.bundle_spec`) and nothing else means
the README cannot state a number the bundle does not carry. The sections a robot engineer
needs, in order: the files and versions, how to install and check the bundle (exact commands,
tested in a clean environment), the control period, the robot frame and sign conventions, the
sensors, every input's normalisation, the controller, the wheel commands, how to load the
behaviours (runnable code, tested) and their portable form, and the survival bookkeeping the
robot must run itself as pseudo-code beside ``reference_step.py``.
"""

from __future__ import annotations

from typing import Any

#: Section headings, in order (the tests check that each is present).
SECTIONS = (
    "Contents",
    "Versions",
    "Installing and checking",
    "Control period",
    "Frame and sign conventions",
    "Sensors",
    "Inputs and their normalisation",
    "Controller",
    "Wheel commands",
    "Loading the behaviours",
    "Portable behaviours",
    "Survival bookkeeping",
    "Agents",
)


def _g(value: Any) -> str:
    """A number as a reader expects it: 0.2, 200, 3.25269."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def _xyz(values: list[float]) -> str:
    return "(" + ", ".join(f"{v:+.4f}" for v in values) + ")"


def _table(header: list[str], rows: list[list[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_g(c) for c in row) + " |" for row in rows]
    return lines


def _load_code(spec: dict[str, Any]) -> list[str]:
    names = ", ".join(f'"{n}"' for n in spec["behaviours"]["order"])
    return [
        "```python",
        "import numpy as np",
        f"import torch  # torch == {spec['torch']['version']}",
        "",
        "# run in the bundle directory",
        "programs = {",
        '    name: torch.export.load(f"{name}.pt2").module()',
        f"    for name in ({names})",
        "}",
        "states = np.array([[0.5, 0.25], [0.75, 1.0]])  # (batch, 2) float64 in [0, 1]",
        'commands = programs["forage"](torch.from_numpy(states)).numpy()  # int64 (batch,)',
        "```",
    ]


def _portable_code(spec: dict[str, Any]) -> list[str]:
    return [
        "```python",
        "import json",
        "import math",
        "",
        "import numpy as np",
        "",
        "# run in the bundle directory: numpy only",
        'described = json.loads(open("behaviours.json").read())',
        'arrays = np.load("behaviours.npz")',
        'forage = next(b for b in described["behaviours"] if b["name"] == "forage")',
        "x = (0.75, 0.25)  # normalised (bearing, distance) of the nearest pack",
        'cell = tuple(math.floor(v * s) for v, s in zip(x, forage["scale"]))',
        'command = int(arrays[forage["greedy"]][cell])  # wheel command index',
        "```",
    ]


def _install(spec: dict[str, Any]) -> list[str]:
    install = spec.get("install") or {}
    vectors = spec.get("test_vectors") or {}
    if not install:
        return ["This bundle states no install commands.", ""]
    out = [
        f"`reference_step.py` needs Python {install['python']} and numpy; torch only for the "
        "`.pt2` programs. In the bundle directory:",
        "",
        "```bash",
        *install["commands"],
        install["check"],
        "```",
        "",
    ]
    if install.get("torch"):
        out += [
            f"`{install['torch']}`: {install['torch_note']}. Without torch, the first command "
            f"is `{install['numpy_only']}` and the check runs the portable behaviours alone.",
            "",
        ]
    if vectors:
        out += [
            f"`--check` replays `{vectors['file']}`: {vectors['rows']} rows recorded from the "
            f"simulator itself ({vectors['recorded']}). Each row holds one step's raw inputs "
            "(8 ranges, the nearest LED, face and pack, energy, previous LED, docked, "
            "recharge steps) and what the simulator decided (behaviour, LEDs, recharge "
            "decision, wheel command, the controller inputs). It prints `PASS n/n`, or `FAIL` "
            "with the first row that differs, and exits 0 or 1. "
            f"`{install['check_all']}` runs every backend installed (numpy, the greedy "
            "table, torch) on the same rows; a port to another language replays the same rows.",
            "",
        ]
    return out


def _pseudo_code(spec: dict[str, Any]) -> list[str]:
    s = spec["survival"]
    energy, recharge, reflex = s["energy"], s["recharge"], s["reflex"]
    sharing, mating = s["time_sharing"], s["mating"]
    dt = spec["control"]["dt_s"]
    after_mating = "start_reflex()" if reflex["after_mating"] else "# no reflex after mating"
    return [
        "```text",
        "constants (bundle.json survival.*, control.dt_s):",
        f"  DT = {_g(dt)} s                      INITIAL_ENERGY = {_g(energy['initial'])}",
        f"  MAX_ENERGY = {_g(energy['max'])}               ENERGY_DECAY = {_g(energy['decay_per_step'])}"  # noqa: E501
        " per step",
        f"  RECHARGE_GAIN = {_g(energy['recharge_gain_per_step'])} per step    "
        f"MAX_RECHARGE_STEPS = {recharge['max_steps']}",
        f"  TIME_SHARING = {sharing['steps']} steps        LIFETIME = {sharing['lifetime_steps']} "
        "steps",
        f"  MATE_DISTANCE = {_g(mating['ir_port_distance_max_m'])} m      "
        f"MATE_ANGLE = {_g(mating['ir_port_angle_max_deg'])} deg   "
        f"MATE_STEPS = {mating['consecutive_steps']}",
        f"  REFLEX_STEPS = {reflex['min_steps']}..{reflex['max_steps']}    "
        f"REFLEX_SPEED = {_g(reflex['wheel_speed_m_s'])} m/s    "
        f"FITNESS_UNIT = {_g(s['fitness']['time_unit_steps'])} steps",
        "",
        "per agent k (row k of controller_weights.npy), kept across its slots:",
        "  energy[k] = INITIAL_ENERGY; age[k] = 0; batteries[k] = 0; matings[k] = 0; "
        "partners[k] = []",
        "robot state: active = 0; slot_steps = 0; docked = False; recharge_steps = 0;",
        "             reflex_left = 0; mate_streak = 0; led = False",
        "",
        "start_reflex():",
        f"  reflex_left = uniform integer in [{reflex['min_steps']}, {reflex['max_steps']}]",
        "  reflex_wheels = (-REFLEX_SPEED, +REFLEX_SPEED)  # left turn, p = 0.5",
        "               or (+REFLEX_SPEED, -REFLEX_SPEED)  # right turn",
        "",
        "undock():  docked = False; recharge_steps = 0; start_reflex()",
        "",
        "every DT seconds:",
        "  k = active; died = False; mated = False",
        "  ranges, bearing, distance, visible = read sensors     # 8 m; 3 rad, 3 m, 3 flags",
        "  d = controller.step(ranges, bearing, distance, visible, energy[k], led,",
        "                      docked, recharge_steps)            # reference_step.py",
        "  if docked and not d.continue_recharge:                # decided before the step",
        "      undock()",
        "  in_reflex = reflex_left > 0",
        "  if in_reflex:       wheels = reflex_wheels            # the controller is ignored",
        "  elif docked:        wheels = (0, 0)",
        "  else:               wheels = d.wheels",
        "  led = d.led                                           # dark while recharging",
        "  mate_signal = d.behaviour == MATE and not docked and not in_reflex",
        "  drive wheels, show led, send mate_signal over IR, wait DT",
        "",
        "  # energy",
        "  if in_reflex: reflex_left -= 1",
        "  if docked:",
        "      energy[k] = min(energy[k] + RECHARGE_GAIN, MAX_ENERGY); recharge_steps += 1",
        "      if recharge_steps >= MAX_RECHARGE_STEPS or energy[k] >= MAX_ENERGY: undock()",
        "  else:",
        "      energy[k] -= ENERGY_DECAY",
        "      if energy[k] <= 0: energy[k] = 0; died = True    # LED off, wheels stopped",
        "  # docking: charging teeth touch a pack's electrode, pack centre within "
        f"{_g(recharge['dock_bearing_tolerance_deg'])} deg",
        "  if not (died or docked or in_reflex or reflex_left > 0) and teeth on electrode:",
        "      docked = True; recharge_steps = 0; batteries[k] += 1"
        + ("" if recharge["capture_rule"] == "docking" else "   # on the first recharge step"),
        "  age[k] += 1; slot_steps += 1",
        "  # IR mating: both robots signal Mate and each IR port faces the other",
        "  if mate_signal and not (died or docked) and the partner's likewise",
        "          and port distance <= MATE_DISTANCE",
        "          and both ports point at each other within MATE_ANGLE:",
        "      mate_streak += 1",
        "  else: mate_streak = 0",
        "  mated = mate_streak >= MATE_STEPS                    # one partner per step",
        "  if mated:",
        "      send (weights[k], fitness(k)); receive (partner_weights, partner_fitness)",
        "      partners[k].append((partner_weights, partner_fitness)); matings[k] += 1",
        f"      mate_streak = 0; {after_mating}",
        "",
        "  # time sharing",
        "  if died or mated or slot_steps >= TIME_SHARING or age[k] >= LIFETIME:",
        "      # the run's evolution replaces a dead agent and one that completed LIFETIME",
        "      # (docs/design.md §5); without on-board evolution restart it: energy[k] =",
        "      # INITIAL_ENERGY, age[k] = batteries[k] = matings[k] = 0, partners[k] = []",
        "      active = (active + 1) % n_agents; slot_steps = 0",
        "      if docked: undock()                               # the recharge was k's",
        "      # the new agent keeps its own energy; led stays as the previous agent left it",
        "",
        "fitness(k) = batteries[k] / (age[k] / FITNESS_UNIT)    # 0 when age[k] == 0",
        "```",
    ]


def render_readme(spec: dict[str, Any]) -> str:
    """The bundle's README.md text (see the module docstring)."""
    control = spec["control"]
    conv = spec["conventions"]
    sensors = spec["sensors"]
    camera = sensors["camera"]
    controller = spec["controller"]
    survival = spec["survival"]
    selection = spec.get("selection") or {}
    provenance = spec.get("provenance") or {}
    behaviours = spec["behaviours"]
    out: list[str] = ["# Cyber Rodent deployment bundle", ""]
    out += [
        f"{controller['n_agents']} evolved agents for a real Cyber Rodent. Every number below is "
        "taken from `bundle.json`, which takes it from the run's resolved configuration "
        "(`run_config` in `bundle.json`).",
        "",
        "## Contents",
        "",
    ]
    portable = spec.get("portable") or {}
    vectors = spec.get("test_vectors") or {}
    files = [
        [f"`{behaviours['files'][name]}`", f"behaviour {name}: greedy policy, `torch.export` "
         "program"]
        for name in behaviours["order"] if name in behaviours["files"]
    ]  # fmt: skip
    if portable:
        held = "action values and greedy tables" if portable["action_values"] else \
            "greedy tables"  # fmt: skip
        files += [
            [f"`{portable['spec']}`", "the behaviours' tile coding, hash, input normalisation "
             "and wheel commands, in words and pseudo-code"],
            [f"`{portable['arrays']}`", f"the behaviours' {held} (numpy arrays; no torch)"],
        ]  # fmt: skip
    files += [
        [f"`{controller['file']}`", f"({controller['n_agents']}, "
         f"{controller['selection_weights'][1]}) float64 controller weights, one row per agent"],
        ["`bundle.json`", "every number and convention of this README, machine-readable"],
        ["`reference_step.py`", "one control step in plain numpy (torch optional); `--check` "
         "replays the test vectors"],
    ]  # fmt: skip
    if vectors:
        files += [[f"`{vectors['file']}`", f"{vectors['rows']} recorded simulator steps: "
                   "inputs and the decisions taken"]]  # fmt: skip
    out += _table(["file", "content"], files) + [""]

    versions = spec["versions"]
    out += ["## Versions", ""]
    out += _table(["package", "version"], [[k, v] for k, v in sorted(versions.items())])
    out += [
        "",
        f"Load the `.pt2` programs with torch **{spec['torch']['version']}** exactly: "
        f"{spec['torch']['note']}. Wheel command set version {spec['command_set_version']}.",
        "",
    ]
    out += ["## Installing and checking", ""] + _install(spec)

    out += [
        "## Control period",
        "",
        f"One control step is **{_g(control['dt_s'])} s** ({_g(control['rate_hz'])} Hz): sense, "
        "decide, drive for one period. Every count of steps below (energy, recharge, reflex, "
        "time sharing, mating, lifetime) is in these steps.",
        "",
    ]

    out += [
        "## Frame and sign conventions",
        "",
        f"- Frame: {spec['frame']}.",
        f"- Bearing: {conv['bearing']}.",
        f"- Wheels: order ({', '.join(conv['wheel_order'])}); {conv['wheel_unit']}; "
        f"{conv['wheel_sign']}.",
        f"- Wheel radius {_g(conv['wheel_radius_m'])} m, half wheel base "
        f"{_g(conv['half_wheel_base_m'])} m, top speed {_g(conv['top_speed_m_s'])} m/s.",
        "",
    ]

    reading = sensors["rangefinder_reading"]
    out += ["## Sensors", "", "### Rangefinders", "", f"{reading[0].upper()}{reading[1:]}.", ""]
    rows = [
        [r["index"], r["name"], r["angle_deg"], _xyz(r["position_m"]), _xyz(r["direction"]),
         r["range_max_m"], "-" if r["controller_input"] is None else r["controller_input"]]
        for r in sensors["rangefinders"]
    ]  # fmt: skip
    out += _table(
        ["reading", "name", "angle (deg)", "position (m)", "direction", "range max (m)",
         "controller input"],
        rows,
    )  # fmt: skip
    out += [
        "",
        "### Omnidirectional camera",
        "",
        f"{camera['type'].capitalize()}, at {_xyz(camera['position_m'])} m, elevations "
        f"{_g(camera['elevation_deg'][0])} to {_g(camera['elevation_deg'][1])} deg, targets "
        f"up to {_g(camera['max_range_m'])} m. Per class ({', '.join(camera['classes'])}): "
        f"{camera['per_class']}. Smallest blob (px): "
        f"{', '.join(map(str, camera['min_blob_area_px']))}.",
        "",
    ]
    out += [f"- {name}: {text}" for name, text in camera["targets"].items()]
    port = sensors["ir_port"]
    out += [
        "",
        "### IR port",
        "",
        f"At {_xyz(port['position_m'])} m, pointing {_xyz(port['direction'])}; the mating "
        "geometry is measured port to port.",
        "",
    ]

    norm = spec["normalisation"]
    out += [
        "## Inputs and their normalisation",
        "",
        f"### Controller ({len(controller['inputs'])} inputs, in order)",
        "",
    ]
    out += _table(["index", "input", "value"], [
        [i["index"], i["name"], i["value"]] for i in controller["inputs"]
    ])  # fmt: skip
    out += [
        "",
        "### Behaviours (2 inputs each)",
        "",
        f"- Bearing: {norm['bearing']}.",
        f"- Distance: {norm['distance']}.",
        f"- Proximity: {norm['proximity']}, range_max per sensor as above.",
    ]
    out += [f"- {name}: {text}." for name, text in behaviours["inputs"].items()]
    out += [f"- Program input: {behaviours['input']}.", ""]

    out += [
        "## Controller",
        "",
        f"Weights row layout: recharge `[{controller['recharge_weights'][0]}:"
        f"{controller['recharge_weights'][1]}]`, selection `[{controller['selection_weights'][0]}"
        f":{controller['selection_weights'][1]}]`, {controller['selection_layout']}.",
        "",
        f"- Selection: {controller['selection_rule']}.",
        f"- LED: {controller['led_rule']}.",
        f"- Recharge (while docked): {controller['recharge_rule']}.",
        "",
    ]

    commands = spec["commands"]
    out += ["## Wheel commands", "", f"Speeds: {commands['unit']}.", ""]
    out += _table(["index", "name", "left", "right"], [
        [i, n, s[0], s[1]] for i, (n, s) in enumerate(zip(commands["names"], commands["speeds"],
                                                          strict=True))
    ])  # fmt: skip
    out += [""]

    out += ["## Loading the behaviours", ""]
    if behaviours["files"]:
        out += [
            f"Input: {behaviours['input']}. Output: {spec['torch']['output']}. From Python, "
            f"with the torch version above (`{spec['torch']['load']}`):",
            "",
        ]
        out += _load_code(spec) + [""]
    else:
        out += ["This bundle holds no `.pt2` programs: its behaviours are the portable form "
                "below.", ""]  # fmt: skip

    out += ["## Portable behaviours", ""]
    if portable:
        backends = " and ".join(f"`{b}`" for b in portable["backends"])
        out += [
            f"`{portable['spec']}` and `{portable['arrays']}` hold the same greedy policies "
            "without torch, for a port to another language: per behaviour its tile coder "
            "(resolution, tilings, offsets, the hash seed and each tiling's start value, table "
            "size), the `lowbias32` hash (constants and algorithm, `hash`), the algorithm in "
            "words (`algorithm`) and as pseudo-code (`pseudo_code`), the input normalisation "
            "and the wheel commands. `<name>_greedy` is the command of every input cell "
            "`(floor(x0 * scale0), floor(x1 * scale1))`: the tile coder reads an input only "
            "through these two integers, so one lookup gives exactly the tile-coded policy's "
            f"command. `reference_step.py` runs them with numpy only (backends {backends}; "
            "`--backend torch` for the programs). One lookup, in the bundle directory:",
            "",
        ]
        out += _portable_code(spec) + [""]
    else:
        out += ["This bundle holds no portable behaviours (written before them).", ""]

    energy, recharge, reflex = survival["energy"], survival["recharge"], survival["reflex"]
    sharing, mating = survival["time_sharing"], survival["mating"]
    out += [
        "## Survival bookkeeping",
        "",
        "`reference_step.py` decides; the robot keeps the books itself, as the simulator does:",
        "",
        f"- Energy: starts at {_g(energy['initial'])}, capped at {_g(energy['max'])}; "
        f"{_g(energy['decay_per_step'])} lost per step off the pack, "
        f"{_g(energy['recharge_gain_per_step'])} gained per recharge step; {energy['death']}.",
        f"- Recharging: {recharge['ends']}. Captures: {recharge['capture']} (capture rule "
        f"\"{recharge['capture_rule']}\").",
        f"- Reflex: {reflex['rule']}; {reflex['turn_per_step_rad']:.3g} rad per step, "
        f"{reflex['turn_deg'][0]:.0f}-{reflex['turn_deg'][1]:.0f} deg in all. After recharging "
        "and after an agent switch while docked; after mating: "
        f"{'yes' if reflex['after_mating'] else 'no'}.",
        f"- Time sharing: {sharing['switch']} ({sharing['agents_per_robot_in_run']} agents per "
        "robot in the run).",
        f"- IR mating: {mating['signal']}; IR ports at most {_g(mating['ir_port_distance_max_m'])}"
        f" m apart, each pointing at the other within {_g(mating['ir_port_angle_max_deg'])} deg, "
        f"for {mating['consecutive_steps']} consecutive steps "
        f"({_g(mating['exchange_duration_s'])} s). Exchanged: {mating['exchanged']}.",
        f"- Fitness: {survival['fitness']['rule']}.",
        "",
    ]
    out += _pseudo_code(spec) + [""]

    out += ["## Agents", ""]
    if selection.get("note"):
        out += [selection["note"][0].upper() + selection["note"][1:] + ".", ""]
    agents = provenance.get("agents") or []
    if agents:
        out += _table(["row", "fitness", "mated", "robot", "slot"], [
            [i, a["fitness"], a["mated"], a["robot"], a["slot"]] for i, a in enumerate(agents)
        ])  # fmt: skip
        out += [""]
    if provenance.get("run"):
        out += [f"From run `{provenance['run']}`, checkpoint `{provenance.get('checkpoint')}`.",
                ""]  # fmt: skip
    return "\n".join(out)


__all__ = ["SECTIONS", "render_readme"]
