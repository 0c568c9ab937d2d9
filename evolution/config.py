"""Every number of the paper's evolution, as frozen, validated configuration.

The paper (Elfwing et al., "Biologically Inspired Embodied Evolution of Survival") fixes its
numbers in two tables; docs/design.md §5 fixes what the paper leaves open. Each number is a
field here with the paper's value as its default, so a run's behaviour is fully described by
its config and seed, and any deviation from the paper is an explicit, visible field change.

- :class:`GeneticConfig` is Table 2 (the genome and its operators) plus the CE tournament size
  (§4.1).
- :class:`EvolutionConfig` is Table 1 (the survival task and the population) plus the fitness
  rule's time unit, and holds a :class:`GeneticConfig`.

The energy numbers (initial 100, maximum 200, maximum recharge 40 steps) also live in the survival
world's own config, which applies them physically. They appear here because the evolution side
needs them too: new agents are born with ``initial_energy`` and the controller normalises its
energy and recharge-step inputs by ``max_energy`` and ``max_recharge_steps``. The runner that
wires the two checks that both configs agree.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cyber_rodent.survival.config import ENERGY_LIMIT, MAX_STEP_COUNT
from cyber_rodent.validation import (
    boolean,
    check_integer,
    check_number,
    choice,
    integer,
    names,
    number,
    validate_fields,
)
from cyber_rodent.world import MAX_ROBOTS
from evolution.controllers import controller_names, paper_blocks, resolve
from evolution.input_kernels import N_INPUTS, PAPER, input_names_allowed, select_inputs

#: The two evolution methods: embodied evolution and the centralised GA baseline (paper §4.1).
METHODS = ("ee", "ce")

#: Genes of the paper's controller (§3.5) over the declared inputs
#: (:data:`evolution.input_kernels.INPUTS`): 3 for the recharge decision + 3 x 12 for
#: selection = 39. Another controller's length follows from its blocks
#: (:attr:`EvolutionConfig.genome_length`).
GENOME_LENGTH = sum(block.size for block in paper_blocks(N_INPUTS))
#: Learning mode's genes after the controller weights (docs/design.md §11): four learning
#: meta-parameters (learning rate, discount, trace decay, exploration ε) and the six weights
#: of the potential-based shaping reward (two inputs for each of Mate, Forage, Search).
N_META_GENES = 4
N_SHAPING_GENES = 6
N_LEARNING_GENES = N_META_GENES + N_SHAPING_GENES
#: Length of a learning-mode genome.
LEARNING_GENOME_LENGTH = GENOME_LENGTH + N_LEARNING_GENES
#: Most virtual agents in a colony (100x the paper's 100). A robot runs its subpopulation one
#: life after another, so a generation lasts about ``population_size / n_robots x
#: lifetime_steps`` control steps: at this bound, 4 robots and the paper's lifetime, a million.
#: Larger numbers are typos (a digit too many), refused before a run allocates or writes.
MAX_POPULATION = 10_000
#: Most generations of one run or sweep member (830x the paper's 120): a generation is at least
#: one life of every agent, so a larger number cannot finish and is a typo.
MAX_GENERATIONS = 100_000
#: Largest step budget of one run (``--max-steps``): about 170 days of simulated robot time at
#: the default 0.2 s control step, far more than any run needs.
MAX_RUN_STEPS = 100_000_000


@dataclass(frozen=True)
class GeneticConfig:
    """The genome and its genetic operators (paper Table 2, §3.5, §4.1).

    Attributes:
        initial_weight_low: lower bound of the uniform initial weights (paper: -1).
        initial_weight_high: upper bound of the uniform initial weights (paper: 1).
        crossover_probability: chance that offspring come from one-point crossover rather than
            reproduction (copying) of a parent (paper: 0.6).
        mutation_probability: independent chance per weight of being mutated (paper: 0.1).
        mutation_low: lower bound of the uniform number added to a mutated weight (paper: -0.5).
        mutation_high: upper bound of the uniform number added to a mutated weight (paper: 0.5).
        tournament_size: individuals per tournament in the centralised GA (paper §4.1: 2).
        meta_mutation_width: learning mode only: a mutated learning meta-gene (kept in [0, 1],
            mapped onto its parameter's range) moves by U[-w, w] and is reflected back into
            [0, 1]. The paper has no meta-genes; 0.1 moves a parameter by at most a tenth of
            its range per mutation.
    """

    initial_weight_low: float = number(-1.0, source="paper Table 2")
    initial_weight_high: float = number(1.0, source="paper Table 2")
    crossover_probability: float = number(0.6, 0.0, 1.0, source="paper Table 2")
    mutation_probability: float = number(0.1, 0.0, 1.0, source="paper Table 2")
    mutation_low: float = number(-0.5, source="paper Table 2")
    mutation_high: float = number(0.5, source="paper Table 2")
    tournament_size: int = integer(2, 1, unit="individuals", source="paper §4.1")
    meta_mutation_width: float = number(0.1, 0.0, 1.0, low_open=True, source="docs/design.md §11")

    def __post_init__(self) -> None:
        validate_fields(self)
        check_number(
            "initial_weight_low",
            self.initial_weight_low,
            high=self.initial_weight_high,
            high_open=True,
        )
        check_number("mutation_low", self.mutation_low, high=self.mutation_high)


#: Where a newborn's action values come from in learning mode.
LEARNING_INITS = ("zero", "shipped")
#: What an offspring inherits in learning mode.
INHERITANCE_MODES = ("darwinian", "lamarckian")
#: Precision of the learned action values.
TABLE_DTYPES = ("float32", "float64")


@dataclass(frozen=True)
class LearningConfig:
    """Learning mode: every virtual agent learns its behaviours during its life (docs/design.md
    §11). Off by default: the paper's agents run the shipped, fixed behaviours.

    Each agent keeps private action values for Mate, Forage and Search and updates the one it
    runs with Sarsa(λ), tile coding and replacing traces (the algorithm of
    ``behaviours/sarsa.py``), from its own rewards. Its genome adds four meta-genes in [0, 1],
    each mapped linearly onto its range below, and six shaping weights (docs/design.md §11).

    Attributes:
        enabled: run in learning mode.
        init: a newborn's action values: ``"zero"`` (all equal: it starts from scratch) or
            ``"shipped"`` (the shipped trained behaviours).
        inheritance: ``"darwinian"`` (genes only: every newborn starts from ``init``) or
            ``"lamarckian"`` (an offspring starts from the learned values of the agent whose
            slot it takes; spare-list and random genomes start from ``init``).
        table_dtype: precision of the stored action values, ``"float32"`` (half the memory
            and checkpoint size) or ``"float64"`` (the precision of ``behaviours/sarsa.py``).
            The update itself always computes in float64.
        alpha_low, alpha_high: range of the evolved step size α (for the whole feature
            vector; each active tile moves by α / tilings), within (0, 1].
        gamma_low, gamma_high: range of the evolved discount γ, within [0, 1].
        lam_low, lam_high: range of the evolved trace decay λ, within [0, 1].
        epsilon_low, epsilon_high: range of the evolved exploration rate ε of the ε-greedy
            policy, within [0, 1].
        goal_reward: reward of Forage's docking and of Mate's IR exchange (the training
            reward of ``behaviours/``), ≥ 0.
        step_cost: reward subtracted on every step of Forage and Mate, ≥ 0.
        collision_penalty: Search's reward subtracted per step in contact, ≥ 0.
        reference_speed: Search's forward speed (m/s) that earns the full progress reward.
        trace_cutoff: traces below this are dropped (set to 0), in (0, 1), as in
            ``behaviours/sarsa.py``.
    """

    enabled: bool = boolean(False, source="docs/design.md §11")
    init: str = choice("zero", LEARNING_INITS, source="docs/design.md §11")
    inheritance: str = choice("darwinian", INHERITANCE_MODES, source="docs/design.md §11")
    table_dtype: str = choice("float32", TABLE_DTYPES, source="docs/design.md §11")
    alpha_low: float = number(0.01, 0.0, 1.0, low_open=True, source="docs/design.md §11")
    alpha_high: float = number(0.5, 0.0, 1.0, low_open=True, source="docs/design.md §11")
    gamma_low: float = number(0.8, 0.0, 1.0, source="docs/design.md §11")
    gamma_high: float = number(0.999, 0.0, 1.0, source="docs/design.md §11")
    lam_low: float = number(0.0, 0.0, 1.0, source="docs/design.md §11")
    lam_high: float = number(0.99, 0.0, 1.0, source="docs/design.md §11")
    epsilon_low: float = number(0.0, 0.0, 1.0, source="docs/design.md §11")
    epsilon_high: float = number(0.3, 0.0, 1.0, source="docs/design.md §11")
    goal_reward: float = number(1.0, 0.0, 1e6, source="docs/design.md §9.22")
    step_cost: float = number(0.02, 0.0, 1e6, source="docs/design.md §9.22")
    collision_penalty: float = number(3.0, 0.0, 1e6, source="docs/design.md §9.22")
    reference_speed: float = number(
        0.5, 0.0, 1.3, low_open=True, unit="m/s", source="docs/design.md §9.22"
    )
    trace_cutoff: float = number(
        1e-3, 0.0, 1.0, low_open=True, high_open=True, source="docs/design.md §9.23"
    )

    def __post_init__(self) -> None:
        validate_fields(self, "learning.")
        for name in ("alpha", "gamma", "lam", "epsilon"):
            low, high = getattr(self, f"{name}_low"), getattr(self, f"{name}_high")
            if low > high:
                raise ValueError(
                    f"learning.{name}_low must be <= learning.{name}_high ({high}), got {low}"
                )


@dataclass(frozen=True)
class CtrnnConfig:
    """The ranges of the ``ctrnn`` controller's evolved time constants and gains (Beer 1995;
    docs/design.md §9.31). A gene g maps onto ``low (high / low) ** ((clip(g, -1, 1) + 1) / 2)``:
    log-uniform over the range for the initial U[-1, 1] genes.

    Attributes:
        tau_low: shortest time constant, in control steps; at least 1, so the forward-Euler
            step of one control step never overshoots a unit's fixed point.
        tau_high: longest time constant, in control steps (100 steps = 20 s at the default
            0.2 s step, a quarter of the paper's 400-step lifetime).
        gain_low: smallest gain of a unit's sigmoid.
        gain_high: largest gain (Beer's networks use gains of about 1 to 5).
    """

    tau_low: float = number(1.0, 1.0, 1e4, unit="control steps", source="docs/design.md §9.31")
    tau_high: float = number(
        100.0, 1.0, 1e4, unit="control steps", source="docs/design.md §9.31"
    )
    gain_low: float = number(1.0, 0.0, 100.0, low_open=True, source="docs/design.md §9.31")
    gain_high: float = number(5.0, 0.0, 100.0, low_open=True, source="docs/design.md §9.31")

    def __post_init__(self) -> None:
        validate_fields(self, "evolution.ctrnn.")
        check_number("evolution.ctrnn.tau_high", self.tau_high, self.tau_low)
        check_number("evolution.ctrnn.gain_high", self.gain_high, self.gain_low)


#: Which agents share a spare list in EE (docs/design.md §9.34).
SPARE_LISTS = ("robot", "colony", "position")


@dataclass(frozen=True)
class MedeaConfig:
    """The rules of mEDEA (Bredeche and Montanier 2012) that the paper it comes from leaves
    open or that meet this world (docs/design.md §9.34). mEDEA runs one agent per robot
    (``population_size = n_robots``) whose slot is its whole life (``time_sharing_steps =
    lifetime_steps``).

    Attributes:
        broadcast_range: m, a robot receives the genome of every active robot whose IR port is
            this close to its own, in the same arena, at every control step (mEDEA broadcasts
            continuously; the default is the IR exchange's port-to-port range,
            ``survival.mate_distance``; no facing condition, a broadcast is omnidirectional).
        listen_lifetimes: lifetimes a robot that received no genome stays inactive, listening,
            before it restarts with a fresh random genome (mEDEA leaves it inactive until it
            hears one; a colony that fell silent would never close a generation).
        mutate: the genome picked from those received is mutated (the genetic operators'
            mutation; mEDEA's rule) before it runs.
    """

    broadcast_range: float = number(
        0.35, 0.0, 10.0, low_open=True, unit="m", source="docs/design.md §9.34"
    )
    listen_lifetimes: int = integer(1, 1, 1000, unit="lifetimes", source="docs/design.md §9.34")
    mutate: bool = boolean(True, source="Bredeche and Montanier 2012")

    def __post_init__(self) -> None:
        validate_fields(self, "evolution.medea.")


#: How the chance that a mating yields an offspring candidate depends on energy.
@dataclass(frozen=True)
class ReproductionConfig:
    """Variants of reproduction from the Cyber Rodent literature (docs/design.md §9.27).

    Attributes:
        energy_dependent: a mating yields an offspring candidate (the partner's genome and
            fitness, stored for the end of life) only with probability
            ``p = clip(E / energy_full, 0, 1)``, E the partner's energy at the mating occasion;
            the mating itself (and its count) happens regardless. Off (the paper): every
            mating yields a candidate.
        energy_full: the partner energy at and above which a mating always yields a candidate.
    """

    energy_dependent: bool = boolean(False, source="docs/design.md §9.27")
    energy_full: float = number(
        200.0, 0.0, ENERGY_LIMIT, low_open=True, source="docs/design.md §9.27"
    )

    def __post_init__(self) -> None:
        validate_fields(self, "reproduction.")

    def candidate_probability(self, partner_energy: float) -> float:
        """The chance that a mating with a partner of this energy yields a candidate."""
        if not self.energy_dependent:
            return 1.0
        return min(1.0, max(0.0, float(partner_energy) / self.energy_full))


@dataclass(frozen=True)
class EvolutionConfig:
    """The survival task and population of the evolution (paper Table 1, §3.3, docs/design.md §5).

    Attributes:
        lifetime_steps: control steps a virtual agent lives if it does not die (paper: 400).
        time_sharing_steps: control steps an agent runs before its robot switches to the next
            agent, unless a successful mating ends the slot earlier (paper: 100).
        population_size: virtual agents in the whole colony (paper: 100).
        n_robots: physical robots sharing the population (paper: 4, i.e. 25 agents each).
        initial_energy: energy of a newborn agent (paper: 100).
        max_energy: energy cap; the controller's energy input is ``energy / max_energy``
            (paper: 200).
        max_recharge_steps: longest recharge; the controller's recharge-step input is
            ``steps / max_recharge_steps`` (paper: 40).
        fitness_time_unit: the 100 in fitness = batteries / (time / 100) (paper §3.3), in
            control steps.
        ce_fitness_requires_survival: in the centralised GA an agent that died scores 0 even if
            it mated. The paper (§2) says a zero fitness "means that a virtual agent dies ... or
            ... is not able to perform any successful mating"; docs/design.md §5 only names the
            mating condition. ``True`` follows the paper.
        ee_close_quorum: EE only (our reading; the paper leaves it open, §4.1): the share of
            slots that must have passed generation g before g's statistics row closes and
            counts as completed. Reproduction is asynchronous, so a slot whose agents keep
            dying lags behind; with 1.0 one such slot holds back every row and the run's end.
            At 0.9 a row closes once 90 % of the slots have moved past it; agents of a closed
            generation that finish later (in lagging slots) are counted in
            ``StatisticsRecorder.late`` instead of a row.
        controller: the evolved controller (docs/design.md §9.28): ``"paper"``, the paper's
            one-layer controller (39 weights), or ``"mlp"``, one tanh hidden layer of
            ``hidden_units`` units with the paper's recharge part; or a controller a program
            registered (:func:`evolution.controllers.register_controller`).
        hidden_units: ``mlp`` and ``ctrnn``: the units of the hidden layer (the network).
        inputs: the controller's inputs, comma-separated, in column order: ``paper`` stands
            for the paper's twelve (§3.5), and any built-in or registered input may follow
            (``paper,steps_since_recharge``; docs/design.md §5 lists them). The genome has one
            weight per input and output, so the default keeps the paper's 39 genes.
        ctrnn: ``ctrnn`` only: the ranges of its time constants and gains.
        spare_list: EE: which agents share a spare list (the unused children that replace
            dead or unmated agents): ``robot``, the paper's (a robot's subpopulation),
            ``colony`` (one list for all), or ``position`` (the robots at the same position in
            their arenas, ``world.arenas``: the twin of one robot's subpopulation).
        medea: the ``medea`` scheme's rules.
        genetics: the genome and its operators (Table 2).
        learning: learning mode (off by default; docs/design.md §11).
        reproduction: reproduction variants (the paper's rule by default).

    The sizes are bounded so that a typo is refused before a run allocates or writes anything:
    at most :data:`MAX_POPULATION` agents, the robots that fit in the field
    (:data:`cyber_rodent.world.MAX_ROBOTS`), and step counts and energies within the survival
    world's own bounds (:data:`~cyber_rodent.survival.config.MAX_STEP_COUNT`,
    :data:`~cyber_rodent.survival.config.ENERGY_LIMIT`).
    """

    lifetime_steps: int = integer(
        400, 1, MAX_STEP_COUNT, unit="control steps", source="paper Table 1"
    )
    time_sharing_steps: int = integer(
        100, 1, MAX_STEP_COUNT, unit="control steps", source="paper Table 1"
    )
    population_size: int = integer(100, 1, MAX_POPULATION, unit="agents", source="paper Table 1")
    n_robots: int = integer(4, 1, MAX_ROBOTS, unit="robots", source="paper Table 1")
    initial_energy: float = number(
        100.0, 0.0, ENERGY_LIMIT, low_open=True, source="paper Table 1"
    )
    max_energy: float = number(200.0, 0.0, ENERGY_LIMIT, low_open=True, source="paper Table 1")
    max_recharge_steps: int = integer(
        40, 1, MAX_STEP_COUNT, unit="control steps", source="paper Table 1"
    )
    fitness_time_unit: float = number(
        100.0, 0.0, low_open=True, unit="control steps", source="paper §3.3"
    )
    ce_fitness_requires_survival: bool = boolean(True, source="docs/design.md §9.15")
    ee_close_quorum: float = number(
        0.9, 0.0, 1.0, low_open=True, unit="share of slots", source="docs/design.md §9.17"
    )
    controller: str = choice("paper", controller_names, source="paper §3.5")
    hidden_units: int = integer(8, 1, 64, unit="units", source="docs/design.md §9.28")
    inputs: str = names(PAPER, input_names_allowed, source="paper §3.5")
    ctrnn: CtrnnConfig = field(default_factory=CtrnnConfig)
    spare_list: str = choice("robot", SPARE_LISTS, source="paper §2")
    medea: MedeaConfig = field(default_factory=MedeaConfig)
    genetics: GeneticConfig = field(default_factory=GeneticConfig)
    learning: LearningConfig = field(default_factory=LearningConfig)
    reproduction: ReproductionConfig = field(default_factory=ReproductionConfig)

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.learning, LearningConfig):
            raise ValueError(f"learning must be a LearningConfig, got {type(self.learning)!r}")
        if not isinstance(self.ctrnn, CtrnnConfig):
            raise ValueError(f"ctrnn must be a CtrnnConfig, got {type(self.ctrnn)!r}")
        if not isinstance(self.medea, MedeaConfig):
            raise ValueError(f"medea must be a MedeaConfig, got {type(self.medea)!r}")
        select_inputs(self.inputs)  # a name given twice
        if not isinstance(self.reproduction, ReproductionConfig):
            raise ValueError(
                f"reproduction must be a ReproductionConfig, got {type(self.reproduction)!r}"
            )
        check_integer("time_sharing_steps", self.time_sharing_steps, 1, self.lifetime_steps)
        check_integer("population_size", self.population_size, self.n_robots)
        if self.population_size % self.n_robots != 0:
            raise ValueError(
                f"population_size ({self.population_size}) must be divisible by n_robots "
                f"({self.n_robots}): every robot carries an equal virtual subpopulation"
            )
        check_number("initial_energy", self.initial_energy, 0.0, self.max_energy, low_open=True)
        if not isinstance(self.genetics, GeneticConfig):
            raise ValueError(f"genetics must be a GeneticConfig, got {type(self.genetics)!r}")
        check_integer(
            "genetics.tournament_size", self.genetics.tournament_size, 1, self.population_size
        )

    @property
    def genome_length(self) -> int:
        """Genes of one genome: the controller's (39 for the paper's), plus the learning genes
        in learning mode."""
        learning = N_LEARNING_GENES if self.learning.enabled else 0
        return resolve(self).length + learning

    @property
    def subpopulation_size(self) -> int:
        """Virtual agents per robot (paper: 100 / 4 = 25)."""
        return self.population_size // self.n_robots


def default_config() -> EvolutionConfig:
    """The paper's configuration (Tables 1 and 2)."""
    return EvolutionConfig()
