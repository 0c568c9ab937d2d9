"""cyber_rodent: the Cyber Rodent robot and its survival world in MuJoCo.

Rendering is off-screen. Headless EGL is the default GL backend unless the user chose one
(``MUJOCO_GL``), and it must be chosen before mujoco or dm_control create a context.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.2.0"
