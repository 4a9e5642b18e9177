#!/usr/bin/env bash
# Empty-space skipping on the GPU machine (docs/BENCHMARKS.md "Empty-space skipping"), from the
# repo root, after staging here:
#   cmake --preset gpu && cmake --build --preset gpu -j2
#   pack.sh build/gpu/apps/gridrt -- X.gridscene ...   (gridrt convert data/scenes/X.json -o X.gridscene)
# There: bash tools/gpu/skip-bench.sh (G=.gpu by default). Per scene, in one run on the same rays:
# the exact traversal with the compute build beside the RT pipeline, skipping off and on; the
# paper traversal's figures unchanged; then gridrt diff (the reference against the shaders, bit for
# bit) with skipping on. Logs go to $OUT.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
B="--backend vulkan --traversal exact --vk-build compute --rtx --frames 30 --warmup 5"
{
  for s in sibenik-teapots sponza-teapots ons-reborn-teapot bunny builtin:atrium; do
    f=$E/$s.gridscene
    [ "${s#builtin:}" != "$s" ] && f=$s
    for k in off on; do
      echo "== bench $s exact skip-empty $k"
      timeout 200 gridrt bench $f $B --skip-empty $k 2>&1 |
        grep -E "^\| (grid|rtx|[0-9])|^agree|^grid memory|warm build split|^vulkan|error" | cut -c1-400
    done
  done
} 2>&1 | tee "$out/bench.txt"
{
  for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
    echo "== diff $s exact, skipping on, compute build (bit for bit)"
    timeout 200 gridrt diff $E/$s.gridscene --traversal exact --vk-build compute --width 480 --height 270 --frames 3 2>&1 |
      grep -E "^(diff|frame|AGREE|DIFFER|spill|  first)" | tail -8
  done
} 2>&1 | tee "$out/diff.txt"
