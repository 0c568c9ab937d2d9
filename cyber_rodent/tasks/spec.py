"""Every task of the Cyber Rodent defined once: a :class:`TaskSpec` per task, in one registry.

A task's spec says everything that makes it that task: its field (robots, packs), which robots
act and which are parked, how an episode starts (re-drawn until a start condition holds), how it
ends (success, death, the episode length), its rewards as named terms
(:mod:`cyber_rodent.tasks.rewards`), and what its robots' LED, Mate signal and recharge decision
are. Every consumer reads the spec and nothing else about the task, and runs it through the one
episode loop of :mod:`cyber_rodent.tasks.episode` (:class:`~cyber_rodent.tasks.episode.
TaskEpisode`):

* the dm-control tasks (:func:`cyber_rodent.tasks.load`; :mod:`cyber_rodent.tasks.base`),
* the Gymnasium environments (:class:`cyber_rodent.gym_env.CyberRodentEnv`),
* the PettingZoo colony (:mod:`cyber_rodent.colony_env`: the ``survival`` task with every robot
  an agent by default, any registered task with its learners the agents),
* the behaviours' training and evaluation episodes (``behaviours.episodes``), and the rewards
  of evolution's learning mode (``evolution.learning``: the goals and Search's progress).

The built-in tasks, in registry order:

==========  ============  ========  =====================  =================  ===============
task        field         learners  start                  ends               rewards
==========  ============  ========  =====================  =================  ===============
survival    4 robots,     all       any placement          all robots dead;   sparse: capture,
            5 packs                                        400 steps          mating
forage      1 robot,      1         the robot sees a pack  docking (success)  sparse: success;
            5 packs                                        or death; 100      shaped: shaping,
                                                                              step_cost, goal
mate        2 robots,     2         each sees the other's  IR exchange        as Forage's
            no packs                LED or face            (success) or
                                                           death; 100
search      4 robots,     1 (3      any placement          death; 100 steps   sparse: new_cell;
            5 packs       parked)                                             shaped: progress,
                                                                              collision
==========  ============  ========  =====================  =================  ===============

Forage and Mate: the learners' Mate signal is the task's (Mate: on; its LEDs start on), Forage
keeps recharging when it docks (the docking ends the episode anyway), Search's learner never
recharges: in every interface a docking is released at once (``release_docking``). Parked
robots stand still with their LEDs off. The behaviour tasks run with endless energy in their
episodes and Gymnasium and PettingZoo environments (``endless_energy``; energy is no
behaviour's task). The Gymnasium ``Survival`` is one robot alone (``solo``), with its LED and
Mate signal off: only its recharge decision is its own.

Why each built-in task is as it is:

* **Forage** and **Mate** are available to the evolved controller only with their target in view
  (the paper's §3.4), so their episodes start in view of it. Forage's target is the nearest
  pack; Mate's the other robot's green LED, else its red face. Discounting makes an earlier
  goal worth more.
* **Mate**'s partner is no script: both robots run Mate and are learners (the behaviours train
  it by self-play with one shared table). The dm-control task takes one action per robot, so
  it stays a plain ``dm_env`` environment with both robots' experience available; the
  Gymnasium environment moves robot 1 with its ``partner_policy``. Their LEDs start on (the LED
  is on when Mate wins over Forage) and both always signal Mate.
* **Search** is the always-available exploration behaviour: obstacle avoidance from the
  proximity sensors, among walls, packs and robots that stand still (parked), so that the
  learner meets static obstacles of every kind. Driving straight at ``reference_speed`` earns 1
  per step, spinning 0, pushing against a wall at most ``−collision_penalty``. The behaviours
  train with a penalty of 3 (with 1 the learned policy touched obstacles about 3× as often);
  the dm-control task keeps its historical default of 1 (``control_scales``).
* **Survival** is the paper's simulation: every robot keeps its energy above 0 by docking and
  reproduces by IR exchanges; it is rewarded for the two measures the paper scores (captured
  batteries, matings). Dying costs no reward: a dead robot earns nothing more, and stands
  still with its LED dark (agent replacement is evolution's job).

Adding a task is one :func:`register` call with its spec; every consumer then offers it by name
(``tasks.load(name)``, ``CyberRodentEnv(name)``, ``ColonyEnv(task=name)``, ``cyber-rodent view
--task name`` in the process that registered it): they all take the names from
:func:`task_names`. Example::

    from cyber_rodent.tasks import rewards
    from cyber_rodent.tasks.spec import Field, TaskSpec, register

    register(TaskSpec(
        name="wander", summary="two robots move about", field=Field(robots=2, packs=3),
        learners=1, sparse=(rewards.NEW_CELL_TERM,), shaped=rewards.SEARCH_TERMS,
        measure="coverage_cells", episode_steps=50,
    ))
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cyber_rodent.survival import StepEvents
from cyber_rodent.tasks import rewards as R
from cyber_rodent.tasks.rewards import RewardScales, RewardTerm
from cyber_rodent.vision import BATTERY, FACE, LED, VisionFrame, normalise_distance

#: The robots' switches, in action order: LED (green), Mate signal, recharge decision.
SWITCHES = ("led", "mate", "recharge")
#: What the Gymnasium environments report in ``info`` as the task's measure.
MEASURES = ("is_success", "coverage_cells", "captures")
#: Which deaths end an episode: any learner's, or every robot's.
DEATHS = ("any", "all")
#: The kinds of reward a task offers.
REWARD_KINDS = ("sparse", "shaped")


@dataclass(frozen=True)
class Field:
    """The robots and battery packs in a task's field."""

    robots: int
    packs: int


