#!/usr/bin/env bash
# Bounce rays sorted before the trace (docs/BENCHMARKS.md "Bounce rays sorted before the trace"):
# on the GPU machine, per frame (the three frames and the built-in atrium), the glossy bounce rays
# of frame 0 as one fixed list (`gridrt bench --rays glossy-list`), traced in pixel rows as made
# (`--ray-order given`) and sorted by direction, then origin (`--ray-order sorted`), ROUNDS times in
# turns, then the frame's own trace of its rays in pixel tiles; per scene
#   gridrt bench X --backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5 ...
# Staged as tools/gpu/speed-and-trust.sh says (this tree's gpu build and the frames' .gridscene
# caches). There: bash tools/gpu/ray-order.sh (G=.gpu by default; SCENES, ORDERS="sorted given" to
# time the sorted list first, NOFRAME=1 without the frame's run); log in $OUT/ray-order.txt.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
keep='^(bench|\| vulkan|vulkan: per traced|machine)|error'
{
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader
  for s in ${SCENES:-sibenik-teapots sponza-teapots ons-reborn-teapot atrium}; do
    X=$E/$s.gridscene
    [ "$s" = atrium ] && X=builtin:atrium
    for round in $(seq "${ROUNDS:-2}"); do
      for order in ${ORDERS:-given sorted}; do
        echo "== $s: glossy-list, --ray-order $order (round $round)"
        timeout 300 gridrt bench "$X" --backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5 \
          --rays glossy-list --ray-order $order 2>&1 | grep -E "$keep"
      done
    done
    [ -n "${NOFRAME:-}" ] && continue
    echo "== $s: the frame's own trace (pixel tiles)"
    timeout 300 gridrt bench "$X" --backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5 2>&1 |
      grep -E "^(\| [0-9]|back to back|\| frame|\|---)" | head -8
  done
} 2>&1 | tee "$out/ray-order.txt"
