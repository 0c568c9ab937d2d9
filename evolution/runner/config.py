"""The configuration of one evolution run: method, evolution rules, world, survival and vision.

The energy numbers of the paper (initial 100, maximum 200, maximum recharge 40 steps) appear in
two configs: :class:`evolution.config.EvolutionConfig` (newborn agents, the controller's input
normalisation) and :class:`cyber_rodent.survival.SurvivalConfig` (the world's mechanics). A run
must use one set of numbers, so :class:`RunConfig` derives the survival config from the
evolution config when none is given and otherwise insists that the two agree; likewise the
world's robot count is the evolution config's ``n_robots``. A user changes a number in one
place, and a contradictory combination is a clear ``ValueError`` instead of a silently
inconsistent run. The camera's range follows the world's field in the same way: by default it
is the field's diagonal (``cyber_rodent.vision.follow_field``).
"""

from __future__ import annotations

import copy
import dataclasses
import typing
from dataclasses import dataclass, field
from typing import Any

from cyber_rodent.profiles import HardwareProfile
from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.validation import choice, validate_fields
from cyber_rodent.vision import PROVIDER_NAMES, CameraConfig, camera_for_field, follow_field
from cyber_rodent.world import WorldConfig
from evolution.config import EvolutionConfig, LearningConfig, ReproductionConfig
from evolution.schemes import scheme, scheme_names

#: Fields that EvolutionConfig and SurvivalConfig share; they must be equal in a run.
SHARED_ENERGY_FIELDS = ("initial_energy", "max_energy", "max_recharge_steps")

