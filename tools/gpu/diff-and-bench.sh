#!/usr/bin/env bash
# On the GPU machine (../shared/gpu/README.md), from the repo root, after `source .gpu/env.sh`:
# the differential tool and the frame benchmark on the paper's three frames, staged as
# .gridscene.gz in .gpu/extra (see docs/BENCHMARKS.md for how to stage them). Logs go to $OUT.
set -uo pipefail
out=${OUT:-/tmp/gridrt-out}
mkdir -p "$out"
cd .gpu/extra && gunzip -kf ./*.gridscene.gz && cd ../..
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot)
nv="--max-image-dimension 16384"
{
  for s in "${scenes[@]}"; do
    for trav in paper exact; do
      echo "== diff $s $trav sorted"
      gridrt diff .gpu/extra/$s.gridscene --traversal $trav $nv --width 480 --height 270 --frames 3 \
        --ulps 8 --uv-tolerance 1e-3 2>&1 | grep -v "^  \|^segment\|^step\|^slot\|^    " | tail -12
    done
  done
  echo "== diff sibenik first-empty, compute build"
  gridrt diff .gpu/extra/sibenik-teapots.gridscene --insertion first-empty --vk-build compute $nv \
    --width 480 --height 270 --frames 3 --ulps 8 --uv-tolerance 1e-3 2>&1 | tail -8
} | tee "$out/diff.txt"
for s in "${scenes[@]}"; do
  echo "== bench $s"
  gridrt bench .gpu/extra/$s.gridscene --backend vulkan,cpu $nv --frames ${FRAMES:-20} --warmup 3 \
    --json "$out/bench-$s.json" 2>&1 | grep -v "gather buffer:"
done | tee "$out/bench.txt"
