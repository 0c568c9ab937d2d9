"""cyber_rodent: the Cyber Rodent robot and its survival world in MuJoCo.

Rendering is off-screen. Headless EGL is the default GL backend unless the user chose one
(``MUJOCO_GL``), and it must be chosen before mujoco or dm_control create a context.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.2.0"

# Gymnasium ids (cyber_rodent/gym_env.py) of the built-in tasks of cyber_rodent/tasks/spec.py,
# by their titles. The task registry (tasks.spec.task_names) is where every interface finds a
# task, a task a program registers too; these titles are the one list beside it, since reading
# the registry imports mujoco and `import cyber_rodent` must not (tests/test_gym_env.py), and
# tests/test_task_specs.py checks that they are the registry's built-in tasks. Entry-point
# strings: registering imports neither the environment module, nor the registry, nor mujoco;
# gymnasium.make imports them. A registered task is an environment by name at once
# (CyberRodentEnv(name)); gymnasium.register gives it an id.
from gymnasium.envs.registration import register as _register  # noqa: E402

for _task in ("Forage", "Mate", "Search", "Survival"):
    _register(
        id=f"CyberRodent/{_task}-v0",
        entry_point="cyber_rodent.gym_env:CyberRodentEnv",
        kwargs={"task": _task.lower()},
    )
