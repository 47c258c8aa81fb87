"""GLSL sources of the ``gl`` renderer (:mod:`.gl_renderer`): projection, sort, splats, background.

The constants are the package's (:mod:`.common`, :mod:`.cpu_project`), written into the sources
when they are built, so that the shaders and the ``cpu`` renderer share one definition.

Buffers (std430, bindings fixed here and used by :mod:`.gl_renderer` and :mod:`.gl_sort`).  The
views are rendered in batches of B consecutive views (all N at once unless the per-view buffers
would exceed the driver's GL_MAX_SHADER_STORAGE_BLOCK_SIZE); per-view buffers hold one batch,
view v of the batch starting at ``first_view`` being its local view v - first_view:

    0 GAUSS    float[G * stride]: per Gaussian mean (3), opacity, world covariance (xx xy xz yy yz
               zz), then the K SH coefficients as K RGB triples; ``stride`` = 10 + 3 K
    1 CAMS     vec4[6 N]: per view the rows of [R t] (3), (fx, fy, cx, cy) in gsplat's frame (cx, cy
               already + 0.5), the camera centre (xyz, 0), the clamp limits of J (lim_x_pos,
               lim_x_neg, lim_y_pos, lim_y_neg)
    2 SPLATS   vec4[3 B G]: per (local view, Gaussian) the ``cpu`` renderer's record
               (:mod:`.cpu_project`'s REC_MX ... REC_EXT_Y, 12 floats) -- (mx, my, a, b), (c, opacity,
               R, G), (B, slope, q, ext_y)
    3 KEYS     uint[B G]: per local view G depth keys (float bits of the camera z, ascending =
               front to back; 0xFFFFFFFF where culled)
    4 VALS     uint[B G]: per key its splat slot v G + i (Gaussian i of local view v)
    5 CMDS     uint[5 N]: one DrawArraysIndirectCommand per view (3 vertices per visible Gaussian,
               1 instance, first 3 v G for local view v, base instance 0) and a pad: moderngl's
               render_indirect reads them 20 bytes apart

Pixel frame: gsplat's (pixel (x, y) centred at (x + 0.5, y + 0.5), y down), which is also
``gl_FragCoord`` in the view's layer drawn without a flip (texel row 0 = image row 0).
"""

from __future__ import annotations

from ..cameras.view_cameras import NEAR_PLANE
from .common import EPS2D, FAR_PLANE
from .cpu import ALPHA_MAX
from .cpu_project import ALPHA_MIN, COV_MAX, SIGMA_MARGIN

GROUP = 64  # compute work-group size (invocations along x)
GAUSS, CAMS, SPLATS, KEYS, VALS, CMDS = range(6)
LAYER_EXTENSION = "GL_ARB_shader_viewport_layer_array"
RECORDS_PER_ROW = 1024  # records per row of the CPU sort's record texture (3 texels each)


def _f(value: float) -> str:
    return f"{float(value):.9e}"


CONSTANTS = f"""
const float NEAR_PLANE = {_f(NEAR_PLANE)};
const float FAR_PLANE = {_f(FAR_PLANE)};
const float EPS2D = {_f(EPS2D)};
const float ALPHA_MIN = {_f(ALPHA_MIN)};
const float ALPHA_MAX = {_f(ALPHA_MAX)};
const float SIGMA_MARGIN = {_f(SIGMA_MARGIN)};
const float COV_MAX = {_f(COV_MAX)};
"""

# SH colour (gsplat's / Sloan's basis, as cpu_project._sh_colour), for a unit direction d;
# sh(k) returns coefficient k as an RGB triple
_SH = """
vec3 sh_colour(int degree, vec3 d) {
    vec3 r = 0.2820947917738781 * sh(0);
    if (degree >= 1) {
        float x = d.x, y = d.y, z = d.z;
        r += 0.48860251190292 * (-y * sh(1) + z * sh(2) - x * sh(3));
        if (degree >= 2) {
            float z2 = z * z;
            float t0b = -1.092548430592079 * z;
            float c1 = x * x - y * y;
            float s1 = 2.0 * x * y;
            r += 0.5462742152960395 * s1 * sh(4) + t0b * y * sh(5)
                 + (0.9461746957575601 * z2 - 0.3153915652525201) * sh(6)
                 + t0b * x * sh(7) + 0.5462742152960395 * c1 * sh(8);
            if (degree >= 3) {
                float t0c = -2.285228997322329 * z2 + 0.4570457994644658;
                float t1b = 1.445305721320277 * z;
                float c2 = x * c1 - y * s1;
                float s2 = x * s1 + y * c1;
                r += -0.5900435899266435 * s2 * sh(9) + t1b * s1 * sh(10) + t0c * y * sh(11)
                     + z * (1.865881662950577 * z2 - 1.119528997770346) * sh(12)
                     + t0c * x * sh(13) + t1b * c1 * sh(14) - 0.5900435899266435 * c2 * sh(15);
            }
        }
    }
    return max(r + 0.5, vec3(0.0));
}
"""

