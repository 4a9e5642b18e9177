#!/usr/bin/env bash
# The gather's rasterizer on the GPU machine (docs/BENCHMARKS.md "The gather as a rasterizer"),
# from the repo root, after staging here:
#   cmake --preset gpu && cmake --build --preset gpu -j2 --target gridrt
#   for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
#     build/release/apps/gridrt convert data/scenes/$s.json -o /tmp/gs/$s.gridscene; done
#   pack.sh build/gpu/apps/gridrt -- /tmp/gs/*.gridscene tools/gpu/gather-bench.sh \
#       /usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so \
#       /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
# There: PART=diff|bench|all bash .gpu/extra/gather-bench.sh (G=.gpu by default); logs to $OUT.
#   diff:  per scene, gridrt diff --gpu-frame (validation layer on): the GPU frame's passes against
#          the reference, and the rasterizer's gather buffer against the box gather's, bit for bit
#   bench: per scene, the frame with the box gather and with the rasterizer, one after the other
#          in this one run (exact traversal, compute build, medians of 30 frames after 5)
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot)
case ${PART:-all} in
diff | all)
  {
    for s in "${scenes[@]}"; do
      echo "== diff $s exact, compute build, the GPU frame's passes and the rasterizer (bit for bit)"
      timeout 200 gridrt diff $E/$s.gridscene --traversal exact --vk-build compute --gpu-frame --width ${DW:-960} \
        --height ${DH:-540} --frames 2 2>&1 | grep -E "^(diff|frame|AGREE|DIFFER|validation|  first)|error" | tail -12
    done
  } 2>&1 | tee "$out/diff.txt"
  ;;&
bench | all)
  B="--backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5 ${BENCH_ARGS:-}"
  {
    for s in "${scenes[@]}"; do
      for g in boxes compute; do
        echo "== bench $s exact, --gather $g"
        timeout 150 gridrt bench $E/$s.gridscene $B --gather $g 2>&1 | grep -v "gather buffer" |
          grep -E "^\||gather split|update" | cut -c1-400
      done
    done
  } 2>&1 | tee "$out/bench.txt"
  ;;
esac
