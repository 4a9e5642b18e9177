#!/usr/bin/env bash
# The sparse offsets' load, on the GPU machine (docs/BENCHMARKS.md "Offsets of the occupied cells
# only"): the trace of three binaries in turns, each at its default grid, no RT side. Staged as
# tools/gpu/speed-and-trust.sh says, with gridrt-base (the baseline commit, dense offsets) and
# gridrt-A (sparse offsets always, the word read after the skip distance) beside this tree's
# gridrt; run there after `source .gpu/env.sh`. The frame row's fifth column is the trace (ms).
E=.gpu/extra; export VK_LAYER_PATH=$PWD/$E LD_LIBRARY_PATH=$PWD/$E:$LD_LIBRARY_PATH; chmod +x $E/gridrt-*
sel='^\| [0-9]|first build split|^grid memory|error'
for round in $(seq "${ROUNDS:-1}"); do
for s in sibenik-teapots ons-reborn-teapot builtin:atrium sponza-teapots "ons-reborn-teapot --resolution 243,243,97"; do
  # shellcheck disable=SC2086
  set -- $s; X=$E/$1.gridscene; [ "$1" = builtin:atrium ] && X=$1; shift
  for bin in $E/gridrt-base $E/gridrt-A gridrt; do
    echo "== round $round $s: $bin"
    timeout 60 "$bin" bench "$X" --backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5 "$@" 2>&1 | grep -E "$sel" | cut -c1-300
  done
done
done
