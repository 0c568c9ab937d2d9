"""One compiled call for the sensing and deciding half of every control step.

Before the physics of a step, the runner asks the geometric vision for each robot's nearest
LED, face and pack, maps the sensors to inputs, evaluates the neural controllers and the
behaviours' greedy policies, and turns the chosen commands into wheel speeds. Each of those is
a compiled kernel already (:mod:`cyber_rodent.vision.geometric_kernel`,
:mod:`evolution.runner.perception_kernel`, :mod:`evolution.controller_kernel`,
:mod:`behaviours.greedy_kernel`); called one by one from Python, the wrappers, argument
unboxing and the numpy glue between them cost about as much as the kernels. Here
:func:`sense_decide_act` calls the same kernels, in the same order on the same buffers, from
compiled code: one dispatch per step.

The runner uses it only on its default path (geometric vision without noise, no sensor noise,
learned behaviours); everything else takes the step-by-step path, which stays the reference:
``tests/test_evolution_runner.py`` checks that both give bit-identical runs.
"""

from __future__ import annotations

from behaviours import greedy_kernel
from cyber_rodent.compiled import AVAILABLE
from cyber_rodent.compiled import jit as _jit
from cyber_rodent.vision import geometric_kernel
from evolution import controller_kernel
from evolution.runner import perception_kernel

__all__ = ["AVAILABLE", "sense_decide_act"]


@_jit
def sense_decide_act(
    # geometric vision: MuJoCo's pose arrays and the provider's kernel buffers
    site_xpos, site_xmat, geom_xpos, geom_xmat, cam_site, target_geom, maddr, daddr, cam, rot,
    centre, gmat, led_on, own, plate, half_width, half_height, rim, half_depth, min_area,
    s_target, s_lat, s_dz, view_centres, scalars, local, t_bearing, t_distance, width_px,
    height_px, half_angle, full_area, candidate, diff, lateral, rays, sample_ok, class_cols,
    class_count, sample_start, sample_end, inv_samples, s_geom, exclude, groups, geom_id, order,
    # perception
    bearing, distance, visible, raw, range_max, ranges, prox_columns, prox_max, max_distance,
    led_class, face_class, battery_class, proximity, norm_bearing, norm_distance, in_mate,
    in_forage, in_search, mate_available, forage_available,
    # controllers
    weights, recharge_start, selection_start, energy, steps_recharged, max_energy,
    max_recharge_steps, c_inputs, activations, behaviour, led, proceed,
    # behaviours
    scale, offsets, count, strides, base, lookup, table, commands,
    # runner
    docked, command_speeds, mate_behaviour, wheels, led_out, mate_out,
):  # fmt: skip
    """Vision, inputs, controllers, behaviours and wheel speeds for every robot.

    Returns:
        ``greedy_kernel.OK``, or its error code (then ``wheels``, ``led_out`` and ``mate_out``
        are not written; the caller's step-by-step path raises the error that names it).
    """
    geometric_kernel.gather(
        site_xpos, site_xmat, geom_xpos, geom_xmat, cam_site, target_geom, cam, rot, centre, gmat
    )
    geometric_kernel.nearest(
        maddr, daddr, cam, rot, centre, gmat, led_on, own, plate, half_width, half_height, rim,
        half_depth, min_area, s_target, s_lat, s_dz, view_centres, scalars, local, t_bearing,
        t_distance, width_px, height_px, half_angle, full_area, candidate, diff, lateral, rays,
        sample_ok, class_cols, class_count, sample_start, sample_end, inv_samples, s_geom,
        exclude, groups, geom_id, order, bearing, distance, visible,
    )  # fmt: skip
    perception_kernel.map_inputs(
        raw, range_max, ranges, prox_columns, prox_max, bearing, distance, visible, max_distance,
        led_class, face_class, battery_class, proximity, norm_bearing, norm_distance, in_mate,
        in_forage, in_search, mate_available, forage_available,
    )  # fmt: skip
    controller_kernel.decide(
        weights, recharge_start, selection_start, energy, proximity,
        norm_distance[:, face_class], norm_distance[:, led_class],
        norm_distance[:, battery_class], led_on, mate_available, forage_available,
        steps_recharged, max_energy, max_recharge_steps, c_inputs, activations, behaviour, led,
        proceed,
    )  # fmt: skip
    status = greedy_kernel.act(
        behaviour, in_mate, in_forage, in_search, scale, offsets, count, strides, base, lookup,
        table, commands,
    )  # fmt: skip
    if status != greedy_kernel.OK:
        return status
    for i in range(behaviour.shape[0]):
        # A robot that keeps recharging runs no behaviour: its LED is dark.
        led_out[i] = led[i] and not (docked[i] and proceed[i])
        wheels[i, 0] = command_speeds[commands[i], 0]
        wheels[i, 1] = command_speeds[commands[i], 1]
        mate_out[i] = behaviour[i] == mate_behaviour
    return status