@dataclass(frozen=True)
class StartCondition:
    """What must hold in the first frame of an episode; the placement is re-drawn until it does.

    Attributes:
        description: what holds, in words ("a pack in view").
        holds: ``holds(frame)``: the condition in a vision frame of every robot.
        min_packs: packs the condition needs in the field.
    """

    description: str
    holds: Callable[[VisionFrame], bool]
    min_packs: int = 0


@dataclass(frozen=True)
class TaskSpec:
    """One task, declared once (see the module docstring).

    Attributes:
        name: the task's name (lower case; ``tasks.load(name)``, ``CyberRodentEnv(name)``).
        summary: the task in one line.
        field: robots and packs in the field.
        learners: robots that act, the first ones (None: every robot); the others are parked
            (wheels stopped, LEDs off).
        start: the start condition (None: any placement).
        success: per robot, whether the step's events reach the task's goal (None: no goal);
            robot 0's is the episode's success, which ends it as a terminal state.
        death: which deaths end an episode: ``"any"`` learner's or ``"all"`` robots'.
        sparse: the sparse reward's terms (the task's success as a reward).
        shaped: the shaped reward's terms (the behaviours' training reward; () if none).
        target: per robot, the normalised distance of the task's target in a frame (what the
            ``shaping`` term and the behaviour's inputs look at; None: no target).
        led: the learners' LED (None: each learner's action sets it).
        mate: the learners' Mate signal (None: each learner's action sets it).
        recharge: every robot's recharge decision while docked (None: each learner's action).
        release_docking: a docking of a learner is released at the end of the step in which
            it docked, without the reflex (in every interface: the episode loop does it).
        endless_energy: the behaviour episodes and the Gymnasium and PettingZoo environments
            run with endless energy (``rewards.episode_rules``); otherwise the survival rules
            as given (the dm-control tasks always run the rules they are given).
        episode_steps: control steps after which an episode is cut.
        measure: what the Gymnasium environment reports as the task's measure in ``info``
            (:data:`MEASURES`).
        control_reward: the dm-control task's reward, ``"sparse"`` or ``"shaped"``.
        control_scales: the default scales of the dm-control task's reward; the fields its
            terms read are options of the task (``tasks.load("search", collision_penalty=2)``).
        solo: the one-learner variant the Gymnasium environment runs (None: the task itself).
    """

    name: str
    summary: str
    field: Field
    learners: int | None = 1
    start: StartCondition | None = None
    success: Callable[[StepEvents], np.ndarray] | None = None
    death: str = "any"
    sparse: tuple[RewardTerm, ...] = (R.SUCCESS,)
    shaped: tuple[RewardTerm, ...] = ()
    target: Callable[[VisionFrame], np.ndarray] | None = None
    led: bool | None = False
    mate: bool | None = False
    recharge: bool | None = False
    release_docking: bool = False
    endless_energy: bool = True
    episode_steps: int = 100
    measure: str = "is_success"
    control_reward: str = "sparse"
    control_scales: RewardScales = dataclasses.field(default_factory=RewardScales)
    solo: TaskSpec | None = None

    def __post_init__(self) -> None:
        if not self.name or self.name != self.name.lower():
            raise ValueError(f"name: must be a non-empty lower-case name, got {self.name!r}")
        if self.field.robots < 1 or self.field.packs < 0:
            raise ValueError(f"field: needs at least 1 robot and 0 packs, got {self.field}")
        if self.learners is not None and not 1 <= self.learners <= self.field.robots:
            raise ValueError(
                f"learners: must be in [1, {self.field.robots}] or None, got {self.learners}"
            )
        for name, value, allowed in (
            ("death", self.death, DEATHS),
            ("measure", self.measure, MEASURES),
            ("control_reward", self.control_reward, REWARD_KINDS),
        ):
            if value not in allowed:
                raise ValueError(f"{name}: must be one of {', '.join(allowed)}, got {value!r}")
        if not self.sparse:
            raise ValueError("sparse: a task needs a sparse reward")
        if not self.rewards(self.control_reward):
            raise ValueError(f"control_reward: the task has no {self.control_reward} reward")
        if self.measure == "is_success" and self.success is None:
            raise ValueError("measure: 'is_success' needs a success")
        needs_target = any(R.DISTANCE in t.needs for t in (*self.sparse, *self.shaped))
        if needs_target and self.target is None:
            raise ValueError("target: a reward term needs the target's distance")

    # --- derived -------------------------------------------------------------------------------
    @property
    def title(self) -> str:
        """The name as in the Gymnasium ids (``CyberRodent/<Title>-v0``) and in messages."""
        return self.name.title()

    @property
    def parked(self) -> int:
        """Robots of the field that do not act: wheels stopped, LEDs off (Search's 3)."""
        return self.field.robots - self.n_learners(self.field.robots)

    @property
    def switches(self) -> tuple[str, ...]:
        """The switches the learners' actions set (:data:`SWITCHES` order)."""
        return tuple(name for name in SWITCHES if getattr(self, name) is None)

    @property
    def sees(self) -> bool:
        """The task looks at what the robots see (a start condition or a target)."""
        return self.start is not None or self.target is not None

    @property
    def gym(self) -> TaskSpec:
        """The variant the one-learner Gymnasium environment runs."""
        return self.solo or self

    def n_learners(self, n_robots: int) -> int:
        """Robots that act in a field of ``n_robots``."""
        return n_robots if self.learners is None else self.learners

    def rewards(self, kind: str) -> tuple[RewardTerm, ...]:
        """The terms of the ``"sparse"`` or ``"shaped"`` reward (() if the task has none)."""
        return self.shaped if kind == "shaped" else self.sparse

    def reward_options(self, kind: str) -> tuple[str, ...]:
        """The :class:`RewardScales` fields the ``kind`` reward's terms read."""
        names: list[str] = []
        for term in self.rewards(kind):
            names += [s for s in term.scales if s not in names]
        return tuple(names)

    def hardware_field(self, n_robots: int, n_packs: int) -> Field:
        """The field on hardware of ``n_robots`` and ``n_packs``: the hardware's packs if the
        task has any, its robots if the task has parked ones (the learners stay)."""
        field = self.field
        return Field(
            robots=n_robots if self.parked else field.robots,
            packs=n_packs if field.packs > 0 else 0,
        )

    def switch_values(self, n_robots: int) -> dict[str, np.ndarray]:
        """Every robot's fixed switches in a field of ``n_robots``: the learners' LED and Mate
        signal (off for parked robots), every robot's recharge decision; False where a
        learner's action sets it."""
        k = min(self.n_learners(n_robots), n_robots)
        led = np.zeros(n_robots, dtype=bool)
        mate = np.zeros(n_robots, dtype=bool)
        led[:k] = bool(self.led)
        mate[:k] = bool(self.mate)
        recharge = np.full(n_robots, bool(self.recharge))
        return {"led": led, "mate": mate, "recharge": recharge}

    def reached(self, events: StepEvents) -> bool:
        """The step reached the task's goal: robot 0's success (False without a goal)."""
        return self.success is not None and bool(self.success(events)[0])

    def dead(self, alive: np.ndarray, k: int) -> bool:
        """A death ends the episode: any of the ``k`` learners' (``"any"``) or every robot's."""
        if self.death == "all":
            return not alive.any()
        return not alive[:k].all()


