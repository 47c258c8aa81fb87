"""The views stage on the GPU: rendered RGBA -> the 8-bit views the encoder samples, in one compute pass.

Between a GL renderer (:mod:`lenticalib.render.renderers.gl_renderer`, float RGBA layers) and
the GL encoder (:mod:`lenticalib.render.encoders.gl_encoder`, 8-bit layers), per pixel of the
views, all N layers at once, what :class:`lenticalib.render.pipeline.avatar_pipeline.AvatarPipeline` does on the
host for the CPU path, in the same order and arithmetic:

1. ``rgb += (1 - alpha) * background`` (a colour, an image of the view size, or black: none);
2. edge desaturation ``luma + (rgb - luma) (1 - s (1 - alpha))`` (:func:`..host_views.desaturate_edges`);
3. 8-bit codes ``floor(v 255 + 0.5)`` clamped to 0..255, in double precision like ``to_uint8``;
4. crosstalk pre-compensation (:class:`lenticalib.render.compose.compensation.Compensator`): the codes
   decoded to linear light by the same table, the circular filters along the view axis with the
   same taps in the same order, the projected-gradient steps, the same 4096-level encode table.

Steps 1-2 run in float32 with ``precise`` (no fused multiply-adds), as numpy does them; the
compensation's filters in float32 too (the CPU kernel may fuse them), so the views agree with
the CPU path's to within one level (tested).  Needs OpenGL 4.3 (compute shaders); without it
the pipeline runs this stage on the host (:mod:`lenticalib.render.pipeline.gl_frame`).

Frames: texel (x, y) of layer i is pixel column x, image row y (row 0 at the top) of view i, in
the source and in :attr:`GLViewStage.views` alike.
"""

from __future__ import annotations

import numpy as np

from ...core.errors import DisplayError
from .compensation import Compensator, decode_table, encode_table

_GROUP = 8  # work group: 8 x 8 pixels

