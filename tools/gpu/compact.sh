#!/usr/bin/env bash
# The compact layout on the GPU machine (docs/BENCHMARKS.md "Compact layout"), from the repo root,
# after staging here:
#   cmake --preset gpu && cmake --build --preset gpu -j2 --target gridrt
#   gridrt convert data/scenes/X.json -o /tmp/gs/X.gridscene   (sibenik-teapots, sponza-teapots, ons-reborn-teapot)
#   ../shared/gpu/pack.sh build/gpu/apps/gridrt -- /tmp/gs/*.gridscene tools/gpu/compact.sh \
#     /usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
# There: bash tools/gpu/compact.sh (G=.gpu by default). First gridrt diff (the reference against the
# shaders, bit for bit, validation layer on) with the compact layout on the three frames; then per
# scene, in one run on the same rays, the exact traversal with the compute build beside the RT
# pipeline: --layout image and --layout compact (the default budget); then compact with a 64 MiB budget.
# Logs go to $OUT.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
{
  for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
    echo "== diff $s exact, compact layout, compute build (bit for bit, validation on)"
    timeout 90 gridrt diff $E/$s.gridscene --traversal exact --layout compact --vk-build compute --width 480 \
      --height 270 --frames 2 2>&1 | grep -E "^(diff|frame|AGREE|DIFFER|validation|  first|gridrt)" | tail -12
  done
} 2>&1 | tee "$out/diff.txt"
B="--backend vulkan --traversal exact --vk-build compute --rtx --frames 30 --warmup 5"
bench() {  # scene, layout options
  echo "== bench $1 exact --layout ${*:2}"
  timeout 75 gridrt bench $E/$1.gridscene $B --layout "${@:2}" 2>&1 |
    grep -E "^\| (grid|rtx|[0-9])|^agree|^grid memory|warm build split|^vulkan|error" | cut -c1-400
}
{
  for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
    bench $s image
    bench $s compact
  done
  for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do bench $s compact --memory-budget 64; done
} 2>&1 | tee "$out/bench.txt"