# --- the pieces of the built-in tasks --------------------------------------------------------
def sees_pack(frame: VisionFrame) -> bool:
    """Robot 0 sees a battery pack."""
    return bool(frame.visible[0, BATTERY])


def see_each_other(frame: VisionFrame) -> bool:
    """Robots 0 and 1 each see the other's LED or face."""
    sees = frame.visible[:2, LED] | frame.visible[:2, FACE]
    return bool(sees.all())


def docked(events: StepEvents) -> np.ndarray:
    """Per robot: it docked onto a pack this step."""
    return events.docked


def mated(events: StepEvents) -> np.ndarray:
    """Per robot: it took part in an IR exchange this step."""
    exchanged: np.ndarray = events.mate_partner >= 0
    return exchanged


def pack_distance(frame: VisionFrame) -> np.ndarray:
    """Per robot, the normalised distance of the nearest pack (1 unseen)."""
    d: np.ndarray = normalise_distance(frame.distance[:, BATTERY], frame.visible[:, BATTERY])
    return d


def partner_distance(frame: VisionFrame) -> np.ndarray:
    """Per robot, the normalised distance of the nearest LED, else of the nearest face."""
    led = normalise_distance(frame.distance[:, LED], frame.visible[:, LED])
    face = normalise_distance(frame.distance[:, FACE], frame.visible[:, FACE])
    d: np.ndarray = np.where(frame.visible[:, LED], led, face)
    return d


