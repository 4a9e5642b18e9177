#!/usr/bin/env bash
# The trace against the grid's resolution on the GPU machine (docs/BENCHMARKS.md "The grid's
# resolution on the GPU"): per frame, the trace-cost policy's chosen grid beside the RT pipeline,
# then the policy's other candidates (finer and coarser; `gridrt stats X --traversal exact
# --candidates --memory-budget 200` lists them) at the same rays, the memory budget lifted so
# that every candidate builds. From the repo root, after staging here:
#   cmake --preset gpu && cmake --build --preset gpu -j2 --target gridrt
#   gridrt convert data/scenes/X.json -o /tmp/gs/X.gridscene   (sibenik-teapots, sponza-teapots, ons-reborn-teapot)
#   ../shared/gpu/pack.sh build/gpu/apps/gridrt -- /tmp/gs/*.gridscene
# There: bash tools/gpu/resolution-sweep.sh (G=.gpu by default; FRAMES=20); log in $OUT/sweep.txt.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
[ -n "${BIN:-}" ] && chmod +x "$BIN"
bin=${BIN:-gridrt}
frames=${FRAMES:-20}
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
declare -A res=(
  [sibenik-teapots]="402,105,256 338,88,215 239,63,152 201,53,128"
  [sponza-teapots]="245,117,110 206,99,93 174,83,78 146,70,66 123,59,55 87,42,39"
  [ons-reborn-teapot]="243,243,97 205,205,82 145,145,58"
  [builtin:atrium]="67,39,100 56,33,84 48,28,71 40,23,60 28,17,42"
)
sel='^\| (grid|rtx|[0-9])|^agree:|^vulkan|error'
B="--backend vulkan --traversal exact --vk-build compute --frames $frames --warmup 5"
{
  for s in sibenik-teapots sponza-teapots ons-reborn-teapot builtin:atrium; do
    X=$E/$s.gridscene
    [ "$s" = builtin:atrium ] && X=$s
    echo "== $s: the chosen grid, beside the RT pipeline"
    # shellcheck disable=SC2086
    timeout 120 "$bin" bench "$X" $B --rtx 2>&1 | grep -E "$sel" | cut -c1-300
    for r in ${res[$s]}; do
      echo "== $s --resolution $r"
      # shellcheck disable=SC2086
      timeout 120 "$bin" bench "$X" $B --resolution "$r" --memory-budget 1024 2>&1 | grep -E "$sel" | cut -c1-300
    done
  done
} 2>&1 | tee "$out/sweep.txt"
