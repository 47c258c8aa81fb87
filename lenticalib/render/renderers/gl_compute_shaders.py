"""GLSL of the ``gl-compute`` renderer (:mod:`.gl_compute`): tile intersection, scan, tile ranges, compositing.

The projection and the depth sort are the ``gl`` renderer's own (:data:`.gl_shaders.PROJECT`,
:class:`.gl_sort.GLSorter`), and a pixel's alpha is :data:`.gl_shaders.SPLAT_ALPHA`: one GLSL
source for each formula, shared with the triangle path.  What is here is what only a tile
renderer needs.

Buffers (std430), in addition to :mod:`.gl_shaders`' 0-5 (GAUSS, CAMS, SPLATS, KEYS, VALS, CMDS)
and :mod:`.gl_sort`'s scratch 6-11, for a batch of B views of G Gaussians and T tiles a view:

    12 TKEYS   uint[I]: per intersection (splat, tile it touches) the key lv T + tile (lv the
               local view, tile = ty tiles_x + tx); sorted stably, so that (splats entering in
               front-to-back order) it is the key view | tile | depth, ties by index
    13 TVALS   uint[I]: per intersection the splat's slot in SPLATS (lv G + i)
    14 SUMS    uint[chunks + 1]: per chunk of :data:`CHUNK` depth-sorted entries its intersections,
               then (after :data:`SCAN`) exclusive offsets and, at [chunks], the total I
    15 RANGES  uvec2[B T]: per tile of the batch [first, end) of its intersections (zero: none)

A splat's tiles: per tile row that the ellipse where alpha can reach 1/255 crosses (the record's
``ext_y``, ``slope`` and ``q``), the tiles its x-extent over that row's band reaches, clamped to
the view: every pixel the compositing can take from the splat.  Against the ellipse's bounding
box in whole tiles, the same images bit for bit from fewer pairs: 15% fewer on the demo avatar
(6000 Gaussians, 4 views of 320x180), 22% by a host estimate at 960x540.

Compositing (:func:`composite_source`): one 16 x 16 work group per (tile, local view), one
invocation per pixel.  The tile's splats are staged in shared memory 256 at a time (each
invocation loads one; float32, or with ``half`` the conic, opacity and colour packed as float16
and the mean kept float32), then every live pixel walks them front to back as the ``cpu``
renderer does: alpha by SPLAT_ALPHA, the pixel stops *before* the splat that would take its
transmittance to <= T_MIN, colour += c alpha T.  A shared counter of stopped pixels ends the
tile early when all 256 have stopped.  The result, RGB + T background and alpha 1 - T, is
stored into layer first_view + lv of the RGBA32F texture array bound as image 0.
"""

from __future__ import annotations

from . import gl_shaders as sh
from .common import TILE_SIZE
from .cpu import T_MIN

TKEYS, TVALS, SUMS, RANGES = range(12, 16)
CHUNK = 256  # depth-sorted entries per invocation of INTERSECT_COUNT / INTERSECT_EMIT
SCAN_GROUP = 256  # invocations of the one work group of SCAN
STAGED = TILE_SIZE * TILE_SIZE  # splats staged in shared memory at a time (one per invocation)
SPAN_MARGIN = 0.01  # px added to each side of a splat's extent on a tile row (the cpu renderer's chord margin)

_HEAD = f"""
#version 430
layout(local_size_x = {sh.GROUP}) in;
layout(std430, binding = {sh.SPLATS}) readonly buffer Splats {{ vec4 splats[]; }};
layout(std430, binding = {sh.KEYS}) readonly buffer Keys {{ uint keys[]; }};
layout(std430, binding = {SUMS}) buffer Sums {{ uint sums[]; }};
uniform uint entries;  // B G depth-sorted entries of the batch
uniform uint chunks;   // ceil(entries / CHUNK)
uniform ivec2 tiles;   // (tiles_x, tiles_y) of a view
const uint CHUNK = {CHUNK}u;
const float TILE = {float(TILE_SIZE)};
const float SPAN_MARGIN = {SPAN_MARGIN};

// the tile rows [y0, y1) of the splat whose record starts with r0, r2: its ellipse's rows
ivec2 tile_rows(vec4 r0, vec4 r2) {{
    float top = float(tiles.y);
    return ivec2(clamp(floor((r0.y - r2.w) / TILE), 0.0, top), clamp(ceil((r0.y + r2.w) / TILE), 0.0, top));
}}

// the tiles [x0, x1) of tile row ``ty`` that the ellipse reaches: its x-extent over the row's
// band of dy (the chord's right end is concave in dy, its left end convex: each has one extreme,
// at dy = +-slope ext_y / sqrt(slope^2 + q)), widened by SPAN_MARGIN px against rounding
ivec2 tile_span(vec4 r0, vec4 r2, int ty) {{
    float slope = r2.y, q = r2.z, e = r2.w;
    float d0 = max(float(ty) * TILE - r0.y, -e), d1 = min(float(ty + 1) * TILE - r0.y, e);
    float turn = slope * e / sqrt(slope * slope + q);
    float dr = min(max(turn, d0), d1), dl = min(max(-turn, d0), d1);
    float hi = r0.x + slope * dr + sqrt(max(q * (e * e - dr * dr), 0.0)) + SPAN_MARGIN;
    float lo = r0.x + slope * dl - sqrt(max(q * (e * e - dl * dl), 0.0)) - SPAN_MARGIN;
    float right = float(tiles.x);
    return ivec2(clamp(floor(lo / TILE), 0.0, right), clamp(ceil(hi / TILE), 0.0, right));
}}

// how many tiles the splat in ``slot`` touches
uint tile_count(uint slot) {{
    vec4 r0 = splats[3u * slot], r2 = splats[3u * slot + 2u];
    ivec2 rows = tile_rows(r0, r2);
    uint n = 0u;
    for (int ty = rows.x; ty < rows.y; ++ty) {{
        ivec2 span = tile_span(r0, r2, ty);
        n += uint(max(span.y - span.x, 0));
    }}
    return n;
}}
"""

