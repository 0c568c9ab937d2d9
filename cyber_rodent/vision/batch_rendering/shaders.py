"""The batch renderer's two GLSL programs: their sources, the model's lights, compile and link.

Pass 1 (transform feedback, once per frame, no rasterisation) moves every vertex of the static
mesh to the world frame and lights it with the view-independent terms (ambient and every
active directional model light); pass 2 (one multi-draw for all views) applies each view's
camera and headlight and moves the result into the view's tile of the framebuffer, clipped to
the tile by four ``gl_ClipDistance`` planes. Lighting is MuJoCo's fixed-function lighting
evaluated per vertex as OpenGL does it (ambient + Lambert diffuse, no specular: the lights have
none), clamped to [0, 1] per vertex and interpolated. The model's lights are compiled into the
transform shader as constants (only their directions change at run time).
"""

from __future__ import annotations

import ctypes
from collections.abc import Iterable

import mujoco
import numpy as np
from OpenGL import GL
from OpenGL.GL import shaders

#: Vec4s per geom in the per-frame buffer read by :data:`TRANSFORM_SHADER`: pos, xmat rows, rgba.
GEOM_VEC4 = 5
#: Vec4s per transformed vertex written by pass 1: world position, world normal, lit colour,
#: headlight colour.
TF_VEC4 = 4
#: The transform-feedback outputs of :data:`TRANSFORM_SHADER`, in buffer order.
TRANSFORM_FEEDBACK = ("t_pos", "t_normal", "t_lit", "t_head")

# Pass 1 (transform feedback, once per frame): geom frame -> world, view-independent lighting.
TRANSFORM_SHADER = """
#version 450
layout(location = 0) in vec4 a_pos;     // xyz: geom frame, scaled; w: geom index
layout(location = 1) in vec3 a_normal;  // geom frame
layout(std430, binding = 0) readonly buffer Geoms {
    vec4 lights[N_LIGHT_SLOTS];  // unit vectors towards the directional lights
    vec4 geoms[];                // per geom: pos, xmat rows 0-2, rgba
};
out vec4 t_pos;
out vec4 t_normal;
out vec4 t_lit;   // rgb * (ambient + directional lights)
out vec4 t_head;  // rgb * headlight diffuse
void main() {
    int g = 5 * int(a_pos.w);
    vec3 r0 = geoms[g + 1].xyz;
    vec3 r1 = geoms[g + 2].xyz;
    vec3 r2 = geoms[g + 3].xyz;
    vec3 rgb = geoms[g + 4].rgb;
    vec3 p = a_pos.xyz;
    vec3 n = vec3(dot(r0, a_normal), dot(r1, a_normal), dot(r2, a_normal));
    t_pos = vec4(geoms[g].xyz + vec3(dot(r0, p), dot(r1, p), dot(r2, p)), 1.0);
    t_normal = vec4(n, 0.0);
    t_lit = vec4(rgb * (AMBIENT LIGHT_TERMS), 0.0);
    t_head = vec4(rgb * HEAD_DIFFUSE, 0.0);
}
"""

# Pass 2 (all views, one multi-draw): camera, headlight, tile.
VIEW_SHADER = """
#version 450
#extension GL_ARB_shader_draw_parameters : require
layout(location = 0) in vec4 a_pos;
layout(location = 1) in vec4 a_normal;
layout(location = 2) in vec4 a_lit;
layout(location = 3) in vec4 a_head;
struct View {
    mat4 clip;  // world -> the view's own clip space (image row 0 at y = -1)
    vec4 head;  // unit vector towards the headlight
    vec4 tile;  // the view's tile in the framebuffer's NDC: centre x, y; scale x, y
};
layout(std430, binding = 1) readonly buffer Views { View views[]; };
out vec3 v_colour;
out float gl_ClipDistance[4];
void main() {
    View v = views[gl_BaseInstanceARB];
    vec4 c = v.clip * a_pos;
    gl_ClipDistance[0] = c.w + c.x;
    gl_ClipDistance[1] = c.w - c.x;
    gl_ClipDistance[2] = c.w + c.y;
    gl_ClipDistance[3] = c.w - c.y;
    gl_Position = vec4(c.xy * v.tile.zw + c.w * v.tile.xy, c.zw);
    v_colour = clamp(a_lit.rgb + a_head.rgb * max(dot(a_normal.xyz, v.head.xyz), 0.0), 0.0, 1.0);
}
"""

FRAGMENT_SHADER = """
#version 450
in vec3 v_colour;
layout(location = 0) out vec4 f_colour;
void main() {
    f_colour = vec4(v_colour, 1.0);
}
"""



def directional_lights(model: mujoco.MjModel) -> list[int]:
    """The model's active lights, all of which must be directional.

    Raises:
        ValueError: for an active light of another type.
    """
    lights = []
    for j in range(model.nlight):
        if not model.light_active[j]:
            continue
        if int(model.light_type[j]) != mujoco.mjtLightType.mjLIGHT_DIRECTIONAL:
            raise ValueError(
                f"light {j} is not directional; BatchOmniRenderer supports directional "
                "lights (and the headlight) only"
            )
        lights.append(j)
    return lights


def _vec3(v: Iterable[float]) -> str:
    return "vec3({:.9g}, {:.9g}, {:.9g})".format(*(float(x) for x in v))


def transform_source(model: mujoco.MjModel, lights: list[int]) -> str:
    """:data:`TRANSFORM_SHADER` with the headlight's and ``lights``' colours filled in."""
    head = model.vis.headlight
    active = float(bool(head.active))
    ambient = np.asarray(head.ambient, float) * active
    for j in lights:
        ambient = ambient + model.light_ambient[j]
    terms = "".join(
        f" + {_vec3(model.light_diffuse[j])} * max(dot(n, lights[{k}].xyz), 0.0)"
        for k, j in enumerate(lights)
    )
    return (
        TRANSFORM_SHADER.replace("N_LIGHT_SLOTS", str(max(len(lights), 1)))
        .replace("AMBIENT", _vec3(ambient))
        .replace("LIGHT_TERMS", terms)
        .replace("HEAD_DIFFUSE", _vec3(np.asarray(head.diffuse, float) * active))
    )


def link_program(
    vertex: str, fragment: str | None = None, feedback: Iterable[str] | None = None
) -> int:
    """Compile and link a program in the current context; ``feedback``: the vertex shader's
    outputs captured by transform feedback, interleaved.

    Raises:
        RuntimeError: if linking fails (compile errors raise PyOpenGL's ``ShaderCompilationError``).
    """
    program = GL.glCreateProgram()
    GL.glAttachShader(program, shaders.compileShader(vertex, GL.GL_VERTEX_SHADER))
    if fragment is not None:
        GL.glAttachShader(program, shaders.compileShader(fragment, GL.GL_FRAGMENT_SHADER))
    names = [ctypes.create_string_buffer(n.encode()) for n in feedback or ()]
    if names:
        pointers = (ctypes.POINTER(ctypes.c_char) * len(names))(
            *[ctypes.cast(n, ctypes.POINTER(ctypes.c_char)) for n in names]
        )
        GL.glTransformFeedbackVaryings(program, len(names), pointers, GL.GL_INTERLEAVED_ATTRIBS)
    GL.glLinkProgram(program)
    if not GL.glGetProgramiv(program, GL.GL_LINK_STATUS):
        raise RuntimeError(f"shader link failed: {GL.glGetProgramInfoLog(program)!r}")
    return int(program)
