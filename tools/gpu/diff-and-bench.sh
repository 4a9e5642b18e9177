#!/usr/bin/env bash
# The GPU machine's full run (docs/BENCHMARKS.md, docs/VULKAN.md), from the repo root, after
# staging here:
#   cmake --preset gpu-embree && cmake --build --preset gpu-embree -j2 --target gridrt
#   pack.sh build/gpu-embree/apps/gridrt -- /tmp/gs/*.gridscene.gz \
#       /usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so \
#       /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
#   xz -6 .gpu/lib/libembree3.so.3 .gpu/extra/libVkLayer_khronos_validation.so
# (/tmp/gs/X.gridscene.gz: `gridrt convert data/scenes/X.json -o X.gridscene`, gzip). There:
#   PART=diff  bash tools/gpu/diff-and-bench.sh   # the reference against the shaders, bit for bit
#   PART=bench bash tools/gpu/diff-and-bench.sh   # the frame, Embree and the RT pipeline side by side
# G=.gpu by default. Logs and JSON go to $OUT.
set -u
G=${G:-.gpu}
out=${OUT:-/tmp/gridrt-out}
mkdir -p "$out/json"
source "$G/env.sh"
# libembree3 and the validation layer travel xz-compressed (xz, or Python's lzma where xz is missing)
for d in "$G/lib" "$G/extra"; do
  (cd "$d" && for f in *.xz; do
    [ -e "$f" ] || continue
    [ -f "${f%.xz}" ] || xz -dk "$f" 2>/dev/null ||
      python3 -c "import lzma,sys; open(sys.argv[1][:-3],'wb').write(lzma.open(sys.argv[1]).read())" "$f"
  done)
done
(cd "$G/extra" && gunzip -kf ./*.gz)
E=$G/extra
export LD_LIBRARY_PATH=$PWD/$E:$LD_LIBRARY_PATH  # the validation layer, for GRIDRT_VALIDATION=1 runs
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot)
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
case ${PART:-all} in
diff | all)
  {
    for s in "${scenes[@]}"; do
      echo "== diff $s paper sorted, the GPU frame's passes too (bit for bit)"
      timeout 200 gridrt diff $E/$s.gridscene --traversal paper --gpu-frame --width 480 --height 270 --frames 3 2>&1 |
        grep -E "^(diff|frame|AGREE|DIFFER|  first)" | tail -12
      echo "== diff $s exact sorted (spill list on)"
      timeout 200 gridrt diff $E/$s.gridscene --traversal exact --width 480 --height 270 --frames 3 2>&1 |
        grep -E "^(diff|frame|AGREE|DIFFER|spill|  first)" | tail -12
    done
    echo "== diff sibenik exact first-empty, compute build (spill on)"
    timeout 200 gridrt diff $E/sibenik-teapots.gridscene --traversal exact --insertion first-empty --layout image --vk-build compute \
      --width 480 --height 270 --frames 3 2>&1 | grep -E "^(diff|frame|AGREE|DIFFER|spill)" | tail -12
  } 2>&1 | tee "$out/diff.txt"
  ;;&
bench | all)
  B="--frames 30 --warmup 5 --back-to-back 1"
  {
    for s in "${scenes[@]}"; do
      X=$E/$s.gridscene
      echo "== validation layer on: $s, paper and exact, RT pipeline too (480x270)"
      for t in paper exact; do
        GRIDRT_VALIDATION=1 VK_LAYER_PATH=$PWD/$E timeout 120 gridrt bench $X --backend vulkan --rtx --traversal $t \
          --width 480 --height 270 --frames 2 --warmup 1 2>&1 | grep -E "validation layer|rror" | head -5
      done
      echo "== bench $s: paper traversal, raster build (the paper's), Embree and the RT pipeline beside"
      timeout 150 gridrt bench $X --backend vulkan,embree --rtx $B --json "$out/json/$s-paper.json" 2>&1 |
        grep -v "gather buffer"
      echo "== bench $s: exact traversal (spill), compute build, RT pipeline beside"
      timeout 150 gridrt bench $X --backend vulkan --traversal exact --vk-build compute --rtx $B \
        --json "$out/json/$s-exact.json" 2>&1 | grep -v "gather buffer"
      echo "== bench $s: paper traversal, compute build"
      timeout 150 gridrt bench $X --backend vulkan --vk-build compute $B --json "$out/json/$s-paper-compute.json" 2>&1 |
        grep -v "gather buffer"
    done
  } 2>&1 | tee "$out/bench.txt"
  tar czf "$out/json.tar.gz" -C "$out" json && rm -rf "$out/json"
  ;;
esac
