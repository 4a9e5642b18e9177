#!/bin/bash
# Builds the libFuzzer targets (the fuzz preset: clang-14, ASan + UBSan) and runs each reader's
# target on one core, seeded with tests/corpus, tests/fuzz/seeds and data/fixtures.
#   tools/fuzz.sh [SECONDS] [KIND...]       a campaign: SECONDS (default 10) per target, a random
#                                           seed; new inputs go to build/fuzz/corpus/<kind>
#   tools/fuzz.sh --runs N [KIND...]        a reproducible run (the suite's): libFuzzer seed 1,
#                                           N inputs per target, a fresh corpus, nothing kept
# KIND: obj gltf glb json gridscene map. Crashes go to build/fuzz/artifacts/: copy one into
# tests/fuzz/regressions/ (with the kind's extension) once it is fixed.
set -euo pipefail
cd "$(dirname "$0")/.."
limit=()
fixed=0
if [ "${1:-}" = "--runs" ]; then
  limit=(-seed=1 -runs="$2")
  fixed=1
  shift 2
else
  limit=(-max_total_time="${1:-10}")
  shift || true
fi
kinds=("$@")
[ ${#kinds[@]} -eq 0 ] && kinds=(obj gltf glb json gridscene map)
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz -j2
mkdir -p build/fuzz/artifacts
status=0
for k in "${kinds[@]}"; do
  seeds=tests/corpus/$k
  [ "$k" = glb ] && seeds=tests/corpus/gltf
  corpus=build/fuzz/corpus/$k
  if [ $fixed = 1 ]; then corpus=$(mktemp -d); fi
  mkdir -p "$corpus" tests/fuzz/seeds/$k
  echo "== fuzz_$k: ${limit[*]}"
  log=build/fuzz/fuzz_$k.log
  if ASAN_OPTIONS=detect_leaks=0:allocator_may_return_null=0 \
     build/fuzz/tests/fuzz/fuzz_$k "${limit[@]}" -timeout=30 -rss_limit_mb=2560 -max_len=262144 \
       -artifact_prefix=build/fuzz/artifacts/$k- -print_final_stats=1 \
       "$corpus" $seeds tests/fuzz/seeds/$k data/fixtures >"$log" 2>&1; then
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb|Done" "$log" | tr '\n' ' '; echo
  else
    status=1
    grep -E -B3 -A30 "ERROR|SUMMARY|Test unit written" "$log" | head -80
  fi
  if [ $fixed = 1 ]; then rm -rf "$corpus"; fi
done
exit $status
