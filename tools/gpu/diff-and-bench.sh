#!/usr/bin/env bash
# On the GPU machine (../shared/gpu/README.md), from the repo root, after `source .gpu/env.sh`:
# the differential tool and the frame benchmark on the paper's three frames, staged as
# .gridscene.gz in .gpu/extra (docs/BENCHMARKS.md says how to stage them). Logs go to $OUT.
set -uo pipefail
out=${OUT:-/tmp/gridrt-out}
mkdir -p "$out"
(cd .gpu/extra && gunzip -kf ./*.gridscene.gz)
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot)
{
  for s in "${scenes[@]}"; do
    for trav in paper exact; do
      echo "== diff $s $trav sorted (bit for bit)"
      gridrt diff .gpu/extra/$s.gridscene --traversal $trav --width 480 --height 270 --frames 3 2>&1 |
        grep -E "^(diff|frame|AGREE|DIFFER|grid image limit)" | tail -8
    done
  done
  echo "== diff sibenik first-empty, compute build"
  gridrt diff .gpu/extra/sibenik-teapots.gridscene --insertion first-empty --vk-build compute \
    --width 480 --height 270 --frames 3 2>&1 | grep -E "^(diff|frame|AGREE|DIFFER)" | tail -8
} | tee "$out/diff.txt"
{
  for s in "${scenes[@]}"; do
    for b in raster compute; do
      echo "== bench $s vulkan ($b build)"
      gridrt bench .gpu/extra/$s.gridscene --backend vulkan --vk-build $b --frames ${FRAMES:-60} --warmup 10 \
        --json "$out/bench-$s-$b.json" 2>&1 | grep -v "gather buffer"
    done
    echo "== bench $s cpu (16 threads)"
    gridrt bench .gpu/extra/$s.gridscene --backend cpu --max-image-dimension 16384 --frames 3 --warmup 1 2>&1 |
      grep -v "gather buffer"
  done
} | tee "$out/bench.txt"
