"""The rules of the survival world as one validated configuration (docs/design.md §5)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cyber_rodent import constants as C
from cyber_rodent.commands import DESIGN_TOP_SPEED
from cyber_rodent.validation import (
    boolean,
    check_integer,
    check_number,
    choice,
    integer,
    number,
    validate_fields,
)

#: Upper bound of the energy fields: large enough for any experiment, small enough to be finite.
ENERGY_LIMIT = 1e9
#: Upper bound of the step counts of a rule (recharge, mating): 1e6 control steps are 55
#: simulated hours at 0.2 s, longer than any experiment; a larger count is a typo.
MAX_STEP_COUNT = 1_000_000
#: The values of ``SurvivalConfig.capture_rule``: a capture is the docking itself, or the
#: docking's first recharge step.
CAPTURE_RULES = ("docking", "recharge")


@dataclass(frozen=True)
class SurvivalConfig:
    """Every rule of the survival world, with the paper's defaults (Table 1, docs/design.md §5).

    Attributes:
        initial_energy: energy of a newborn agent (paper: 100).
        max_energy: energy cap (paper: 200).
        energy_decay: energy lost per control step when not recharging (paper: 1).
        recharge_rate: energy gained per recharge step (paper: 5).
        decay_while_recharging: also drain ``energy_decay`` on recharge steps (net +4 instead of
            +5). Off by default: 40 steps x 5 = 200 = ``max_energy`` is the paper's arithmetic.
        max_recharge_steps: consecutive recharge steps after which recharging ends (paper: 40).
        control_dt: seconds of simulated time per control step; must be a whole number of
            physics timesteps. 0.2 s (5 Hz, a plausible cycle for the CR's on-board omni vision)
            brings the batteries per life nearest the paper's (docs/calibration.md,
            docs/design.md §9.1).
        reflex_min_steps: shortest post-recharge rotation reflex, control steps.
        reflex_max_steps: longest reflex; the length is drawn uniformly in [min, max]. At the
            default spin speed a step of 0.2 s turns 0.75 rad, so 2..4 steps turn 86°..172°.
        reflex_wheel_speed: wheel rim speed of the reflex spin, m/s, on the Cyber Rodent;
            another robot (``world.robot``) spins at this times its top speed over the Cyber
            Rodent's, as the discrete commands do (``commands.motor_scale``).
        dock_bearing_tolerance_deg: a teeth/electrode contact is a capture only if the pack's
            centre lies within this angle of the robot's heading. With 6 cm wide teeth and a
            9 cm electrode ring, 15° admits contacts with the pack's axis up to about 4.7 cm
            off the robot's centre line, and refuses the glancing contacts of a teeth corner
            further out (16-29°).
        mate_angle_deg: each IR port must face the other port within this angle (paper: about
            ±15°; docs/design.md §5).
        mate_distance: largest IR port-to-port distance for an exchange, m (docs/design.md
            §5: 0.35).
        mate_consecutive_steps: control steps the mating condition must hold: 2, a 0.4 s IR
            exchange, brings the matings per life nearest the paper's without stopping most
            exchanges (docs/calibration.md, docs/design.md §9.7).
        capture_rule: when a docking counts as a captured battery (``StepEvents.captured``):
            "docking" on the step the teeth dock onto the pack; "recharge" only on the
            docking's first recharge step, so a docking whose recharge the controller stops
            at once is no capture. The paper counts captured batteries but leaves open whether
            a docking without a recharge counts (docs/design.md §9.5).
        mate_reflex: after a successful IR exchange both robots perform the rotation reflex, as
            after recharging. The paper turns a robot away from the pack it recharged from "to
            prevent ... continuing to recharge from the same battery" and says nothing of what
            follows a mating; without a reflex the next agents of two robots still nose to nose
            mate at once, and such chained matings were most of CE's (docs/calibration.md,
            docs/design.md §9.7).
        mate_min_energy: a robot signals Mate, and so can mate, only while its active agent's
            energy at the start of the step is above this. 0 is the paper's rule (any living
            agent may mate); later Cyber Rodent work let only well-fed robots mate
            (docs/design.md §9.29).
        tip_uprightness: the watchdog counts a robot as tipped while its uprightness (chassis
            z-axis · world z) is below this: 0.5, tilted past 60° (docs/design.md §9.35).
        stuck_steps: the watchdog counts a robot as stuck after this many control steps in a
            row of commanding motion (driving or turning) without getting ``stuck_distance``
            away or turning ``stuck_turn``, neither docked nor in its reflex (25 steps: 5 s).
        stuck_distance: m, the progress that keeps a robot that commands motion from being
            stuck (5 s at the slowest forward command would cover over 0.3 m).
        stuck_turn: rad, the turn that keeps a robot that commands motion from being stuck
            (5 s at the slowest turning command would turn it 3.1 rad).
        stuck_progress: a control step in which a robot achieves this share of the travel or
            the turn it commanded (speed x control step; turn rate (right - left) / 2 / half
            wheel base) counts as moving and restarts the count: a robot that dithers,
            spinning left and right on the spot, is not held. 0.2: dithering robots achieved
            a third of their commanded turn per step, held robots a few per cent
            (docs/design.md §9.35).
        rescue: an experimenter rescues robots: after ``rescue_after_steps`` control steps
            tipped or stuck, a robot is set upright at rest at the nearest free spot, its energy
            and agent unchanged. Off: the paper's robots were never helped.
        rescue_after_steps: control steps tipped or stuck before a rescue.
    """

    initial_energy: float = number(
        100.0, 0.0, ENERGY_LIMIT, low_open=True, source="paper Table 1"
    )
    max_energy: float = number(200.0, 0.0, ENERGY_LIMIT, low_open=True, source="paper Table 1")
    energy_decay: float = number(
        1.0, 0.0, ENERGY_LIMIT, unit="per control step", source="paper Table 1"
    )
    recharge_rate: float = number(
        5.0, 0.0, ENERGY_LIMIT, unit="per recharge step", source="paper Table 1"
    )
    decay_while_recharging: bool = boolean(False, source="docs/design.md §9.2")
    max_recharge_steps: int = integer(
        40, 1, MAX_STEP_COUNT, unit="control steps", source="paper Table 1"
    )
    control_dt: float = number(
        0.2, 0.0, 10.0, low_open=True, unit="s", source="docs/design.md §9.1"
    )
    reflex_min_steps: int = integer(2, 0, 1000, unit="control steps", source="docs/design.md §9.6")
    reflex_max_steps: int = integer(4, 0, 1000, unit="control steps", source="docs/design.md §9.6")
    reflex_wheel_speed: float = number(
        0.3, 0.0, DESIGN_TOP_SPEED, low_open=True, unit="m/s", source="docs/design.md §9.6"
    )
    dock_bearing_tolerance_deg: float = number(
        15.0, 0.0, 90.0, low_open=True, unit="deg", source="docs/design.md §9.4"
    )
    mate_angle_deg: float = number(
        15.0, 0.0, 90.0, low_open=True, unit="deg", source="docs/design.md §9.7"
    )
    mate_distance: float = number(
        0.35, 0.0, C.FIELD_SIZE * math.sqrt(2), low_open=True, unit="m",
        source="docs/design.md §9.7",
    )  # fmt: skip
    mate_consecutive_steps: int = integer(
        2, 1, MAX_STEP_COUNT, unit="control steps", source="docs/design.md §9.7"
    )
    capture_rule: str = choice("docking", CAPTURE_RULES, source="docs/design.md §9.5")
    mate_reflex: bool = boolean(True, source="docs/design.md §9.7")
    mate_min_energy: float = number(
        0.0, 0.0, ENERGY_LIMIT, unit="energy units", source="docs/design.md §9.29"
    )
    tip_uprightness: float = number(0.5, -1.0, 1.0, source="docs/design.md §9.35")
    stuck_steps: int = integer(
        25, 1, MAX_STEP_COUNT, unit="control steps", source="docs/design.md §9.35"
    )
    stuck_distance: float = number(
        0.05, 0.0, 1.0, low_open=True, unit="m", source="docs/design.md §9.35"
    )
    stuck_turn: float = number(
        0.5, 0.0, math.pi, low_open=True, unit="rad", source="docs/design.md §9.35"
    )
    stuck_progress: float = number(0.2, 0.0, 1.0, unit="share", source="docs/design.md §9.35")
    rescue: bool = boolean(False, source="docs/design.md §9.35")
    rescue_after_steps: int = integer(
        25, 1, MAX_STEP_COUNT, unit="control steps", source="docs/design.md §9.35"
    )

    def __post_init__(self) -> None:
        validate_fields(self)
        # The cap holds a newborn's energy, and a step drains or gains at most the cap.
        check_number("max_energy", self.max_energy, self.initial_energy, ENERGY_LIMIT)
        check_number("energy_decay", self.energy_decay, 0.0, self.max_energy)
        check_number("recharge_rate", self.recharge_rate, 0.0, self.max_energy)
        check_number("mate_min_energy", self.mate_min_energy, 0.0, self.max_energy)
        check_integer("reflex_max_steps", self.reflex_max_steps, self.reflex_min_steps, 1000)
