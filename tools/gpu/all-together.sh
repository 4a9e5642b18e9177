#!/usr/bin/env bash
# Everything on the GPU machine in one run (docs/BENCHMARKS.md "All of it together", docs/VULKAN.md
# "What agrees where"), from the repo root, after staging here:
#   cmake --preset gpu && cmake --build --preset gpu -j2 --target gridrt
#   for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
#     build/release/apps/gridrt convert $GRIDRT_SCENES/$s.json -o /tmp/gs/$s.gridscene; done
#   pack.sh build/gpu/apps/gridrt -- /tmp/gs/*.gridscene tools/gpu/all-together.sh \
#       /usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so \
#       /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
# There: PART=diff|bench|all bash .gpu/extra/all-together.sh (G=.gpu by default); logs to $OUT.
#   diff:  per scene, the reference against the shaders bit for bit with the validation layer on:
#          the paper traversal with the raster build and the GPU frame's own passes (gather, bounce,
#          shadow rays), the exact traversal with the compute build and the GPU frame's passes (and
#          the rasterizer's gather against the box gather), and with the raster build.
#   bench: per scene, the default exact traversal (compute build, separating-axis cell test,
#          skipping, spill list, rasterizer gather) beside the RT pipeline, with the shadow pass
#          (the scenes' light) and without; and with the plane/sphere cell test.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot)
case ${PART:-all} in
diff | all)
  {
    for s in "${scenes[@]}"; do
      X=$E/$s.gridscene
      echo "== diff $s paper, raster build, the GPU frame's passes (bit for bit)"
      timeout 150 gridrt diff $X --traversal paper --vk-build raster --gpu-frame --width 480 --height 270 --frames 2 2>&1 |
        grep -E "^(diff|frame|AGREE|DIFFER|validation|  first)|error" | tail -14
      echo "exit $?"
      for b in compute raster; do
        fr=""; [ $b = compute ] && fr=--gpu-frame
        echo "== diff $s exact, $b build $fr (bit for bit)"
        timeout 150 gridrt diff $X --traversal exact --vk-build $b $fr --width 480 --height 270 --frames 2 2>&1 |
          grep -E "^(diff|frame|AGREE|DIFFER|spill|validation|  first)|error" | tail -10
      done
    done
  } 2>&1 | tee "$out/diff.txt"
  ;;&
bench | all)
  B="--backend vulkan --traversal exact --vk-build compute --rtx --frames 30 --warmup 5"
  {
    for s in "${scenes[@]}"; do
      for sh in on off; do
        echo "== bench $s exact (defaults), shadows $sh"
        timeout 150 gridrt bench $E/$s.gridscene $B --shadows $sh 2>&1 | grep -v "gather buffer" | cut -c1-300
      done
      echo "== bench $s exact, the plane/sphere cell test instead of the separating axes, shadows on"
      timeout 150 gridrt bench $E/$s.gridscene $B --cell-test sphere 2>&1 | grep -v "gather buffer" | cut -c1-300
    done
  } 2>&1 | tee "$out/bench.txt"
  ;;
esac