A_PACK_IN_VIEW = StartCondition("a pack in view", sees_pack, min_packs=1)
IN_VIEW_OF_EACH_OTHER = StartCondition("the two robots in view of each other", see_each_other)

_SURVIVAL = TaskSpec(
    name="survival",
    summary="the paper's colony: every robot keeps its energy up by docking and mates by IR",
    field=Field(robots=4, packs=5),
    learners=None,
    death="all",
    sparse=(R.CAPTURE, R.MATING),
    led=None,
    mate=None,
    recharge=None,
    endless_energy=False,
    episode_steps=400,
    measure="captures",
)
SURVIVAL = dataclasses.replace(
    _SURVIVAL,
    solo=dataclasses.replace(_SURVIVAL, field=Field(robots=1, packs=5), led=False, mate=False),
)
FORAGE = TaskSpec(
    name="forage",
    summary="one robot approaches the nearest battery pack and docks onto it",
    field=Field(robots=1, packs=5),
    start=A_PACK_IN_VIEW,
    success=docked,
    shaped=R.APPROACH,
    target=pack_distance,
    recharge=True,
)
MATE = TaskSpec(
    name="mate",
    summary="two robots, both running Mate, meet nose to nose for an IR exchange",
    field=Field(robots=2, packs=0),
    learners=2,
    start=IN_VIEW_OF_EACH_OTHER,
    success=mated,
    shaped=R.APPROACH,
    target=partner_distance,
    led=True,
    mate=True,
)
SEARCH = TaskSpec(
    name="search",
    summary="one robot moves about the field without bumping into the parked robots, packs "
    "and walls",
    field=Field(robots=4, packs=5),
    sparse=(R.NEW_CELL_TERM,),
    shaped=R.SEARCH_TERMS,
    release_docking=True,
    measure="coverage_cells",
    control_reward="shaped",
    control_scales=RewardScales(collision_penalty=1.0),
)

# --- the registry ----------------------------------------------------------------------------
_REGISTRY: dict[str, TaskSpec] = {}


def register(spec: TaskSpec) -> TaskSpec:
    """Add a task; every consumer offers it by name from then on.

    Raises:
        ValueError: ``spec`` is no TaskSpec, or a task of that name exists.
    """
    if not isinstance(spec, TaskSpec):
        raise ValueError(f"spec: must be a TaskSpec, got {type(spec).__name__}")
    if spec.name in _REGISTRY:
        raise ValueError(f"a task named {spec.name!r} is registered already")
    _REGISTRY[spec.name] = spec
    return spec


def unregister(name: str) -> None:
    """Remove a task added with :func:`register` (the built-in tasks stay).

    Raises:
        ValueError: no such task, or a built-in one.
    """
    if name in BUILT_IN or name not in _REGISTRY:
        raise ValueError(f"{name!r} is no registered task that can be removed")
    del _REGISTRY[name]


def task_names() -> tuple[str, ...]:
    """The registered tasks' names, in registry order."""
    return tuple(_REGISTRY)


def task_spec(name: str) -> TaskSpec:
    """The spec of task ``name`` (case-insensitive).

    Raises:
        ValueError: for an unknown name (the message lists the registered ones).
    """
    spec = _REGISTRY.get(name.lower()) if isinstance(name, str) else None
    if spec is None:
        raise ValueError(f"unknown task {name!r}; allowed names: {', '.join(_REGISTRY)}")
    return spec


for _spec in (SURVIVAL, FORAGE, MATE, SEARCH):
    register(_spec)
#: The built-in tasks' names, in registry order.
BUILT_IN = task_names()

__all__ = [
    "BUILT_IN",
    "FORAGE",
    "MATE",
    "MEASURES",
    "SEARCH",
    "SURVIVAL",
    "SWITCHES",
    "Field",
    "StartCondition",
    "TaskSpec",
    "register",
    "task_names",
    "task_spec",
    "unregister",
]