_SOURCE = """
#version 430
layout(local_size_x = %(group)d, local_size_y = %(group)d) in;
layout(rgba32f, binding = 0) readonly uniform image2DArray rendered;
layout(rgba8, binding = 1) writeonly uniform image2DArray views;
uniform int width;
uniform int height;
uniform int background_kind;   // 0 none, 1 colour, 2 image
uniform vec3 background_colour;
uniform sampler2D background_image;   // (W_v, H_v) RGB, texel row 0 = image row 0
uniform float desaturation;
const int N = %(views)d;
#define COMPENSATE %(compensate)d
#if COMPENSATE
layout(std430, binding = 2) readonly buffer Tables { float decode[256]; uint encode_codes[%(levels)d]; };
const int SOLVE_TAPS = %(solve_count)d;
const int SOLVE_OFFSETS[SOLVE_TAPS] = int[](%(solve_offsets)s);
const float SOLVE_WEIGHTS[SOLVE_TAPS] = float[](%(solve_weights)s);
const int NORMAL_TAPS = %(normal_count)d;
const int NORMAL_OFFSETS[NORMAL_TAPS] = int[](%(normal_offsets)s);
const float NORMAL_WEIGHTS[NORMAL_TAPS] = float[](%(normal_weights)s);
const int RHS_TAPS = %(rhs_count)d;
const int RHS_OFFSETS[RHS_TAPS] = int[](%(rhs_offsets)s);
const float RHS_WEIGHTS[RHS_TAPS] = float[](%(rhs_weights)s);
const float STEP = %(step)s;
const float LIFT = %(lift)s;
const int ITERATIONS = %(iterations)d;
#endif

uvec3 codes_of(ivec3 at, vec3 under) {
    precise vec4 p = imageLoad(rendered, at);
    precise vec3 rgb = p.rgb + (1.0 - p.a) * under;
    if (desaturation > 0.0) {
        precise float luma = 0.2126 * rgb.r + 0.7152 * rgb.g + 0.0722 * rgb.b;
        precise float keep = 1.0 - desaturation * (1.0 - p.a);
        rgb = luma + (rgb - luma) * keep;
    }
    dvec3 v = dvec3(rgb) * 255.0LF + 0.5LF;
    return uvec3(clamp(floor(v), 0.0LF, 255.0LF));
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (px.x >= width || px.y >= height) return;
    vec3 under = background_kind == 1 ? background_colour
               : background_kind == 2 ? texelFetch(background_image, px, 0).rgb : vec3(0.0);
#if COMPENSATE
    float t[N], e[N], b[N], g[N];
    uint codes[N];
    for (int i = 0; i < N; ++i) codes[i] = 0u;
    for (int c = 0; c < 3; ++c) {
        for (int i = 0; i < N; ++i) t[i] = LIFT + (1.0 - LIFT) * decode[codes_of(ivec3(px, i), under)[c]];
        for (int i = 0; i < N; ++i) {
            float acc = 0.0;
            for (int k = 0; k < SOLVE_TAPS; ++k) acc += SOLVE_WEIGHTS[k] * t[(i + SOLVE_OFFSETS[k] + N * 64) %% N];
            e[i] = clamp(acc, 0.0, 1.0);
        }
        if (ITERATIONS > 0) {
            for (int i = 0; i < N; ++i) {
                float acc = 0.0;
                for (int k = 0; k < RHS_TAPS; ++k) acc += RHS_WEIGHTS[k] * t[(i + RHS_OFFSETS[k] + N * 64) %% N];
                b[i] = acc;
            }
            for (int it = 0; it < ITERATIONS; ++it) {
                for (int i = 0; i < N; ++i) {
                    float acc = 0.0;
                    for (int k = 0; k < NORMAL_TAPS; ++k) acc += NORMAL_WEIGHTS[k] * e[(i + NORMAL_OFFSETS[k] + N * 64) %% N];
                    g[i] = acc;
                }
                for (int i = 0; i < N; ++i) e[i] = clamp(e[i] - STEP * (g[i] - b[i]), 0.0, 1.0);
            }
        }
        for (int i = 0; i < N; ++i) codes[i] |= encode_codes[int(e[i] * %(top)d.0 + 0.5)] << (8 * c);
    }
    for (int i = 0; i < N; ++i) {
        uvec3 q = uvec3(codes[i] & 255u, (codes[i] >> 8) & 255u, (codes[i] >> 16) & 255u);
        imageStore(views, ivec3(px, i), vec4(vec3(q) / 255.0, 1.0));
    }
#else
    for (int i = 0; i < N; ++i) imageStore(views, ivec3(px, i), vec4(vec3(codes_of(ivec3(px, i), under)) / 255.0, 1.0));
#endif
}
"""


def _floats(values) -> str:
    return ", ".join(repr(float(np.float32(v))) for v in values)


def _ints(values) -> str:
    return ", ".join(str(int(v)) for v in values)


def views_stage_source(n_views: int, compensator: Compensator | None) -> str:
    """The compute shader's GLSL for ``n_views`` layers, with ``compensator``'s taps baked in."""
    fields = {"group": _GROUP, "views": n_views, "compensate": int(compensator is not None), "levels": 1,
              "top": 0, "step": "0.0", "lift": "0.0", "iterations": 0}
    for name in ("solve", "normal", "rhs"):  # inside ``#if COMPENSATE``: compiled only with a compensator
        fields.update({f"{name}_count": 1, f"{name}_offsets": "0", f"{name}_weights": "0.0"})
    if compensator is not None:
        c = compensator
        table = encode_table()
        fields.update(levels=table.size, top=table.size - 1, step=repr(float(np.float32(c.step))),
                      lift=repr(float(np.float32(c.black_lift))), iterations=c.iterations)
        for name, offsets, weights in (("solve", c.solve_offsets, c.solve_weights),
                                       ("normal", c.normal_offsets, c.normal_weights),
                                       ("rhs", c.rhs_offsets, c.rhs_weights)):
            fields.update({f"{name}_count": len(offsets), f"{name}_offsets": _ints(offsets),
                           f"{name}_weights": _floats(weights)})
    return _SOURCE % fields


