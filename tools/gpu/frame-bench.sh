#!/usr/bin/env bash
# The frame benchmark of docs/BENCHMARKS.md ("The paper's frame on the H200"), on the GPU machine,
# from the repo root. Staging, here:
#   cmake --preset gpu-embree && cmake --build --preset gpu-embree -j2 --target gridrt
#   pack.sh build/gpu-embree/apps/gridrt [BASELINE_BINARY] -- /tmp/gs/*.gridscene.gz
#   xz -6 .gpu/lib/libembree3.so.3   # 42 MiB -> 9 MiB: pack.sh's 60 MiB check fails before this
# There: bash tools/gpu/frame-bench.sh (G=.gpu by default; BASELINE=name of a staged binary to
# time it beside gridrt). Logs and JSON go to $OUT.
set -u
G=${G:-.gpu}
out=${OUT:-/tmp/gridrt-out}
mkdir -p "$out/json"
source "$G/env.sh"
# libembree3 travels xz-compressed (xz, or Python's lzma where xz is missing)
(cd "$G/lib" && for f in *.xz; do
  [ -e "$f" ] || continue
  [ -f "${f%.xz}" ] || xz -dk "$f" 2>/dev/null ||
    python3 -c "import lzma,sys; open(sys.argv[1][:-3],'wb').write(lzma.open(sys.argv[1]).read())" "$f"
done)
(cd "$G/extra" && gunzip -kf ./*.gz)
L=$out/bench.log
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader >"$L"
B="--frames 30 --warmup 5 --back-to-back 1"
run() { local name=$1; shift; echo "=== $name" >>"$L"; timeout 120 "$@" 2>&1 | grep -v "gather buffer" >>"$L"; }
for s in sponza-teapots sibenik-teapots ons-reborn-teapot; do
  X=$G/extra/$s.gridscene
  if [ -n "${BASELINE:-}" ]; then
    run "$s $BASELINE raster build" "$BASELINE" bench "$X" --backend vulkan $B --json "$out/json/$s-base-raster.json"
    run "$s $BASELINE compute build" "$BASELINE" bench "$X" --backend vulkan --vk-build compute $B --json "$out/json/$s-base-compute.json"
  fi
  run "$s raster build (defaults), embree" gridrt bench "$X" --backend vulkan,embree $B --json "$out/json/$s-raster.json"
  run "$s compute build" gridrt bench "$X" --backend vulkan --vk-build compute $B --json "$out/json/$s-compute.json"
  run "$s compute build, raster gather" gridrt bench "$X" --backend vulkan --vk-build compute --gather raster $B \
    --counter-frames 1 --json "$out/json/$s-compute-rastergather.json"
  run "$s compute build, compacted trace" gridrt bench "$X" --backend vulkan --vk-build compute --compact-rays $B \
    --counter-frames 1 --json "$out/json/$s-compute-compact.json"
done
tar czf "$out/json.tar.gz" -C "$out" json && rm -rf "$out/json"
cat "$L"
