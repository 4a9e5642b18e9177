#!/usr/bin/env bash
# The tail pass's budget on the GPU machine (docs/BENCHMARKS.md, "The tail pass"), from the repo
# root after staging as tools/gpu/speed-and-trust.sh says (this tree's gridrt and the scenes):
#   PART=sweep  per scene (the three frames and the built-in atrium), the frame at each budget in
#               BUDGETS (0: one pass), in turns, then (unless RTX=0) the RT pipeline beside budget 0
#               and BEST
#   PART=diff   gridrt diff --gpu-frame, the exact traversal and compute build, at BEST (and at a
#               budget of 1: nearly every ray through the second pass) on the three frames
set -u
G=${G:-.gpu}
out=${OUT:-/tmp/gridrt-out}
mkdir -p "$out"
source "$G/env.sh"
E=$G/extra
export VK_LAYER_PATH=$PWD/$E LD_LIBRARY_PATH=$PWD/$E:$LD_LIBRARY_PATH
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot builtin:atrium)
BUDGETS=${BUDGETS:-0 32 64 96 128 192}
BEST=${BEST:-64}
B="--backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5"
sel='^\| [0-9]|^tail pass|^shadow pass|^back to back|^\| (grid|rtx)|^agreement|error'
case ${PART:-sweep} in
sweep)
  {
    for s in "${scenes[@]}"; do
      X=$E/$s.gridscene
      [ "$s" = builtin:atrium ] && X=$s
      for b in $BUDGETS; do
        echo "== tail $s: --trace-budget $b"
        # shellcheck disable=SC2086
        timeout 60 gridrt bench "$X" $B --trace-budget $b 2>&1 | grep -E "$sel" | cut -c1-300
      done
    done
    for s in "${scenes[@]}"; do
      [ "${RTX:-1}" = 0 ] && break
      X=$E/$s.gridscene
      [ "$s" = builtin:atrium ] && X=$s
      for b in 0 $BEST; do
        echo "== tail $s: --trace-budget $b beside the RT pipeline"
        # shellcheck disable=SC2086
        timeout 60 gridrt bench "$X" $B --rtx --trace-budget $b 2>&1 | grep -E "$sel" | cut -c1-300
      done
    done
  } 2>&1 | tee "$out/tail-sweep.txt"
  ;;
diff)
  keep='^(frame|AGREE|DIFFER|validation|  first|gridrt)|error'
  {
    for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
      for b in $BEST 1; do
        echo "== diff $s exact, compute build, the GPU frame's passes, --trace-budget $b"
        timeout 150 gridrt diff $E/$s.gridscene --traversal exact --vk-build compute --gpu-frame --width 480 \
          --height 270 --frames 2 --trace-budget $b 2>&1 | grep -E "$keep" | tail -6
      done
    done
  } 2>&1 | tee "$out/tail-diff.txt"
  ;;
esac
