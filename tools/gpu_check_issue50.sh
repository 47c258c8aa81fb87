#!/usr/bin/env bash
# Issue 50's measurements on a machine with an NVIDIA GPU, in one run; prints every number.
#
#   bash tools/gpu_check_issue50.sh [PYTHON]      # from anywhere; PYTHON: the venv's python
#
# 1. the GPU and driver (nvidia-smi), the OpenGL driver that EGL gives (GL_RENDERER)
# 2. render of the demo avatar (100k Gaussians), 32 views of 960x540: gl triangles and
#    gl-compute (fp32 and fp16), stage medians (tools/bench_gl_compute.py), then gsplat on CUDA
#    (CUDA events) and the ratio gl-compute / gsplat (target: <= 2)
# 3. the encoders, 32 views of 960x540 -> 3840x2160: the gl encoder's draw (GL timer queries) and
#    the torch encoder (tools/bench_encode_torch.py, CUDA events) (target: < 1 ms each)
# 4. `play --display offscreen` end to end, 120 frames: gsplat + torch, and gl + gl (the compute
#    renderer on a GPU's driver) (target: the CUDA path >= 100 fps)
#
# ISSUE50_SMALL=1 shrinks everything (3000 Gaussians, 96x54 views, 3 frames) to check the script
# on a machine without a GPU; the CUDA rows then say they cannot run.  gsplat compiles its CUDA
# kernels on first use (74-84 s on an H100): step 2 pays that once, step 4 reuses the cache.
# Each step has its own time limit and a failed step does not stop the others.
set -u
PY=${1:-${PYTHON:-python}}
cd "$(dirname "$0")/.."
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
if [ "${ISSUE50_SMALL:-0}" = 1 ]; then
    COUNT=3000; SIZE=96x54; FRAMES=3; PLAY_FRAMES=3; RUNS=5
else
    COUNT=100000; SIZE=960x540; FRAMES=10; PLAY_FRAMES=120; RUNS=30
