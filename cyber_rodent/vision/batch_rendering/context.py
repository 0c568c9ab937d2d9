"""The batch renderer's OpenGL context: an off-screen context with its own framebuffer.

The context is MuJoCo's (:func:`~cyber_rodent.vision.rendering.gl_context`: EGL, OSMesa or
GLFW after ``MUJOCO_GL``), so it coexists with MuJoCo's renderers in one process; each
renderer makes its own context current before drawing. Everything is drawn into one
off-screen framebuffer (RGBA8 colour, 32-bit float depth) that holds every robot's strip;
freeing the context frees every GL object made in it.
"""

from __future__ import annotations

from typing import Any

from OpenGL import GL

from cyber_rodent.vision.rendering import gl_context


class OffscreenContext:
    """An off-screen GL context, current after construction, with a complete framebuffer of
    ``width × height`` pixels bound for drawing and reading.

    Raises:
        RuntimeError: if the framebuffer is incomplete.
    """

    def __init__(self, width: int, height: int):
        self.width, self.height = width, height
        self._gl: Any = gl_context(width, height)
        self._closed = False
        try:
            self._gl.make_current()
            self._framebuffer()
        except Exception:
            self.free()
            raise

    def _framebuffer(self) -> None:
        self._fbo = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._fbo)
        self._renderbuffers = GL.glGenRenderbuffers(2)
        for rb, fmt, attachment in zip(
            self._renderbuffers,
            (GL.GL_RGBA8, GL.GL_DEPTH_COMPONENT32F),
            (GL.GL_COLOR_ATTACHMENT0, GL.GL_DEPTH_ATTACHMENT),
            strict=True,
        ):
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, fmt, self.width, self.height)
            GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, attachment, GL.GL_RENDERBUFFER, rb)
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"off-screen framebuffer incomplete (status 0x{status:x})")
        GL.glDrawBuffer(GL.GL_COLOR_ATTACHMENT0)
        GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)

    def make_current(self) -> None:
        """Make this context current in the calling thread (another renderer may have drawn)."""
        self._gl.make_current()

    def free(self) -> None:
        """Free the context and every GL object in it (idempotent)."""
        if not self._closed:
            self._closed = True
            self._gl.free()
