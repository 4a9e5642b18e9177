#!/usr/bin/env bash
# The shadow pass's cost (docs/BENCHMARKS.md, "Shadow rays"), on the GPU machine, from the repo
# root: each real scene's frame with --shadows on and off, the same command otherwise; `gridrt
# bench` prints the pass as its own phase ("shadow pass: ... rays + trace = ... ms", GPU timestamps)
# and the frame with it. Staging as for tools/gpu/frame-bench.sh (G=.gpu by default). Logs and JSON
# go to $OUT.
set -u
G=${G:-.gpu}
out=${OUT:-/tmp/gridrt-out}
mkdir -p "$out/json"
source "$G/env.sh"
(cd "$G/extra" && gunzip -kf ./*.gz)
L=$out/shadow-bench.log
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader >"$L"
B="--backend vulkan --vk-build compute --frames 30 --warmup 5 --back-to-back 1 --counter-frames 1"
for s in sponza-teapots sibenik-teapots ons-reborn-teapot; do
  X=$G/extra/$s.gridscene
  for mode in on off; do
    echo "=== $s --shadows $mode" >>"$L"
    timeout 120 gridrt bench "$X" $B --shadows "$mode" --json "$out/json/$s-shadows-$mode.json" 2>&1 |
      grep -v "gather buffer" >>"$L"
  done
  # The frame's own shadow rays and hits against the reference's, in bits
  echo "=== $s diff --gpu-frame" >>"$L"
  timeout 300 gridrt diff "$X" --gpu-frame --frames 1 --width 480 --height 270 2>&1 |
    grep -E "GPU frame|AGREE|DIFFER|differ" >>"$L"
done
tar czf "$out/json-shadows.tar.gz" -C "$out" json && rm -rf "$out/json"
grep -E "^=== |^shadow pass|^\| [0-9]|shadow rays" "$L"