fi
W=${SIZE%x*}; H=${SIZE#*x}
step() { echo; echo "== $*"; }

step "1. machine"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>&1 || echo "no nvidia-smi"
"$PY" - <<'EOF' 2>&1
from lenticalib.render.gpu.gl_context import headless_context
ctx = headless_context()
with ctx:
    print("OpenGL:", ctx.info["GL_RENDERER"], "|", ctx.info["GL_VERSION"])
try:
    import torch
    print("torch", torch.__version__, "cuda", torch.version.cuda, "device",
          torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none")
except ImportError:
    print("torch: not installed")
EOF

step "2a. gl renderer: triangles vs compute, $SIZE x 32 views, $COUNT Gaussians (ms)"
timeout 600 "$PY" tools/bench_gl_compute.py --count "$COUNT" --views 32 --size "$SIZE" --frames "$FRAMES" \
    --warmup 2 --skip-cpu 2>&1 | tail -n 8
timeout 300 "$PY" tools/bench_gl_compute.py --count "$COUNT" --views 32 --size "$SIZE" --frames "$FRAMES" \
    --warmup 2 --skip-cpu --paths compute --precision fp16 2>&1 | tail -n 1

step "2b. gsplat vs gl-compute on the same posed avatar (ms, medians; PSNR of gl-compute against gsplat)"
COUNT=$COUNT W=$W H=$H FRAMES=$FRAMES timeout 600 "$PY" - <<'EOF' 2>&1
import math, os, statistics, time
import numpy as np
from lenticalib.render.cameras.models import make_cameras
from lenticalib.render.avatar.demo_avatar import make_demo_avatar
from lenticalib.render.gpu.gl_context import headless_context
from lenticalib.render.renderers.gl_compute import GLComputeRenderer
count, w, h, frames = (int(os.environ[k]) for k in ("COUNT", "W", "H", "FRAMES"))
rig = make_demo_avatar(count=count)
g = rig.deform(rig.neutral_controls()).to_numpy()
cams = make_cameras("arc", g, 32, view_size=(w, h))
ctx = headless_context()
with ctx:
    r = GLComputeRenderer(ctx, 32, w, h)
    times = []
    for k in range(frames + 2):
        t = time.perf_counter(); r.render(g, cams.viewmats, cams.K); ctx.finish(); times.append(time.perf_counter() - t)
    gl_ms = 1e3 * statistics.median(times[2:])
    gl_views = r.read()
    r.release()
print(f"gl-compute render_ms {gl_ms:.2f} ({ctx.info['GL_RENDERER']})")
try:
    import torch
    from lenticalib.render.renderers.gsplat_backend import gsplat_unavailable, render_gsplat
    reason = gsplat_unavailable()
    if reason:
        raise RuntimeError(reason)
    t0 = time.perf_counter()
    out = render_gsplat(g, cams.viewmats, cams.K, w, h)
    torch.cuda.synchronize()
    print(f"gsplat first call (kernel compile) {time.perf_counter() - t0:.1f} s")
    g_cuda = g.to_torch("cuda")
    times = []
    for k in range(frames + 2):
        start, end = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
        start.record(); out = render_gsplat(g_cuda, cams.viewmats, cams.K, w, h); end.record()
        torch.cuda.synchronize(); times.append(start.elapsed_time(end))
    gs_ms = statistics.median(times[2:])
    ref = out.float().cpu().numpy()
    worst = min(10 * math.log10(1 / max(float(np.mean((gl_views[v, ..., :3] - ref[v, ..., :3]) ** 2)), 1e-30))
                for v in range(32))
    print(f"gsplat render_ms {gs_ms:.2f} (CUDA events); gl-compute / gsplat = {gl_ms / gs_ms:.2f} (target <= 2); "
          f"worst view PSNR gl-compute vs gsplat {worst:.1f} dB")
except Exception as exc:  # no torch, gsplat or CUDA here
    print(f"gsplat: cannot run here: {exc}")
EOF

step "3a. gl encoder draw, 32 views $SIZE -> 3840x2160 (GL timer queries, ms)"
W=$W H=$H RUNS=$RUNS timeout 300 "$PY" - <<'EOF' 2>&1
import os, statistics
import numpy as np
from lenticalib.core.profile import load_profile
from lenticalib.render.encoders.gl_encoder import GLEncoder
from lenticalib.render.gpu.gl_context import headless_context
w, h, runs = int(os.environ["W"]), int(os.environ["H"]), int(os.environ["RUNS"])
profile = load_profile("fixtures/panel-4k-32.json")
ctx = headless_context()
with ctx:
    enc = GLEncoder(profile, (h, w), ctx=ctx)
    enc.upload_views(np.random.default_rng(0).integers(0, 256, (32, h, w, 3), dtype=np.uint8))
    query, times = ctx.query(time=True), []
    for k in range(runs + 3):
        with query:
            enc.draw()
            ctx.finish()
        times.append(query.elapsed / 1e6)
    enc.release()
    print(f"gl encoder draw_ms {statistics.median(times[3:]):.3f} (median of {runs}; {ctx.info['GL_RENDERER']}; "
          "target < 1)")
EOF

step "3b. torch encoder (CUDA events, ms; target < 1)"
for dtype in float64 float32 float16; do
    timeout 300 "$PY" tools/bench_encode_torch.py --device cuda --dtype "$dtype" --runs "$RUNS" 2>&1 | tail -n 1
done

step "4. play --display offscreen, $PLAY_FRAMES frames (stage medians and fps; target: cuda >= 100 fps)"
timeout 120 "$PY" tools/make_demo_avatar.py "$WORK/demo.npz" --count "$COUNT" > /dev/null 2>&1 || echo "no demo avatar"
for pair in "gsplat torch" "gl gl"; do  # gl: the compute renderer on a GPU (gl_renderer_for)
    set -- $pair
    echo "-- renderer $1, encoder $2"
    timeout 600 "$PY" -m lenticalib.cli play "$WORK/demo.npz" --profile fixtures/panel-4k-32.json \
        --display offscreen --frames "$PLAY_FRAMES" --renderer "$1" --encoder "$2" --view-size "$SIZE" 2>&1 | tail -n 12
done
echo; echo "== done"
