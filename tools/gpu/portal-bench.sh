#!/usr/bin/env bash
# The portal tracer beside the grid on the GPU machine (docs/PORTAL.md, "On the GPU machine"), from
# the repo root. Staging, here:
#   cmake --preset gpu && cmake --build --preset gpu -j2 --target gridrt
#   ../shared/gpu/pack.sh build/gpu/apps/gridrt -- ../shared/data/scenes/bunny/bunny.obj data/scenes/bunny.json
# There: bash tools/gpu/portal-bench.sh (G=.gpu by default). Logs go to $OUT (default
# /tmp/gridrt-out): portal-bench.log (everything, in order), one log per run under $OUT/runs, and
# instanced-summary.txt (instanced against flattened, and the grid on the same level, runs 1-10). INSTANCED_ONLY=1: only those
# runs (about a minute).
# A failing run is logged with its exit code and the script goes on; the exit code is the number of
# failed runs (0: all ran).
#
# What is compared: the same scenes (the built-in teapot, the Stanford bunny) through the portal
# tracer (voxelized; primary rays, then the renderer's primary + 2 shadow rays per pixel) and
# through the grid (`gridrt bench`: its static build, then per frame the glossy-bounce trace),
# both 720 x 360. The workloads differ: each prints its own rays/s and milliseconds.
set -euo pipefail
G=${G:-.gpu}
OUT=${OUT:-/tmp/gridrt-out}
mkdir -p "$OUT/runs" "$OUT/scenes/bunny"
L=$OUT/portal-bench.log
: >"$L"
if [ ! -f "$G/env.sh" ]; then
  echo "portal-bench: $G/env.sh missing: stage the gpu build with ../shared/gpu/pack.sh first" | tee -a "$L"
  exit 1
fi
set +u  # env.sh is not written for set -u
# shellcheck disable=SC1091
source "$G/env.sh"
set -u
command -v gridrt >/dev/null || { echo "portal-bench: gridrt is not on PATH after $G/env.sh" | tee -a "$L"; exit 1; }

# The bunny as the scene file expects it: ${GRIDRT_SCENES}/bunny/bunny.obj.
bunny_json=$G/extra/bunny.json
obj=$G/extra/bunny.obj
if [ ! -f "$obj" ] && [ -f "$obj.xz" ]; then
  xz -dkf "$obj.xz" 2>/dev/null ||
    python3 -c "import lzma,sys; open(sys.argv[1][:-3],'wb').write(lzma.open(sys.argv[1]).read())" "$obj.xz"
fi
have_bunny=0
if [ -f "$obj" ] && [ -f "$bunny_json" ]; then
  ln -sf "$(cd "$(dirname "$obj")" && pwd)/bunny.obj" "$OUT/scenes/bunny/bunny.obj"
  export GRIDRT_SCENES=$OUT/scenes
  have_bunny=1
else
  echo "portal-bench: bunny.obj or bunny.json not staged in $G/extra: the bunny runs are skipped" | tee -a "$L"
fi

failed=0
n=0
run() {  # run NAME COMMAND...: its output to $OUT/runs/NN.log and to the main log
  local name=$1 rc=0
  shift
  n=$((n + 1))
  local log
  log=$OUT/runs/$(printf '%02d' "$n").log
  {
    echo "=== $name"
    echo "\$ $*"
  } | tee -a "$L"
  timeout 600 "$@" >"$log" 2>&1 || rc=$?
  cat "$log" >>"$L"
  if [ "$rc" -ne 0 ]; then
    echo "=== FAILED (exit $rc): $name" | tee -a "$L"
    failed=$((failed + 1))
  fi
}

nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader >>"$L" 2>&1 || echo "(no nvidia-smi)" >>"$L"
nproc >>"$L"
S=(--width 720 --height 360)
P=(--repeat 5 "${S[@]}")

# Instanced subspaces (docs/PORTAL.md, "Instanced subspaces"): the built-in block level instanced
# and flattened (the same voxels written out), the pixels that differ between the two renders, the
# device against the reference, and a generated block level that only fits instanced. First, so
# that its summary ($OUT/instanced-summary.txt) is written even if a later run is cut off.
run "instanced builtin:blocks" gridrt portal bench builtin:blocks "${P[@]}"
i_bench=$n
run "flattened builtin:blocks" gridrt portal bench builtin:blocks --flatten "${P[@]}"
f_bench=$n
run "instanced vs flattened render, portal-cpu" gridrt portal render builtin:blocks --flat-compare "${S[@]}" \
  -o "$OUT/blocks-cpu.ppm"
