#!/bin/bash
# Builds the libFuzzer targets (the fuzz preset: clang-14, ASan + UBSan) and runs each reader's
# target for SECONDS (default 10) on one core, seeded with tests/corpus and data/fixtures.
# New inputs go to build/fuzz/corpus/<kind>, crashes to build/fuzz/artifacts/: copy a crash
# into tests/fuzz/regressions/ (with the kind's extension) once it is fixed.
#   tools/fuzz.sh [SECONDS] [KIND...]      KIND: obj gltf glb json gridscene map
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-10}
shift || true
kinds=("$@")
[ ${#kinds[@]} -eq 0 ] && kinds=(obj gltf glb json gridscene map)
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz -j2
mkdir -p build/fuzz/artifacts
status=0
for k in "${kinds[@]}"; do
  seeds=tests/corpus/$k
  [ "$k" = glb ] && seeds=tests/corpus/gltf
  mkdir -p build/fuzz/corpus/$k tests/fuzz/seeds/$k
  echo "== fuzz_$k for $secs s"
  log=build/fuzz/fuzz_$k.log
  if ASAN_OPTIONS=detect_leaks=0:allocator_may_return_null=0 \
     build/fuzz/tests/fuzz/fuzz_$k -max_total_time="$secs" -timeout=30 -rss_limit_mb=2560 -max_len=262144 \
       -artifact_prefix=build/fuzz/artifacts/$k- -print_final_stats=1 \
       build/fuzz/corpus/$k $seeds tests/fuzz/seeds/$k data/fixtures >"$log" 2>&1; then
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb|Done" "$log" | tr '\n' ' '; echo
  else
    status=1
    grep -E -A30 "ERROR|SUMMARY|Test unit written" "$log" | head -60
  fi
done
exit $status
