#!/usr/bin/env bash
# On the GPU machine, from the repo root: the device's ray tracing pipeline beside the grid
# (`gridrt bench --rtx`, docs/BENCHMARKS.md "The device's RT pipeline side by side") on the paper's
# three frames. Staged in $STAGE (default .gpu; the measured run used .gpu-rtx) by
# pack.sh with gridrt, optionally gridrt_rtx_tests (docs/VULKAN.md says how it is
# linked), and as extra files the three *.gridscene.gz, libVkLayer_khronos_validation.so and its
# JSON. Writes every log and JSON to $OUT/rtx-run.tgz.
#   1. validation layer on (480x270, both ways of ignoring the launch triangle): 0 messages?
#   2. the RT test (tests/test_vulkan_rtx.cpp), validation on
#   3. 1920x1080, 30 frames after 5: the defaults, --rtx-opaque, --traversal exact, --rtx-rebuild
STAGE=${STAGE:-.gpu}
OUT=${OUT:-/tmp/gridrt-out}
source $STAGE/env.sh
E=$STAGE/extra
(cd $E && gunzip -kf ./*.gz)
export LD_LIBRARY_PATH=$PWD/$E:$LD_LIBRARY_PATH
R=$(mktemp -d)
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv > $R/gpu.txt 2>&1
for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
  for a in "" "--rtx-opaque"; do
    GRIDRT_VALIDATION=1 VK_LAYER_PATH=$PWD/$E timeout 120 gridrt bench $E/$s.gridscene --backend vulkan --rtx $a \
      --width 480 --height 270 --frames 2 --warmup 1 --back-to-back 1 > $R/validated-$s$a.txt 2>&1
    echo "validated $s $a rc=$?"; grep -E "validation layer|error" $R/validated-$s$a.txt
  done
done
if command -v gridrt_rtx_tests > /dev/null; then
  VK_LAYER_PATH=$PWD/$E timeout 150 gridrt_rtx_tests "Vulkan RT side by side*" > $R/test.txt 2>&1
  echo "test rc=$?"; tail -3 $R/test.txt
fi
for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
  timeout 150 gridrt bench $E/$s.gridscene --backend vulkan --rtx --frames 30 --warmup 5 --json $R/$s.json > $R/$s.txt 2>&1
  echo "$s rc=$?"; grep -E "^\| (grid|rtx)|agree|error" $R/$s.txt
done
for v in "opaque:--rtx-opaque" "exact:--traversal exact" "rebuild:--rtx-rebuild"; do
  n=${v%%:*}; a=${v#*:}
  for s in sibenik-teapots sponza-teapots ons-reborn-teapot; do
    [ $n = rebuild ] && [ $s != sponza-teapots ] && continue
    timeout 120 gridrt bench $E/$s.gridscene --backend vulkan --rtx $a --frames 30 --warmup 5 --back-to-back 1 \
      --json $R/$s-$n.json > $R/$s-$n.txt 2>&1
    echo "$s $n rc=$?"; grep -E "^\| (grid|rtx)|agree:|error" $R/$s-$n.txt
  done
done
mkdir -p $OUT && tar czf $OUT/rtx-run.tgz -C $R .