class GLViewStage:
    """The compute pass of the module docstring in moderngl context ``ctx`` (the caller's, current
    during every call; never released here).

    ``n_views``, ``width``, ``height``: the view stack; ``background``: None, (3,) RGB or
    (height, width, 3) float in 0..1; ``edge_desaturation`` 0..1; ``compensator`` or None.
    :attr:`views` is the RGBA8 texture array written by :meth:`run`, which the GL encoder samples.
    DisplayError (one line) without OpenGL 4.3.
    """

    def __init__(self, ctx, n_views: int, width: int, height: int, *, background=None,
                 edge_desaturation: float = 0.0, compensator: Compensator | None = None):
        if ctx.version_code < 430:
            raise DisplayError(f"the views stage needs OpenGL 4.3 compute shaders, the driver has "
                               f"{ctx.version_code // 100}.{ctx.version_code // 10 % 10}",
                               hint="the pipeline runs it on the host instead")
        self.ctx = ctx
        self.size = (int(width), int(height))
        self.n_views = int(n_views)
        self.compensator = compensator
        self._objects = []
        self.views = self._keep(ctx.texture_array((width, height, n_views), 4, dtype="f1"))
        self.views.filter = (ctx.NEAREST, ctx.NEAREST)
        self._program = self._keep(ctx.compute_shader(views_stage_source(n_views, compensator)))
        self._program["width"].value, self._program["height"].value = self.size
        self._program["desaturation"].value = float(edge_desaturation)
        kind = 0
        if background is not None:
            background = np.asarray(background, dtype=np.float32)
            if background.ndim == 1:
                kind = 1
                self._program["background_colour"].value = tuple(float(v) for v in background)
            else:
                kind = 2
                self._background = self._keep(ctx.texture((width, height), 3, np.ascontiguousarray(background).tobytes(),
                                                          dtype="f4"))
                self._background.filter = (ctx.NEAREST, ctx.NEAREST)
        self._program["background_kind"].value = kind
        if kind == 2:
            self._program["background_image"].value = 3
        self._tables = None
        if compensator is not None:
            tables = np.concatenate([decode_table().astype(np.float32).view(np.uint32),
                                     encode_table().astype(np.uint32)])
            self._tables = self._keep(ctx.buffer(tables.tobytes()))

    def _keep(self, obj):
        self._objects.append(obj)
        return obj

    def run(self, rendered) -> None:
        """Write :attr:`views` from ``rendered``, an RGBA32F texture array of the same size and layers."""
        rendered.bind_to_image(0, read=True, write=False)
        self.views.bind_to_image(1, read=False, write=True)
        if self._tables is not None:
            self._tables.bind_to_storage_buffer(2)
        if getattr(self, "_background", None) is not None:
            self._background.use(3)
        width, height = self.size
        self._program.run(-(-width // _GROUP), -(-height // _GROUP), 1)
        self.ctx.memory_barrier(self.ctx.TEXTURE_FETCH_BARRIER_BIT | self.ctx.SHADER_IMAGE_ACCESS_BARRIER_BIT
                                | self.ctx.TEXTURE_UPDATE_BARRIER_BIT)

    def read(self) -> np.ndarray:
        """The views as (N, height, width, 3) uint8, row 0 at the top."""
        width, height = self.size
        data = np.frombuffer(self.views.read(alignment=1), dtype=np.uint8)
        return np.ascontiguousarray(data.reshape(self.n_views, height, width, 4)[..., :3])

    def release(self) -> None:
        for obj in self._objects:
            obj.release()
        self._objects = []
