"""The batch renderer's per-frame draw: one upload, two passes, one read-back.

1. One buffer upload (:class:`FrameData`): the geoms' poses and colours (the LED's colour
   changes at run time) and the light directions, plus per view a clip matrix, the headlight
   direction, its tile, and the draw commands.
2. A transform-feedback pass (one draw, no rasterisation) moves every vertex to the world frame
   and lights it with the view-independent terms, once per frame rather than once per view
   (per-view vertex work was the largest cost of a one-pass design).
3. One ``glMultiDrawElementsIndirect`` draws all views; a command's ``baseInstance`` is its
   view, which the vertex shader reads (``gl_BaseInstanceARB``) to pick the view's camera,
   headlight and tile.
4. One ``glReadPixels`` (RGBA, llvmpipe's fast path) and an OpenCV RGBA → RGB conversion into
   the caller's array.

Row order: each view's projection is flipped vertically, so OpenGL's bottom-up rows come back
from ``glReadPixels`` top row first and the output needs no flip (the flip mirrors triangles'
winding, hence ``glFrontFace(GL_CW)``). The per-frame GL calls go through plain ctypes entry
points (:class:`RawGL`).
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
from OpenGL import GL
from OpenGL.platform import PLATFORM

from cyber_rodent.vision.batch_rendering.meshes import SceneGeometry
from cyber_rodent.vision.batch_rendering.shaders import (
    FRAGMENT_SHADER,
    GEOM_VEC4,
    TF_VEC4,
    TRANSFORM_FEEDBACK,
    VIEW_SHADER,
    link_program,
)

#: Vec4s per view in the per-frame buffer: clip matrix (4 columns), direction to the headlight,
#: tile transform.
VIEW_VEC4 = 6
#: uint32s per draw command (``DrawElementsIndirectCommand``).
COMMAND_UINTS = 5


def _align(n_bytes: int, alignment: int = 256) -> int:
    return -(-n_bytes // alignment) * alignment


class FrameData:
    """The per-frame upload buffer: one byte array and numpy views of its three sections.

    ``[lights | geoms]`` (shader storage block 0), ``[views]`` (block 1) and ``[draw
    commands]`` (the indirect buffer), each section aligned to 256 bytes (every GL
    implementation's largest offset alignment). The tiles and the commands' instance counts
    are written here once; everything else every frame.

    Args:
        n_lights: directional model lights.
        n_geoms: geoms of the model (all have a slot; only drawn ones are read).
        n_robots, n_views: robots, and views per robot.
        n_drawn: drawn geoms (at most one command per view and drawn geom).

    Attributes:
        light_dir: (n_lights, 3) unit vectors towards the lights.
        geom_pos, geom_mat, geom_rgba: (ngeom, 3), (ngeom, 3, 3), (ngeom, 4) every geom's pose
            and colour.
        clip_t, head: (n_robots, n_views, 4, 4), (n_robots, n_views, 3) each view's clip
            matrix from the world (transposed: GLSL's column-major order) and unit vector
            towards its headlight.
        commands: (n_robots * n_views * n_drawn, 5) draw commands.
        views_offset, commands_offset: byte offsets of the second and third sections.
    """

    def __init__(self, n_lights: int, n_geoms: int, n_robots: int, n_views: int, n_drawn: int):
        n, n_k = n_robots, n_views
        n_light_slots = max(n_lights, 1)
        geoms_bytes = 16 * (n_light_slots + GEOM_VEC4 * n_geoms)
        views_bytes = 16 * VIEW_VEC4 * n * n_k
        commands_bytes = 4 * COMMAND_UINTS * n * n_k * n_drawn
        self.views_offset = _align(geoms_bytes)
        self.commands_offset = self.views_offset + _align(views_bytes)
        self.bytes = np.zeros(self.commands_offset + commands_bytes, dtype=np.uint8)
        f32 = self.bytes[: self.commands_offset].view(np.float32)
        self.light_dir = f32[: 4 * n_lights].reshape(-1, 4)[:, :3]
        geoms = f32[4 * n_light_slots : geoms_bytes // 4].reshape(n_geoms, GEOM_VEC4, 4)
        self.geom_pos = geoms[:, 0, :3]
        self.geom_mat = geoms[:, 1:4, :3]
        self.geom_rgba = geoms[:, 4, :]
        views = f32[self.views_offset // 4 : (self.views_offset + views_bytes) // 4]
        views = views.reshape(n, n_k, VIEW_VEC4, 4)
        self.clip_t = views[:, :, :4, :]
        self.head = views[:, :, 4, :3]
        # Tile of robot i, view k: columns k*w.., rows i*h.. from the framebuffer's bottom.
        views[:, :, 5, 0] = -1.0 + (2.0 * np.arange(n_k) + 1.0) / n_k
        views[:, :, 5, 1] = (-1.0 + (2.0 * np.arange(n) + 1.0) / n)[:, None]
        views[:, :, 5, 2] = 1.0 / n_k
        views[:, :, 5, 3] = 1.0 / n
        commands = self.bytes[self.commands_offset :].view(np.uint32)
        self.commands = commands.reshape(-1, COMMAND_UINTS)
        self.commands[:, 1] = 1  # instance count


class RawGL:
    """Plain ctypes entry points of the GL calls made every frame.

    PyOpenGL's wrappers (argument conversion, a ``glGetError`` after every call) cost several
    microseconds a call, a sizeable part of a frame; these cost well under one.

    Raises:
        RuntimeError: if the GL library lacks one of them.
    """

    _SIGNATURES: dict[str, tuple[Any, ...]] = {
        "glBufferSubData": (ctypes.c_uint, ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_void_p),
        "glEnable": (ctypes.c_uint,),
        "glDisable": (ctypes.c_uint,),
        "glUseProgram": (ctypes.c_uint,),
        "glBindVertexArray": (ctypes.c_uint,),
        "glBeginTransformFeedback": (ctypes.c_uint,),
        "glEndTransformFeedback": (),
        "glDrawArrays": (ctypes.c_uint, ctypes.c_int, ctypes.c_int),
        "glClear": (ctypes.c_uint,),
        "glMultiDrawElementsIndirect": (
            ctypes.c_uint,
            ctypes.c_uint,
            ctypes.c_void_p,
            ctypes.c_int,
            ctypes.c_int,
        ),
        "glReadPixels": (
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_uint,
            ctypes.c_uint,
            ctypes.c_void_p,
        ),
    }

    BufferSubData: Callable[[int, int, int, int], None]
    Enable: Callable[[int], None]
    Disable: Callable[[int], None]
    UseProgram: Callable[[int], None]
    BindVertexArray: Callable[[int], None]
    BeginTransformFeedback: Callable[[int], None]
    EndTransformFeedback: Callable[[], None]
    DrawArrays: Callable[[int, int, int], None]
    Clear: Callable[[int], None]
    MultiDrawElementsIndirect: Callable[[int, int, int, int, int], None]
    ReadPixels: Callable[[int, int, int, int, int, int, int], None]

    def __init__(self) -> None:
        for name, args in self._SIGNATURES.items():
            prototype = ctypes.CFUNCTYPE(None, *args)
            try:
                fn = prototype((name, PLATFORM.GL))
            except AttributeError:
                address = PLATFORM.getExtensionProcedure(name.encode())
                if not address:
                    raise RuntimeError(f"OpenGL has no {name}") from None
                fn = prototype(address)
            setattr(self, name[2:], fn)


def _attributes(buffer: int, layout: list[tuple[int, int]], stride: int) -> None:
    """Float vertex attributes ``(size, byte offset)`` at locations 0, 1, … of ``buffer``."""
    GL.glBindBuffer(GL.GL_ARRAY_BUFFER, buffer)
    for location, (size, offset) in enumerate(layout):
        GL.glEnableVertexAttribArray(location)
        GL.glVertexAttribPointer(
            location, size, GL.GL_FLOAT, GL.GL_FALSE, stride, ctypes.c_void_p(offset)
        )


class DrawPipeline:
    """The GL programs, buffers and state of the two passes, made in the current context.

    Args:
        geometry: the static meshes (uploaded once).
        transform_source: the transform shader with the model's lights
            (:func:`~cyber_rodent.vision.batch_rendering.shaders.transform_source`).
        frame: the per-frame upload buffer (its size fixes the GL buffer's).
        width, height: the framebuffer's size.
    """

    def __init__(
        self,
        geometry: SceneGeometry,
        transform_source: str,
        frame: FrameData,
        width: int,
        height: int,
    ):
        self.frame = frame
        self.width, self.height = width, height
        self._n_vertices = len(geometry.vertices)
        self._transform = link_program(transform_source, feedback=TRANSFORM_FEEDBACK)
        self._draw = link_program(VIEW_SHADER, FRAGMENT_SHADER)
        self._upload(geometry)
        self._fixed_state()
        self._rgba = np.empty((height, width, 4), dtype=np.uint8)
        self._rgba_ptr = self._rgba.ctypes.data
        self._frame_ptr = frame.bytes.ctypes.data
        self._raw = RawGL()

    def _upload(self, geo: SceneGeometry) -> None:
        """Buffers (static mesh, index, per-frame data, transformed vertices) and the two
        passes' vertex arrays."""
        frame = self.frame
        self._buffers = GL.glGenBuffers(4)
        mesh, index, data, moved = (int(b) for b in self._buffers)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, mesh)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, geo.vertices.nbytes, geo.vertices, GL.GL_STATIC_DRAW)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, moved)
        GL.glBufferData(
            GL.GL_ARRAY_BUFFER, 16 * TF_VEC4 * self._n_vertices, None, GL.GL_DYNAMIC_COPY
        )
        GL.glBindBufferBase(GL.GL_TRANSFORM_FEEDBACK_BUFFER, 0, moved)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, data)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, frame.bytes.nbytes, None, GL.GL_STREAM_DRAW)
        GL.glBindBufferRange(GL.GL_SHADER_STORAGE_BUFFER, 0, data, 0, frame.views_offset)
        GL.glBindBufferRange(
            GL.GL_SHADER_STORAGE_BUFFER,
            1,
            data,
            frame.views_offset,
            frame.commands_offset - frame.views_offset,
        )
        GL.glBindBuffer(GL.GL_DRAW_INDIRECT_BUFFER, data)
        self._vaos = [int(v) for v in GL.glGenVertexArrays(2)]
        GL.glBindVertexArray(self._vaos[0])
        _attributes(mesh, [(4, 0), (3, 16)], geo.vertices.strides[0])
        GL.glBindVertexArray(self._vaos[1])
        _attributes(moved, [(4, 16 * a) for a in range(TF_VEC4)], 16 * TF_VEC4)
        GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, index)
        GL.glBufferData(
            GL.GL_ELEMENT_ARRAY_BUFFER, geo.indices.nbytes, geo.indices, GL.GL_STATIC_DRAW
        )
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)

    def _fixed_state(self) -> None:
        GL.glViewport(0, 0, self.width, self.height)
        for plane in range(4):
            GL.glEnable(GL.GL_CLIP_DISTANCE0 + plane)
        GL.glDisable(GL.GL_DITHER)
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_MULTISAMPLE)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glFrontFace(GL.GL_CW)  # the flipped projection mirrors the winding
        GL.glClearColor(0.0, 0.0, 0.0, 1.0)
        GL.glClearDepth(1.0)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)

    def draw(self, n_commands: int, pixels: np.ndarray) -> None:
        """Upload the frame with its first ``n_commands`` commands, draw, and read the
        framebuffer into ``pixels`` ((height, width, 3) uint8 RGB, top row first); the
        pipeline's context must be current."""
        gl = self._raw
        frame = self.frame
        used = frame.commands_offset + 4 * COMMAND_UINTS * n_commands
        gl.BufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, used, self._frame_ptr)
        # Pass 1: every vertex to the world frame, once.
        gl.Enable(GL.GL_RASTERIZER_DISCARD)
        gl.UseProgram(self._transform)
        gl.BindVertexArray(self._vaos[0])
        gl.BeginTransformFeedback(GL.GL_POINTS)
        gl.DrawArrays(GL.GL_POINTS, 0, self._n_vertices)
        gl.EndTransformFeedback()
        gl.Disable(GL.GL_RASTERIZER_DISCARD)
        # Pass 2: all views.
        gl.UseProgram(self._draw)
        gl.BindVertexArray(self._vaos[1])
        gl.Clear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        gl.MultiDrawElementsIndirect(
            GL.GL_TRIANGLES, GL.GL_UNSIGNED_INT, frame.commands_offset, n_commands, 0
        )
        gl.ReadPixels(
            0, 0, self.width, self.height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, self._rgba_ptr
        )
        cv2.cvtColor(self._rgba, cv2.COLOR_RGBA2RGB, dst=pixels)
