#!/usr/bin/env bash
# The portal tracer beside the grid on the GPU machine (docs/PORTAL.md, "On the GPU machine"), from
# the repo root. Staging, here:
#   cmake --preset gpu && cmake --build --preset gpu -j2 --target gridrt
#   ../shared/gpu/pack.sh build/gpu/apps/gridrt -- ../shared/data/scenes/bunny/bunny.obj data/scenes/bunny.json
# There: bash tools/gpu/portal-bench.sh (G=.gpu by default). Logs go to $OUT (default
# /tmp/gridrt-out): portal-bench.log (everything, in order) and one log per run under $OUT/runs.
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
  run "grid bunny" gridrt bench "$bunny_json" --backend vulkan --frames 30 --warmup 5 "${S[@]}"
fi

echo "=== $failed of $n runs failed" | tee -a "$L"
exit "$failed"