#: Default of the fields that follow ``evolution`` (``survival``, ``world``) or the world
#: (``camera``): "not given", so ``__post_init__`` derives them. After construction they always
#: hold a config.
_FROM_EVOLUTION: Any = None
_FROM_WORLD: Any = None


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines a run except its seed and its behaviour policies.

    Attributes:
        method: the evolution scheme (:mod:`evolution.schemes`): ``"ee"`` (embodied
            evolution, paper §2), ``"ce"`` (centralised GA, §4.1), ``"medea"`` (mEDEA,
            Bredeche and Montanier 2012), or one a program registered.
        evolution: the paper's evolution numbers (Tables 1 and 2).
        survival: the world's energy, docking, recharge and mating rules; derived from
            ``evolution`` if not given (the paper's defaults for everything else).
        world: the field (robots, packs, physics timestep); ``n_robots`` from ``evolution``
            and 5 packs if not given (the paper's simulation).
        camera: the omnidirectional camera; if not given, :class:`CameraConfig` with the
            range of ``world``'s field (its diagonal: 3.25 m in the paper's field).
        vision: the vision provider, ``"geometric"`` (fast, the default for evolution runs) or
            ``"rendered"`` (the real off-screen camera; much slower).
        profile: optional hardware-like profile (:mod:`cyber_rodent.profiles`). The runner
            applies its range-sensor noise and actuator differences; its field and vision
            parts must already be in ``world`` and ``camera`` (build such a config with
            :func:`evolution.lab.transfer.hardware_run_config`), which is checked here. None (the
            default): the plain simulation.

    Raises:
        ValueError: an unknown method or vision provider, a sub-config of the wrong type, or
            sub-configs that disagree (energy numbers, robot count).
    """

    method: str = choice("ee", scheme_names, source="paper §4.1")
    evolution: EvolutionConfig = field(default_factory=EvolutionConfig)
    survival: SurvivalConfig = _FROM_EVOLUTION
    world: WorldConfig = _FROM_EVOLUTION
    camera: CameraConfig = _FROM_WORLD
    vision: str = choice("geometric", PROVIDER_NAMES, source="docs/design.md §6")
    profile: HardwareProfile | None = None

    def __post_init__(self) -> None:
        validate_fields(self)
        if not isinstance(self.evolution, EvolutionConfig):
            raise ValueError(f"evolution must be an EvolutionConfig, got {type(self.evolution)!r}")
        evo = self.evolution
        check = scheme(self.method).check
        if check is not None:
            check(evo)
        if self.survival is _FROM_EVOLUTION:
            shared = {name: getattr(evo, name) for name in SHARED_ENERGY_FIELDS}
            object.__setattr__(self, "survival", SurvivalConfig(**shared))
        elif not isinstance(self.survival, SurvivalConfig):
            raise ValueError(f"survival must be a SurvivalConfig, got {type(self.survival)!r}")
        for name in SHARED_ENERGY_FIELDS:
            a, b = getattr(evo, name), getattr(self.survival, name)
            if a != b:
                raise ValueError(
                    f"survival.{name} ({b!r}) must equal evolution.{name} ({a!r}): the world "
                    "applies the energy rules the evolution assumes"
                )
        if self.world is _FROM_EVOLUTION:
            object.__setattr__(self, "world", WorldConfig(n_robots=evo.n_robots))
        elif not isinstance(self.world, WorldConfig):
            raise ValueError(f"world must be a WorldConfig, got {type(self.world)!r}")
        if self.world.n_robots != evo.n_robots:
            raise ValueError(
                f"world.n_robots ({self.world.n_robots}) must equal evolution.n_robots "
                f"({evo.n_robots}): every physical robot carries one subpopulation"
            )
        if self.camera is _FROM_WORLD:
            object.__setattr__(self, "camera", camera_for_field(self.world.field_size))
        elif not isinstance(self.camera, CameraConfig):
            raise ValueError(f"camera must be a CameraConfig, got {type(self.camera)!r}")
        if self.profile is not None:
            self._check_profile(self.profile)

    def _check_profile(self, profile: object) -> None:
        """The profile's field and vision parts must be the world's and the camera's."""
        if not isinstance(profile, HardwareProfile):
            raise ValueError(f"profile must be a HardwareProfile or None, got {type(profile)!r}")
        layout = profile.field
        if layout.enabled and (self.world.n_robots, self.world.n_packs) != (
            layout.n_robots,
            layout.n_packs,
        ):
            raise ValueError(
                f"profile.field ({layout.n_robots} robots, {layout.n_packs} packs) must match "
                f"world ({self.world.n_robots} robots, {self.world.n_packs} packs); build the "
                "config with evolution.lab.transfer.hardware_run_config"
            )
        if profile.vision.enabled and self.camera.noise != profile.vision.noise():
            raise ValueError(
                f"profile.vision ({profile.vision.noise()}) must equal camera.noise "
                f"({self.camera.noise}); build the config with "
                "evolution.lab.transfer.hardware_run_config"
            )

    def replace(self, **changes: Any) -> RunConfig:
        """A copy with some fields changed, kept consistent.

        When ``evolution`` changes and ``survival`` or ``world`` are not passed, their shared
        fields (energy numbers, robot count) follow the new evolution config and every other
        field is kept, so ``config.replace(evolution=...)`` never produces a contradiction.
        When the world's field changes and ``camera`` is not passed, a camera range that was
        the old field's default becomes the new field's (``follow_field``); a range set by
        hand is kept.
        """
        evo = changes.get("evolution")
        if isinstance(evo, EvolutionConfig):
            if "survival" not in changes:
                shared = {name: getattr(evo, name) for name in SHARED_ENERGY_FIELDS}
                changes["survival"] = dataclasses.replace(self.survival, **shared)
            if "world" not in changes:
                changes["world"] = dataclasses.replace(self.world, n_robots=evo.n_robots)
        world = changes.get("world")
        if isinstance(world, WorldConfig) and "camera" not in changes:
            old, new = self.world.field_size, world.field_size
            changes["camera"] = follow_field(self.camera, old, new)
        return dataclasses.replace(self, **changes)


#: Config fields added after checkpoints were first written and before new fields were left out
#: automatically (their path in the config, then the default that reproduces the behaviour
#: before them): at that default they are left out of the fingerprint, so older checkpoints
#: still resume. Frozen history: a field added since needs no entry (:func:`_drop_new_defaults`),
#: unless its default changes what a run does (a model fix, such as ``camera.trace_below`` and
#: ``world.contacts``): such a field enters here with the value that reproduces the
#: runs before it, so they keep their fingerprints and replay with that value set. A record
#: written before a field existed is read with the value listed here
#: (:func:`run_config_from_record`), so that it means what it ran.
LATER_FIELDS: tuple[tuple[Any, ...], ...] = (
    ("evolution", "controller", "paper"),
    ("evolution", "hidden_units", 8),
    ("evolution", "genetics", "meta_mutation_width", 0.1),
    ("evolution", "learning", dataclasses.asdict(LearningConfig())),
    ("evolution", "reproduction", dataclasses.asdict(ReproductionConfig())),
    ("survival", "capture_rule", "docking"),
    ("survival", "mate_reflex", False),
    ("survival", "mate_min_energy", 0.0),
    ("world", "pack_gap", 0.3),
    ("world", "pack_wall_clearance", 0.2),
    ("world", "pack_reactivation_steps", 0),
    ("world", "field_size", 2.3),
    ("camera", "trace_below", (0, 0, 0)),
    ("world", "contacts", "published"),
)


def run_config_from_record(data: object) -> RunConfig:
    """Rebuild a :class:`~evolution.runner.RunConfig` from its ``dataclasses.asdict`` form.

    Raises:
        ValueError: ``data`` is not such a form, or a value its field refuses.
    """
    if not isinstance(data, dict):
        raise ValueError(f"run.json: config must be a JSON object, got {type(data).__name__}")
    data = _with_earlier_fields(data)
    try:
        config: RunConfig = _dataclass_from_dict(RunConfig, data)
    except TypeError as err:
        raise ValueError(f"run.json: malformed config ({err})") from None
    return config


def _with_earlier_fields(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a record's config) with every :data:`LATER_FIELDS` field it lacks set to the
    value that reproduces the runs written before the field existed (a copy; sections the
    record lacks stay absent)."""
    data = copy.deepcopy(data)
    for *path, name, value in LATER_FIELDS:
        section: Any = data
        for part in path:
            section = section.get(part) if isinstance(section, dict) else None
        if isinstance(section, dict) and name not in section:
            section[name] = copy.deepcopy(value)
    return data


def _dataclass_from_dict(cls: type, values: dict[str, Any]) -> Any:
    """Inverse of ``dataclasses.asdict`` for frozen config trees (nested dataclasses, tuples)."""
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(values) - names
    if unknown:
        raise ValueError(f"run.json: unknown {cls.__name__} field(s) {sorted(unknown)}")
    kwargs = {}
    for name, value in values.items():
        nested = _dataclass_in(hints[name])
        if isinstance(value, dict) and nested is not None:
            value = _dataclass_from_dict(nested, value)
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return cls(**kwargs)


def _dataclass_in(hint: Any) -> type | None:
    """The dataclass in a field's type hint (``X`` or ``X | None``), if any."""
    for candidate in (hint, *typing.get_args(hint)):
        if isinstance(candidate, type) and dataclasses.is_dataclass(candidate):
            return candidate
    return None