# per chunk of depth-sorted entries, the intersections of its visible splats (culled keys: all ones)
INTERSECT_COUNT = _HEAD + f"""
layout(std430, binding = {sh.VALS}) readonly buffer Vals {{ uint vals[]; }};
void main() {{
    uint c = gl_GlobalInvocationID.x;
    if (c >= chunks) return;
    uint total = 0u;
    uint end = min(c * CHUNK + CHUNK, entries);
    for (uint i = c * CHUNK; i < end; ++i) {{
        if (keys[i] != 0xFFFFFFFFu) total += tile_count(vals[i]);
    }}
    sums[c] = total;
}}
"""

# exclusive offsets of the chunks' intersections, and the total at [chunks]: one work group, each
# invocation scans a run of chunks serially, the run totals are scanned in shared memory
SCAN = f"""
#version 430
layout(local_size_x = {SCAN_GROUP}) in;
layout(std430, binding = {SUMS}) buffer Sums {{ uint sums[]; }};
uniform uint chunks;
shared uint partial[{SCAN_GROUP}];
void main() {{
    uint t = gl_LocalInvocationID.x;
    uint per = (chunks + {SCAN_GROUP - 1}u) / {SCAN_GROUP}u;
    uint first = min(t * per, chunks), end = min(first + per, chunks);
    uint total = 0u;
    for (uint c = first; c < end; ++c) total += sums[c];
    partial[t] = total;
    memoryBarrierShared();
    barrier();
    if (t == 0u) {{
        uint run = 0u;
        for (uint k = 0u; k < {SCAN_GROUP}u; ++k) {{ uint n = partial[k]; partial[k] = run; run += n; }}
        sums[chunks] = run;
    }}
    memoryBarrierShared();
    barrier();
    uint run = partial[t];
    for (uint c = first; c < end; ++c) {{ uint n = sums[c]; sums[c] = run; run += n; }}
}}
"""

# per chunk, its intersections from its offset on, in depth order: key lv T + tile, value the slot
INTERSECT_EMIT = _HEAD + f"""
layout(std430, binding = {sh.VALS}) readonly buffer Vals {{ uint vals[]; }};
layout(std430, binding = {TKEYS}) writeonly buffer TKeys {{ uint tkeys[]; }};
layout(std430, binding = {TVALS}) writeonly buffer TVals {{ uint tvals[]; }};
uniform uint count;  // G: entries per local view
void main() {{
    uint c = gl_GlobalInvocationID.x;
    if (c >= chunks) return;
    uint at = sums[c];
    uint per_view = uint(tiles.x * tiles.y);
    uint end = min(c * CHUNK + CHUNK, entries);
    for (uint i = c * CHUNK; i < end; ++i) {{
        if (keys[i] == 0xFFFFFFFFu) continue;
        uint slot = vals[i];
        vec4 r0 = splats[3u * slot], r2 = splats[3u * slot + 2u];
        ivec2 rows = tile_rows(r0, r2);
        uint base = (i / count) * per_view;
        for (int ty = rows.x; ty < rows.y; ++ty) {{
            ivec2 span = tile_span(r0, r2, ty);
            for (int tx = span.x; tx < span.y; ++tx) {{
                tkeys[at] = base + uint(ty * tiles.x + tx);
                tvals[at] = slot;
                ++at;
            }}
        }}
    }}
}}
"""

