#!/usr/bin/env bash
# The bounce trace and the first light's shadow trace in one dispatch (`--traces together`, the
# default) against two passes (`--traces apart`; docs/BENCHMARKS.md "The bounce and shadow traces
# in one dispatch"), on the GPU machine:
#   diff:  bit for bit, gridrt diff --gpu-frame --traces together|apart on the three frames and the
#          built-in atrium at 480x270, two frames, validation on; Sponza's together at 1920x1080
#   bench: per frame, apart and together in turns, ROUNDS times, beside the RT pipeline; per scene
#          gridrt bench X --backend vulkan --traversal exact --vk-build compute --rtx --frames 30 \
#            --warmup 5 --traces apart|together
# Staged as tools/gpu/speed-and-trust.sh says (this tree's gpu build and the frames' .gridscene
# caches). There: PART=diff|bench|all bash tools/gpu/traces-together.sh (SCENES, ROUNDS=2); logs
# in $OUT/traces-together-{diff,bench}.txt.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
scenes=${SCENES:-sibenik-teapots sponza-teapots ons-reborn-teapot atrium teapot}
scene_arg() { [ "$1" = atrium ] && echo builtin:atrium || echo "$E/$1.gridscene"; }
part=${PART:-all}
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
if [ "$part" = diff ] || [ "$part" = all ]; then
  keep='^(frame [0-9]+: GPU frame|AGREE|DIFFER|validation|  first|gridrt)|error'
  {
    for s in sibenik-teapots sponza-teapots ons-reborn-teapot atrium; do
      for traces in together apart; do
        echo "== diff $s --traces $traces, exact, compute build, the GPU frame's passes, 480x270"
        timeout 150 gridrt diff "$(scene_arg "$s")" --traversal exact --vk-build compute --gpu-frame --traces $traces \
          --width 480 --height 270 --frames 2 2>&1 | grep -E "$keep" | cut -c1-600 | tail -4
      done
    done
    echo "== diff sponza-teapots --traces together at 1920x1080, one frame"
    timeout 300 gridrt diff "$(scene_arg sponza-teapots)" --traversal exact --vk-build compute --gpu-frame \
      --traces together --width 1920 --height 1080 --frames 1 2>&1 | grep -E "$keep" | cut -c1-600 | tail -4
  } 2>&1 | tee "$out/traces-together-diff.txt"
fi
if [ "$part" = bench ] || [ "$part" = all ]; then
  sel='^\| [0-9g]|^\| rtx|^traces together|^shadow pass|^vulkan, the whole frame|error'
  {
    for s in $scenes; do
      for round in $(seq "${ROUNDS:-2}"); do
        for traces in apart together; do
          echo "== bench $s --traces $traces (round $round)"
          timeout 120 gridrt bench "$(scene_arg "$s")" --backend vulkan --traversal exact --vk-build compute --rtx \
            --frames 30 --warmup 5 --traces $traces 2>&1 | grep -E "$sel" | cut -c1-400
        done
      done
    done
  } 2>&1 | tee "$out/traces-together-bench.txt"
fi
