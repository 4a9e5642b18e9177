#!/usr/bin/env bash
# The race mutants on the GPU machine (docs/VULKAN.md "Mutation testing"): the three mutants of
# tools/mutate/mutants.txt that lavapipe cannot tell apart (gather-atomicmin-plain, clear-barrier,
# build-no-coherent: llvmpipe runs their races in one order) judged by `gridrt diff` on NVIDIA,
# where warps run side by side. From the repo root, after staging here, per mutant ID:
#   apply the mutant to a copy of the tree (tools/mutate/mutate.py's rule), build the gpu preset's
#   gridrt, copy it as /tmp/gridrt-ID; then
#   ../shared/gpu/pack.sh build/gpu/apps/gridrt -- /tmp/gridrt-gather-atomicmin-plain \
#     /tmp/gridrt-clear-barrier /tmp/gridrt-build-no-coherent /tmp/gs/*.gridscene \
#     /usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
# There: bash tools/gpu/race-mutants.sh (G=.gpu by default); log $OUT/race.txt. A mutant is killed
# when a diff that reaches its code reports DIFFER (exit 3); each diff runs twice (races vary).
# The unmutated gridrt runs the same diffs once first, as the control: they must agree.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$out/device.txt"
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot)
# The diffs that reach each mutant's code: the compute gather (every frame's); the image layout's
# clear pass (an update: frames 2 and 3); the image layout's insertions (raster and compute builds)
declare -A modes=(
  [gather-atomicmin-plain]="--traversal exact --vk-build compute --gpu-frame --frames 2"
  [clear-barrier]="--traversal paper --vk-build compute --frames 3"
  [build-no-coherent]="--traversal exact --layout image --vk-build compute --frames 2"
)
run_diffs() {  # binary, mutant id, tries per scene
  local bin=$1 id=$2 tries=$3 killed=0
  for s in "${scenes[@]}"; do
    for rep in $(seq "$tries"); do
      # shellcheck disable=SC2086
      timeout 120 "$bin" diff $E/$s.gridscene ${modes[$id]} --width 320 --height 180 > "$out/run.txt" 2>&1
      local rc=$?
      echo "$id $s try $rep: exit $rc $(grep -E '^(AGREE|DIFFER)' "$out/run.txt" | cut -c1-160)"
      [ $rc -eq 3 ] && killed=1
      [ $rc -eq 3 ] && grep -E "differ|DIFFER" "$out/run.txt" | head -4
      [ $rc -ne 0 ] && [ $rc -ne 3 ] && { killed=2; tail -2 "$out/run.txt"; }
    done
  done
  local verdict="not told apart"
  [ $killed = 1 ] && verdict=killed
  [ $killed = 2 ] && verdict="error (see above)"
  echo "== $id with $(basename "$bin"): $verdict"
}
{
  for id in gather-atomicmin-plain clear-barrier build-no-coherent; do
    run_diffs "$(command -v gridrt)" "$id" 1 | sed 's/^/control: /'
    f=$E/gridrt-$id
    [ -f "$f" ] || { echo "$f missing"; continue; }
    chmod +x "$f"
    run_diffs "$f" "$id" 2
  done
} 2>&1 | tee "$out/race.txt"