# per sorted intersection, where its tile's run starts and ends
RANGES_OF_TILES = f"""
#version 430
layout(local_size_x = {sh.GROUP}) in;
layout(std430, binding = {TKEYS}) readonly buffer TKeys {{ uint tkeys[]; }};
layout(std430, binding = {RANGES}) buffer Ranges {{ uvec2 ranges[]; }};
uniform uint total;
void main() {{
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * {sh.GROUP}u;
    if (i >= total) return;
    uint k = tkeys[i];
    if (i == 0u || tkeys[i - 1u] != k) ranges[k].x = i;
    if (i + 1u == total || tkeys[i + 1u] != k) ranges[k].y = i + 1u;
}}
"""

_STAGE_FLOAT = f"""
shared vec4 s_a[{STAGED}];  // mean, conic a, b
shared vec4 s_b[{STAGED}];  // conic c, opacity, R, G
shared float s_c[{STAGED}];  // B
void stage(uint k, uint s) {{ s_a[k] = splats[s]; s_b[k] = splats[s + 1u]; s_c[k] = splats[s + 2u].x; }}
void staged(uint k, out vec2 mean, out vec4 conic_op, out vec3 colour) {{
    vec4 a = s_a[k], b = s_b[k];
    mean = a.xy; conic_op = vec4(a.zw, b.xy); colour = vec3(b.zw, s_c[k]);
}}
"""

_STAGE_HALF = f"""
shared vec2 s_mean[{STAGED}];  // float32: pixel coordinates need it
shared uvec4 s_pack[{STAGED}];  // float16 pairs: (a, b), (c, opacity), (R, G), (B, 0)
void stage(uint k, uint s) {{
    vec4 a = splats[s], b = splats[s + 1u];
    s_mean[k] = a.xy;
    s_pack[k] = uvec4(packHalf2x16(a.zw), packHalf2x16(b.xy), packHalf2x16(b.zw), packHalf2x16(vec2(splats[s + 2u].x, 0.0)));
}}
void staged(uint k, out vec2 mean, out vec4 conic_op, out vec3 colour) {{
    uvec4 p = s_pack[k];
    mean = s_mean[k];
    conic_op = vec4(unpackHalf2x16(p.x), unpackHalf2x16(p.y));
    colour = vec3(unpackHalf2x16(p.z), unpackHalf2x16(p.w).x);
}}
"""

_COMPOSITE = f"""
#version 430
layout(local_size_x = {TILE_SIZE}, local_size_y = {TILE_SIZE}) in;
layout(std430, binding = {sh.SPLATS}) readonly buffer Splats {{ vec4 splats[]; }};
layout(std430, binding = {TVALS}) readonly buffer TVals {{ uint tvals[]; }};
layout(std430, binding = {RANGES}) readonly buffer Ranges {{ uvec2 ranges[]; }};
layout(rgba32f, binding = 0) writeonly uniform image2DArray views;
uniform int first_view;
uniform ivec2 size;      // (width, height), pixels
uniform vec3 background;
{sh.CONSTANTS}
const float T_MIN = {T_MIN!r};
const uint STAGED = {STAGED}u;
{sh.SPLAT_ALPHA}
%(stage)s
shared uint stopped;  // pixels of the tile that take nothing more
void main() {{
    uint lid = gl_LocalInvocationIndex;
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    uvec3 wg = gl_WorkGroupID;
    uvec2 range = ranges[(wg.z * gl_NumWorkGroups.y + wg.y) * gl_NumWorkGroups.x + wg.x];
    bool inside = px.x < size.x && px.y < size.y;
    bool done = !inside;
    if (lid == 0u) stopped = 0u;
    memoryBarrierShared();
    barrier();
    if (done) atomicAdd(stopped, 1u);
    vec2 centre = vec2(px) + 0.5;  // gsplat's pixel centre, the records' frame
    float T = 1.0;
    vec3 C = vec3(0.0);
    for (uint first = range.x; first < range.y; first += STAGED) {{
        memoryBarrierShared();
        barrier();  // the last batch is composited, and every stop counted
        if (stopped == STAGED) break;
        if (first + lid < range.y) stage(lid, 3u * tvals[first + lid]);
        memoryBarrierShared();
        barrier();
        if (done) continue;
        uint n = min(STAGED, range.y - first);
        for (uint k = 0u; k < n; ++k) {{
            vec2 mean;
            vec4 conic_op;
            vec3 colour;
            staged(k, mean, conic_op, colour);
            float alpha = splat_alpha(centre - mean, conic_op);
            if (alpha == 0.0) continue;
            float next_t = T * (1.0 - alpha);
            if (next_t <= T_MIN) {{
                done = true;
                atomicAdd(stopped, 1u);
                break;
            }}
            C += colour * (alpha * T);
            T = next_t;
        }}
    }}
    if (inside) imageStore(views, ivec3(px, first_view + int(wg.z)), vec4(C + T * background, 1.0 - T));
}}
"""


def composite_source(half: bool) -> str:
    """The compositing compute shader, its staged splats float32 or (``half``) float16 but the mean."""
    return _COMPOSITE % {"stage": _STAGE_HALF if half else _STAGE_FLOAT}
