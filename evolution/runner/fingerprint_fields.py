"""The config fields every run fingerprint has held since checkpoints began: frozen, never edited.

A run's fingerprint (:func:`evolution.runner.checkpoints.run_fingerprint`) hashes its config.
So that a config field added later does not change the fingerprints of runs that leave it at
its default (and older checkpoints keep resuming), the fingerprint leaves out every field
that is neither listed here nor in ``LATER_FIELDS`` (the fields added before this list existed,
with their own historical rule) while it holds its default. A new field therefore needs no
entry anywhere: give it a default that reproduces the behaviour before it.

Generated once from the config of the commit before this file (``dataclasses.asdict`` of the
default ``RunConfig``, its leaves as dotted paths, ``LATER_FIELDS`` and ``profile`` left out).
"""

from __future__ import annotations

FINGERPRINT_FIELDS: frozenset[str] = frozenset((
    "method",
    "evolution.lifetime_steps",
    "evolution.time_sharing_steps",
    "evolution.population_size",
    "evolution.n_robots",
    "evolution.initial_energy",
    "evolution.max_energy",
    "evolution.max_recharge_steps",
    "evolution.fitness_time_unit",
    "evolution.ce_fitness_requires_survival",
    "evolution.ee_close_quorum",
    "evolution.genetics.initial_weight_low",
    "evolution.genetics.initial_weight_high",
    "evolution.genetics.crossover_probability",
    "evolution.genetics.mutation_probability",
    "evolution.genetics.mutation_low",
    "evolution.genetics.mutation_high",
    "evolution.genetics.tournament_size",
    "survival.initial_energy",
    "survival.max_energy",
    "survival.energy_decay",
    "survival.recharge_rate",
    "survival.decay_while_recharging",
    "survival.max_recharge_steps",
    "survival.control_dt",
    "survival.reflex_min_steps",
    "survival.reflex_max_steps",
    "survival.reflex_wheel_speed",
    "survival.dock_bearing_tolerance_deg",
    "survival.mate_angle_deg",
    "survival.mate_distance",
    "survival.mate_consecutive_steps",
    "world.n_robots",
    "world.n_packs",
    "world.timestep",
    "camera.n_views",
    "camera.view_width",
    "camera.height",
    "camera.elevation_min_deg",
    "camera.elevation_max_deg",
    "camera.max_range",
    "camera.min_blob_area",
    "camera.led.hue_low",
    "camera.led.hue_high",
    "camera.led.sat_min",
    "camera.led.val_min",
    "camera.face.hue_low",
    "camera.face.hue_high",
    "camera.face.sat_min",
    "camera.face.val_min",
    "camera.battery.hue_low",
    "camera.battery.hue_high",
    "camera.battery.sat_min",
    "camera.battery.val_min",
    "camera.noise.bearing_std_deg",
    "camera.noise.distance_rel_std",
    "camera.noise.dropout",
    "camera.near_clip",
    "vision",
))  # fmt: skip

__all__ = ["FINGERPRINT_FIELDS"]