PROJECT = f"""
#version 430
layout(local_size_x = {GROUP}) in;
layout(std430, binding = {GAUSS}) readonly buffer Gauss {{ float g[]; }};
layout(std430, binding = {CAMS}) readonly buffer Cams {{ vec4 cams[]; }};
layout(std430, binding = {SPLATS}) writeonly buffer Splats {{ vec4 splats[]; }};
layout(std430, binding = {KEYS}) writeonly buffer Keys {{ uint keys[]; }};
layout(std430, binding = {VALS}) writeonly buffer Vals {{ uint vals[]; }};
layout(std430, binding = {CMDS}) buffer Cmds {{ uint cmds[]; }};
uniform int count;     // G
uniform int first_view;  // the batch's first view
uniform int stride;    // floats per Gaussian in GAUSS
uniform int degree;    // SH degree
uniform vec2 size;     // (width, height), pixels
{CONSTANTS}
int base;
vec3 sh(int k) {{ int o = base + 10 + 3 * k; return vec3(g[o], g[o + 1], g[o + 2]); }}
{_SH}
void main() {{
    int i = int(gl_GlobalInvocationID.x);
    int lv = int(gl_WorkGroupID.y);  // local view
    int v = first_view + lv;
    if (i >= count) return;
    uint slot = uint(lv * count + i);
    uint key = 0xFFFFFFFFu;
    vals[slot] = slot;
    {{
        base = i * stride;
        vec3 m = vec3(g[base], g[base + 1], g[base + 2]);
        float op = g[base + 3];
        vec4 r0 = cams[6 * v], r1 = cams[6 * v + 1], r2 = cams[6 * v + 2];
        vec4 f = cams[6 * v + 3], eye = cams[6 * v + 4], lim = cams[6 * v + 5];
        float x = dot(r0.xyz, m) + r0.w;
        float y = dot(r1.xyz, m) + r1.w;
        float z = dot(r2.xyz, m) + r2.w;
        if (z >= NEAR_PLANE && z <= FAR_PLANE && op >= ALPHA_MIN) {{
            int c = base + 4;
            mat3 cov = mat3(g[c], g[c + 1], g[c + 2], g[c + 1], g[c + 3], g[c + 4], g[c + 2], g[c + 4], g[c + 5]);
            mat3 rot = transpose(mat3(r0.xyz, r1.xyz, r2.xyz));
            mat3 k = rot * cov * transpose(rot);  // camera frame
            float rz = 1.0 / z;
            float tx = z * min(lim.x, max(-lim.y, x * rz));
            float ty = z * min(lim.z, max(-lim.w, y * rz));
            float j00 = f.x * rz, j02 = -f.x * tx * rz * rz;
            float j11 = f.y * rz, j12 = -f.y * ty * rz * rz;
            float k00 = k[0][0], k01 = k[1][0], k02 = k[2][0], k11 = k[1][1], k12 = k[2][1], k22 = k[2][2];
            float c00 = j00 * j00 * k00 + 2.0 * j00 * j02 * k02 + j02 * j02 * k22 + EPS2D;
            float c01 = j00 * j11 * k01 + j00 * j12 * k02 + j02 * j11 * k12 + j02 * j12 * k22;
            float c11 = j11 * j11 * k11 + 2.0 * j11 * j12 * k12 + j12 * j12 * k22 + EPS2D;
            float det = c00 * c11 - c01 * c01;
            if (det > 0.0 && c00 < COV_MAX && c11 < COV_MAX) {{
                float lg = max(log(op / ALPHA_MIN), 0.0);
                float extend = min(3.33, sqrt(2.0 * lg));
                float rx = ceil(extend * sqrt(c00));
                float ry = ceil(extend * sqrt(c11));
                float u = f.x * x * rz + f.z;
                float w = f.y * y * rz + f.w;
                bool off = u + rx <= 0.0 || u - rx >= size.x || w + ry <= 0.0 || w - ry >= size.y;
                if (!(rx <= 0.0 && ry <= 0.0) && !off) {{
                    key = floatBitsToUint(z);
                    vec3 d = m - eye.xyz;
                    float n = length(d);
                    if (n > 0.0) d /= n;
                    vec3 colour = sh_colour(degree, d);
                    uint s = 3u * slot;
                    splats[s] = vec4(u, w, c11 / det, -c01 / det);
                    splats[s + 1u] = vec4(c00 / det, op, colour.rg);
                    splats[s + 2u] = vec4(colour.b, c01 / c11, det / (c11 * c11),
                                          sqrt(2.0 * (lg + SIGMA_MARGIN) * c11));
                    atomicAdd(cmds[5 * v], 3u);
                }}
            }}
        }}
    }}
    keys[slot] = key;
}}
"""

