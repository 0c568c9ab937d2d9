"""System identification: fit the simulator to a real robot's run logs, and measure the gap.

* :mod:`~cyber_rodent.sysid.log`: the run log (columns :data:`cyber_rodent.robot_step.
  LOG_COLUMNS`), read and checked row by row;
* :mod:`~cyber_rodent.sysid.replay`: a log's wheel commands replayed in MuJoCo, segment by
  segment, with a candidate drive;
* :mod:`~cyber_rodent.sysid.fit`: the drive (per-robot wheel gains, motor lag, friction) by
  least squares over the replay, the IR and camera noise by maximum likelihood at the logged
  geometry, each with a bootstrap over log segments, as a
  :class:`~cyber_rodent.profiles.FittedProfile`;
* :mod:`~cyber_rodent.sysid.gap`: per-sensor errors and pose divergence over a horizon;
* :mod:`~cyber_rodent.sysid.synthetic`: logs of a simulated "true robot" with hidden
  parameters and realistic faults, to validate all of the above without a robot.
"""
