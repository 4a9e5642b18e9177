#!/usr/bin/env bash
# Scenes nobody tuned for (tools/random_scenes.py) through `gridrt diff`, the reference against the
# shaders bit for bit with the validation layer on, in both traversals with the GPU frame's passes,
# and `gridrt verify` of the exact traversal against Embree (VERIFY=0 leaves it out):
#   python3 tools/random_scenes.py DIR 40 1
#   GRIDRT=build/release/apps/gridrt bash tools/random_diff.sh DIR [WIDTH HEIGHT]
# On the GPU machine: tools/gpu/random.sh, on the scenes' caches.
# One line per run: the scene, the run, diff's AGREE/DIFFER line or verify's verdict; a summary last.
# Exit 1 if any run did not agree (or verify found a wrong answer); the scenes it names are rebuilt
# from their seeds alone. A diff lavapipe refuses because a ray would pass llvmpipe's loop limit
# (docs/VULKAN.md) is counted as refused, not as a disagreement (REFUSED_OK=0: as a failure, as
# the test suite runs it): run that scene on a GPU.
set -u
dir=$1
w=${2:-320}
h=${3:-180}
bin=${GRIDRT:-gridrt}
runs=0
bad=0
refused=0
verify=${VERIFY:-1}  # VERIFY=0: diff only (a build without Embree, such as the GPU machine's)
for s in "$dir"/rand-*; do
  # the scene files, or their caches (`gridrt convert`: what a build without OpenImageIO loads)
  case $s in *.json | *.gridscene) ;; *) continue ;; esac
  n=$(basename "${s%.*}")
  for args in "--traversal paper" "--traversal exact --vk-build compute"; do
    # shellcheck disable=SC2086
    line=$(timeout 300 "$bin" diff "$s" $args --gpu-frame --width "$w" --height "$h" --frames 3 2>&1 |
      grep -E '^(AGREE|DIFFER)|error|validation message' | head -2 | tr '\n' ' ')
    runs=$((runs + 1))
    case $line in
      AGREE*" 0 validation message(s) ") ;;
      # a documented refusal, not a disagreement: a ray past llvmpipe's loop limit (docs/VULKAN.md)
      *"llvmpipe (a CPU Vulkan driver) ends a shader's loops"*)
        refused=$((refused + 1))
        [ "${REFUSED_OK:-1}" = 1 ] || bad=$((bad + 1)) ;;
      *) bad=$((bad + 1)) ;;
    esac
    echo "$n | diff $args | ${line:-no verdict}"
  done
  if [ $verify = 1 ]; then
    line=$(timeout 300 "$bin" verify "$s" --traversal exact -n 200 2>&1 | grep -E '^verify: (OK|FAIL)|error' | head -2 | tr '\n' ' ')
    runs=$((runs + 1))
    case $line in "verify: OK"*) ;; *) bad=$((bad + 1)) ;; esac
    echo "$n | verify --traversal exact -n 200 | ${line:-no verdict}"
  fi
done
echo "random scenes: $runs runs, $bad without agreement, $refused refused by llvmpipe's loop limit"
[ $runs -gt 0 ] || { echo "random_diff.sh: no rand-*.json or rand-*.gridscene in $dir" >&2; exit 1; }
[ $bad = 0 ]
