#!/usr/bin/env bash
# The frame's bounce rays sorted on the GPU before their trace (`--sort-rays BITS`, ray_sort.comp;
# docs/BENCHMARKS.md "The frame's bounce rays sorted on the GPU"), on the GPU machine:
#   1. bit for bit: gridrt diff --gpu-frame --sort-rays 32 (and 16) on the three frames and the
#      built-in atrium at 480x270, two frames, validation on; Sponza's at 1920x1080, one frame
#      (the order checked by diff at the frame's own size: 1013 blocks of the sort)
#   2. speed: per frame, the tiles (--sort-rays 0) and each of SORTS' key widths in turns, ROUNDS
#      times, the frame's passes with the sort's share; per scene
#        gridrt bench X --backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5 --sort-rays B
# Staged as tools/gpu/speed-and-trust.sh says (this tree's gpu build and the frames' .gridscene
# caches). There: bash tools/gpu/ray-sort.sh (G=.gpu by default; SCENES, SORTS="0 32 24 16",
# ROUNDS=2, NODIFF=1 or NOBENCH=1 to leave a part out; DIFFSORTS="32 16" the diffs' widths;
# VARIANTS="BIN:BITS ..." benches each staged binary $E/BIN, or gridrt, with --sort-rays BITS in
# turns instead of SORTS, to compare builds in one run); logs in $OUT/ray-sort-diff.txt and
# $OUT/ray-sort-bench.txt.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
scenes=${SCENES:-sibenik-teapots sponza-teapots ons-reborn-teapot atrium}
scene_arg() { [ "$1" = atrium ] && echo builtin:atrium || echo "$E/$1.gridscene"; }
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
if [ -z "${NODIFF:-}" ]; then
  keep='^(frame|AGREE|DIFFER|validation|  first|gridrt|  hit records)|error'
  {
    for s in $scenes; do
      for bits in ${DIFFSORTS:-32 16}; do
        echo "== diff $s --sort-rays $bits, exact, compute build, the GPU frame's passes, 480x270"
        timeout 150 gridrt diff "$(scene_arg "$s")" --traversal exact --vk-build compute --gpu-frame --sort-rays $bits \
          --width 480 --height 270 --frames 2 2>&1 | grep -E "$keep" | tail -8
      done
    done
    bits=${DIFFSORTS:-32}
    bits=${bits%% *}
    echo "== diff sponza-teapots --sort-rays $bits at 1920x1080, one frame"
    timeout 300 gridrt diff "$(scene_arg sponza-teapots)" --traversal exact --vk-build compute --gpu-frame \
      --sort-rays "$bits" --width 1920 --height 1080 --frames 1 2>&1 | grep -E "$keep" | tail -8
  } 2>&1 | tee "$out/ray-sort-diff.txt"
fi
if [ -z "${NOBENCH:-}" ]; then
  sel='^\| [0-9]|^sorted rays|^shadow pass|^vulkan, the whole frame|error'
  {
    for s in $scenes; do
      for round in $(seq "${ROUNDS:-2}"); do
        variants=${VARIANTS:-}
        if [ -z "$variants" ]; then
          for bits in ${SORTS:-0 32 24 16}; do variants="$variants gridrt:$bits"; done
        fi
        for v in $variants; do
          bin=${v%%:*} bits=${v##*:}
          exe=gridrt
          [ "$bin" != gridrt ] && exe=$E/$bin && chmod +x "$exe"
          echo "== bench $s $bin --sort-rays $bits (round $round)"
          timeout 120 "$exe" bench "$(scene_arg "$s")" --backend vulkan --traversal exact --vk-build compute --frames 30 \
            --warmup 5 --sort-rays "$bits" 2>&1 | grep -E "$sel" | cut -c1-300
        done
      done
    done
  } 2>&1 | tee "$out/ray-sort-bench.txt"
fi