c_cmp=$n
run "instanced vs flattened render, portal-vulkan" gridrt portal render builtin:blocks --flat-compare \
  --backend portal-vulkan "${S[@]}" -o "$OUT/blocks-vulkan.ppm"
v_cmp=$n
run "portal diff builtin:blocks (bit for bit: division and square root correctly rounded)" \
  gridrt portal diff builtin:blocks "${S[@]}"
d_blocks=$n
run "instanced gen-blocks:255x255x4 (flattened: 2040 voxels wide, beyond the format)" \
  gridrt portal bench gen-blocks:255x255x4 "${P[@]}"
g_bench=$n
# The grid on the same level: its voxel faces as triangles (gridrt portal export), the blocks as the
# grid's own instances, and flattened into one mesh.
mkdir -p "$OUT/scenes/blocks"
run "export builtin:blocks as triangles (instances)" gridrt portal export builtin:blocks -o "$OUT/scenes/blocks/blocks.json"
run "export builtin:blocks as triangles (flattened)" gridrt portal export builtin:blocks --flatten \
  -o "$OUT/scenes/blocks/blocks_flat.json"
run "grid builtin:blocks (instances)" gridrt bench "$OUT/scenes/blocks/blocks.json" --backend vulkan --frames 30 \
  --warmup 5 --rays primary "${S[@]}"
gi_bench=$n
run "grid builtin:blocks (flattened)" gridrt bench "$OUT/scenes/blocks/blocks_flat.json" --backend vulkan --frames 30 \
  --warmup 5 --rays primary "${S[@]}"
gf_bench=$n
{
  echo "Instanced subspaces on $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || echo '?'),"
  echo "$(nproc) CPU cores; 720 x 360, best of 5 (full logs: $OUT/runs/NN.log)."
  for k in "$i_bench" "$f_bench" "$g_bench"; do
    f=$OUT/runs/$(printf '%02d' "$k").log
    echo "--- run $k"
    grep -E '^world |^\| portal-|^\| voxel-|^render portal-|vs portal-cpu|vs voxel-dda' "$f" 2>/dev/null || echo "(no output)"
  done
  for k in "$gi_bench" "$gf_bench"; do
    f=$OUT/runs/$(printf '%02d' "$k").log
    echo "--- run $k (the grid)"
    grep -E '^bench:|^\| vulkan' "$f" 2>/dev/null || echo "(no output)"
  done
  for k in "$c_cmp" "$v_cmp" "$d_blocks"; do
    f=$OUT/runs/$(printf '%02d' "$k").log
    echo "--- run $k"
    grep -E 'instanced against flattened|hit records|render:|agree|DIFFER|error' "$f" 2>/dev/null || echo "(no output)"
  done
} >"$OUT/instanced-summary.txt"
cat "$OUT/instanced-summary.txt" >>"$L"
if [ "${INSTANCED_ONLY:-0}" = 1 ]; then
  echo "=== $failed of $n runs failed" | tee -a "$L"
  exit "$failed"
fi

# Portal: tile maps (no triangle version, so no grid beside them).
run "portal builtin level" gridrt portal bench builtin:level "${P[@]}"
run "portal generated level 255x255x4" gridrt portal bench gen:255x255x4 "${P[@]}"
run "portal generated level 255x255x16" gridrt portal bench gen:255x255x16 "${P[@]}"
run "portal generated level 255x255x253 (build time)" gridrt portal bench gen:255x255x253 --repeat 1 "${S[@]}"
run "portal diff builtin level (NVIDIA division: t within 3 ulps)" \
  gridrt portal diff builtin:level "${S[@]}" --ulps 3 --uv-tolerance 1e-4 --pixels 0.5

# The same scenes through both.
run "portal teapot 64 (bounded choice)" gridrt portal bench builtin:teapot --voxels 64 "${P[@]}"
run "portal teapot 64 (exact choice)" gridrt portal bench builtin:teapot --voxels 64 --div-choice exact "${P[@]}"
run "grid teapot" gridrt bench builtin:teapot --backend vulkan --frames 30 --warmup 5 "${S[@]}"
if [ "$have_bunny" = 1 ]; then
  for v in 48 64 96; do
    run "portal bunny $v" gridrt portal bench "$bunny_json" --voxels "$v" --atlas-width 8192 "${P[@]}"
  done
  run "portal bunny 128 (build time)" gridrt portal bench "$bunny_json" --voxels 128 --atlas-width 8192 --repeat 1 "${S[@]}"
  run "grid bunny" gridrt bench "$bunny_json" --backend vulkan --frames 30 --warmup 5 --rays primary "${S[@]}"
fi

echo "=== $failed of $n runs failed" | tee -a "$L"
exit "$failed"
