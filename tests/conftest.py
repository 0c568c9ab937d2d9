"""Shared fixtures. Rendering is off-screen (EGL) and needs no display."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")