# Splats as one triangle each (geometry, not fragments, is what costs most on llvmpipe): the
# record's ellipse where alpha can reach 1/255 is, in (x', dy) with x' = dx - slope dy, the
# axis-aligned ellipse of half-axes sqrt(q) ext_y and ext_y, i.e. the unit circle scaled; the
# triangle is the equilateral one circumscribing that circle (vertices 2 from its centre), mapped
# back (an affine map keeps it circumscribed).  One that would reach far past the view is a
# triangle covering the whole view instead (the fragment test decides).
_SPLAT = """
out Splat {
    flat vec2 mean;
    flat vec4 conic_op;
    flat vec3 colour;
} splat_out;
uniform vec2 size;
const vec2 TRIANGLE[3] = vec2[3](vec2(0.0, 2.0), vec2(-1.7320508, -1.0), vec2(1.7320508, -1.0));
void splat(vec4 r0, vec4 r1, vec4 r2, int corner) {
    vec2 mean = r0.xy;
    splat_out.mean = mean;
    splat_out.conic_op = vec4(r0.zw, r1.xy);
    splat_out.colour = vec3(r1.zw, r2.x);
    float ext_y = r2.w;
    float half_x = sqrt(r2.z) * ext_y;
    vec2 p;
    if (2.0 * (ext_y + abs(r2.y) * ext_y + half_x) > 4.0 * (size.x + size.y)) {
        p = vec2(corner == 1 ? 2.0 : 0.0, corner == 2 ? 2.0 : 0.0) * (size + 2.0) - 1.0;
    } else {
        vec2 s = TRIANGLE[corner];
        float dy = s.y * ext_y;
        p = mean + vec2(s.x * half_x + r2.y * dy, dy);
    }
    gl_Position = vec4(2.0 * p / size - 1.0, 0.0, 1.0);
}
"""

# The layer of a vertex: SET_LAYER(x) writes gl_Layer where the driver has the extension that
# allows it in a vertex shader, else passes it to :func:`geometry_shader`'s pass-through, which
# writes it (OpenGL 3.2 core); :func:`vertex_shader` picks one.
_LAYER = f"""
#ifdef VERTEX_LAYER
#extension {LAYER_EXTENSION} : require
#define SET_LAYER(x) gl_Layer = (x)
#else
flat out int layer_v;
#define SET_LAYER(x) layer_v = (x)
#endif
"""

# GPU-sorted draw: no instancing (llvmpipe runs each instance as a draw of its own), one
# triangle per splat; vertex 3 (v G + rank) + k is corner k of the rank-th splat of local view v,
# whose slot is VALS[v G + rank]
SPLAT_VERTEX_GPU = f"""
#version 430
{_LAYER}
layout(std430, binding = {SPLATS}) readonly buffer Splats {{ vec4 splats[]; }};
layout(std430, binding = {VALS}) readonly buffer Vals {{ uint vals[]; }};
uniform int count;
uniform int first_view;
{_SPLAT}
void main() {{
    uint slot = vals[gl_VertexID / 3];
    uint s = 3u * slot;
    splat(splats[s], splats[s + 1u], splats[s + 2u], gl_VertexID % 3);
    SET_LAYER(first_view + int(slot) / count);
}}
"""

