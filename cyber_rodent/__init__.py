"""cyber_rodent: the Cyber Rodent robot and its survival world in MuJoCo.

Rendering is off-screen. Headless EGL is the default GL backend unless the user chose one
(``MUJOCO_GL``), and it must be chosen before mujoco or dm_control create a context.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.2.0"

# Gymnasium ids (cyber_rodent/gym_env.py) of the built-in tasks of cyber_rodent/tasks/spec.py,
# by their titles (tests/test_task_specs.py checks that they match). Entry-point strings:
# registering imports neither the environment module, nor the registry, nor mujoco;
# gymnasium.make imports them.
from gymnasium.envs.registration import register as _register  # noqa: E402

for _task in ("Forage", "Mate", "Search", "Survival"):
    _register(
        id=f"CyberRodent/{_task}-v0",
        entry_point="cyber_rodent.gym_env:CyberRodentEnv",
        kwargs={"task": _task.lower()},
    )