# CPU-sorted draw (OpenGL 3.3): the records in drawing order in an RGBA32F texture, record r in
# texels (3 (r % per_row) + k, r / per_row), k = 0, 1, 2; one draw call per view (``first`` = 3
# times the view's first record), one triangle per record
SPLAT_VERTEX_HOST = f"""
#version 330 core
{_LAYER}
uniform sampler2D records;
uniform int per_row;
uniform int layer;
{_SPLAT}
void main() {{
    int r = gl_VertexID / 3;
    ivec2 t = ivec2(3 * (r % per_row), r / per_row);
    splat(texelFetch(records, t, 0), texelFetch(records, t + ivec2(1, 0), 0), texelFetch(records, t + ivec2(2, 0), 0),
          gl_VertexID % 3);
    SET_LAYER(layer);
}}
"""

# A splat's alpha at a pixel centre (the ``cpu`` renderer's compositing rule), shared by the
# fragment shader here and the ``gl-compute`` renderer's tiles (:mod:`.gl_compute_shaders`):
# ``d`` the pixel centre minus the mean (px), ``c`` the conic (a, b, c) and opacity; 0 where
# sigma < 0 or alpha < 1/255 (the pixel skips the splat).  Needs ``CONSTANTS``.
SPLAT_ALPHA = """
float splat_alpha(vec2 d, vec4 c) {
    float sigma = 0.5 * (c.x * d.x * d.x + c.z * d.y * d.y) + c.y * d.x * d.y;
    float alpha = min(ALPHA_MAX, c.w * exp(-sigma));
    return (sigma < 0.0 || alpha < ALPHA_MIN) ? 0.0 : alpha;
}
"""

SPLAT_FRAGMENT = f"""
#version 330 core
{CONSTANTS}
{SPLAT_ALPHA}
in Splat {{
    flat vec2 mean;
    flat vec4 conic_op;
    flat vec3 colour;
}} splat_in;
out vec4 result;
void main() {{
    float alpha = splat_alpha(gl_FragCoord.xy - splat_in.mean, splat_in.conic_op);
    if (alpha == 0.0) discard;
    result = vec4(splat_in.colour * alpha, alpha);  // blended: C += (1 - A) c alpha, A += (1 - A) alpha
}}
"""

# Background under what was drawn: one triangle per layer (instance = layer), (bg, 0) blended
# like a splat: C += (1 - A) bg, A unchanged
BACKGROUND_VERTEX = f"""
#version 330 core
{_LAYER}
void main() {{
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
    SET_LAYER(gl_InstanceID);
}}
"""

BACKGROUND_FRAGMENT = """
#version 330 core
uniform vec3 background;
out vec4 result;
void main() { result = vec4(background, 0.0); }
"""


def vertex_shader(source: str, vertex_layer: bool) -> str:
    """``source`` (one of the vertex shaders above) writing gl_Layer itself (``vertex_layer``:
    the driver has LAYER_EXTENSION) or handing it to :func:`geometry_shader`."""
    head, rest = source.lstrip().split("\n", 1)
    return f"{head}\n#define VERTEX_LAYER\n{rest}" if vertex_layer else f"{head}\n{rest}"


def geometry_shader(splat: bool) -> str:
    """A pass-through geometry shader that writes gl_Layer (for drivers without LAYER_EXTENSION),
    handing on the Splat block when ``splat``."""
    block = "flat vec2 mean; flat vec4 conic_op; flat vec3 colour;"
    return f"""
#version 330 core
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
flat in int layer_v[];
{f"in Splat {{ {block} }} splat_in[]; out Splat {{ {block} }} splat_out;" if splat else ""}
void main() {{
    for (int k = 0; k < 3; ++k) {{
        gl_Position = gl_in[k].gl_Position;
        gl_Layer = layer_v[0];
        {"splat_out.mean = splat_in[k].mean; splat_out.conic_op = splat_in[k].conic_op; "
         "splat_out.colour = splat_in[k].colour;" if splat else ""}
        EmitVertex();
    }}
    EndPrimitive();
}}
"""
