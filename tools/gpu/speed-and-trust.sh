#!/usr/bin/env bash
# The mailbox, the faster static build and bit-exactness on the GPU machine (docs/BENCHMARKS.md
# "Mailbox and the static build's passes", docs/VULKAN.md "Bit for bit on NVIDIA"), from the repo
# root, after staging here:
#   cmake --preset gpu && cmake --build --preset gpu -j2 --target gridrt        (this tree)
#   the same in a worktree of the baseline commit, its binary copied as gridrt-base
#   gridrt convert data/scenes/X.json -o /tmp/gs/X.gridscene   (sibenik-teapots, sponza-teapots,
#                                                              ons-reborn-teapot, bunny)
#   ../shared/gpu/pack.sh build/gpu/apps/gridrt -- gridrt-base /tmp/gs/*.gridscene \
#     /usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
# There: PART=diff|bench|variants|build|gather|frame|stats|portal|untuned bash tools/gpu/speed-and-trust.sh (G=.gpu by default); logs in $OUT.
#   diff    gridrt diff (reference against the shaders, validation on) on the three frames: paper
#           traversal + raster build + the GPU frame's passes, exact + compute build + the GPU
#           frame, exact + raster build; portal diff bit for bit on the built-in level, its mip
#           levels and the instanced block level
#   variants every staged binary in turns (gridrt-base, gridrt-A, ..., this one) on the three
#           frames and the atrium beside the RT pipeline; the trace pipelines' driver statistics
#   bench   per scene (and the untuned bunny's primary rays and the atrium), in one run on the same
#           rays: the baseline binary and this one at their defaults, each beside the RT pipeline
#   gather  per scene (and the built-in atrium), the baseline binary (and gridrt-A, gridrt-V1, ...:
#           intermediate builds, when staged; none with NOBASE=1) and this one at its defaults, or with
#           each of VARIANTS' '|'-separated argument sets in turns, ROUNDS times: the frame's passes,
#           the gather's split, its work items and tile pairs, the shadow pass (PART=frame: the same)
#   build   the first static build (device timestamps), every staged binary in turns, 3 rounds; then
#           this binary's every pass (--build-passes)
#   stats   the driver's statistics of every compute pipeline of one frame per scene (registers, ...)
#   portal  tools/gpu/portal-bench.sh with INSTANCED_ONLY=1
#   untuned the bunny's primary rays, the built-in teapot and Cornell box, both binaries in turns
#           twice; the three frames' first build split (this binary)
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
[ -f "$E/gridrt-base" ] && chmod +x "$E/gridrt-base"
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader | tee "$out/device.txt"
scenes=(sibenik-teapots sponza-teapots ons-reborn-teapot)
keep='^(diff|frame|AGREE|DIFFER|spill|validation|  first|gridrt|portal diff|  hit records|  render|  agree)|error'
case ${PART:-diff} in
diff)
  {
    for s in "${scenes[@]}"; do
      X=$E/$s.gridscene
      echo "== diff $s paper, raster build, the GPU frame's passes"
      timeout 120 gridrt diff $X --traversal paper --vk-build raster --gpu-frame --width 480 --height 270 --frames 2 2>&1 |
        grep -E "$keep" | tail -6
      echo "== diff $s exact (compact layout, mailbox), compute build, the GPU frame's passes"
      timeout 120 gridrt diff $X --traversal exact --vk-build compute --gpu-frame --width 480 --height 270 --frames 2 2>&1 |
        grep -E "$keep" | tail -6
      echo "== diff $s exact, raster build, image layout"
      timeout 120 gridrt diff $X --traversal exact --vk-build raster --layout image --width 480 --height 270 --frames 2 2>&1 |
        grep -E "$keep" | tail -6
    done
    for w in builtin:level builtin:blocks "builtin:level --mip-levels 3"; do
      echo "== portal diff $w (bit for bit)"
      # shellcheck disable=SC2086
      timeout 120 gridrt portal diff $w --width 720 --height 360 2>&1 | grep -E "$keep" | tail -6
    done
  } 2>&1 | tee "$out/diff.txt"
  ;;
bench)
  sel='^\| (grid|rtx|vulkan|[0-9])|^agree|^grid memory|warm build split|^first build split|^update passes|^vulkan|error'
  {
    for s in "${scenes[@]}" bunny builtin:atrium; do
      X=$E/$s.gridscene
      R=--rtx
      [ "$s" = builtin:atrium ] && X=$s
      [ "$s" = bunny ] && R="--rays primary"  # no glossy material: its primary rays, without the RT side
      B="--backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5"
      for bin in "$E/gridrt-base" gridrt; do
        echo "== bench $s $R: $bin, defaults, beside the RT pipeline"
        # shellcheck disable=SC2086
        timeout 90 "$bin" bench "$X" $B $R 2>&1 | grep -E "$sel" | cut -c1-400
      done
    done
  } 2>&1 | tee "$out/bench.txt"
  ;;
bunny)
  # The untuned bunny's primary rays alone (trace(), not the frame's passes), both binaries
  {
    for bin in "$E/gridrt-base" gridrt; do
      echo "== bench bunny --rays primary: $bin, defaults"
      timeout 90 "$bin" bench $E/bunny.gridscene --backend vulkan --traversal exact --vk-build compute --rays primary \
        --frames 30 --warmup 5 2>&1 | grep -E '^\| (grid|vulkan|[0-9])|^vulkan|error' | cut -c1-400
    done
  } 2>&1 | tee "$out/bunny.txt"
  ;;
untuned)
  # Scenes nobody tuned for, the baseline binary and this one in turns, twice: the primary rays of
  # the bunny, the built-in teapot and the Cornell box (no glossy material: no bounce rays, and the
  # diffuse ones need Embree); then the three frames' first build split with this binary
  sel='^\| (grid|vulkan|[0-9])|^vulkan|^first build split|error'
  B="--backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5"
  {
    for s in bunny builtin:teapot builtin:cornell; do
      X=$E/$s.gridscene
      R="--rays primary"
      case $s in builtin:*) X=$s ;; esac
      for round in 1 2; do
        for bin in "$E/gridrt-base" gridrt; do
          echo "== bench $s $R (round $round): $bin, defaults"
          # shellcheck disable=SC2086
          timeout 90 "$bin" bench "$X" $B $R 2>&1 | grep -E "$sel" | cut -c1-300
        done
      done
    done
    for s in "${scenes[@]}"; do
      echo "== first build split $s: gridrt"
      timeout 90 gridrt bench $E/$s.gridscene --backend vulkan --traversal exact --vk-build compute --frames 2 \
        --warmup 1 2>&1 | grep -E '^first build split|^\| [0-9]|error' | head -3
    done
  } 2>&1 | tee "$out/untuned.txt"
  ;;
build)
  # The first static build (device timestamps), the baseline binary, any intermediate builds
  # (gridrt-A, ...) and this one in turns, three rounds: short runs (3 frames); then this one with
  # every pass of the static build and the skip field timed (--build-passes)
  sel='^first build split|^\| grid|error'
  B="--backend vulkan --traversal exact --vk-build compute --frames 3 --warmup 1"
  bins=("$E/gridrt-base")
  for f in "$E"/gridrt-[A-Z]*; do
    case $f in *.xz) continue ;; esac
    [ -f "$f" ] && chmod +x "$f" && bins+=("$f")
  done
  {
    for round in 1 2 3; do
      for s in "${scenes[@]}" builtin:atrium; do
        X=$E/$s.gridscene
        [ "$s" = builtin:atrium ] && X=$s
        for bin in "${bins[@]}" gridrt; do
          echo "== build $s (round $round): $bin"
          timeout 90 "$bin" bench "$X" $B 2>&1 | grep -E "$sel" | cut -c1-400
        done
      done
    done
    for s in "${scenes[@]}" builtin:atrium; do
      X=$E/$s.gridscene
      [ "$s" = builtin:atrium ] && X=$s
      echo "== build passes $s: gridrt --build-passes"
      timeout 90 gridrt bench "$X" $B --build-passes 2>&1 | grep -E "$sel" | cut -c1-400
    done
  } 2>&1 | tee "$out/build.txt"
  ;;
gather | frame)
  # The compute gather's screen box (common/shared/raster.h gather_box) against the baseline's:
  # per scene, the baseline binary and this one at their defaults, one after the other
  B="--backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5"
  sel='^\| [0-9]|^\| (grid|rtx)|^agree|^grid memory|^gather split|^gather passes|^update passes|^shadow pass|^back to back|error'
  {
    for s in "${scenes[@]}" builtin:atrium; do
      X=$E/$s.gridscene
      [ "$s" = builtin:atrium ] && X=$s
      bins=("$E/gridrt-base")
      for f in "$E"/gridrt-[A-Z]*; do  # intermediate builds, when staged (gridrt-A, gridrt-V1, ...)
        case $f in *.xz) continue ;; esac  # pack.sh's compressed copy, unpacked beside it
        [ -f "$f" ] && chmod +x "$f" && bins+=("$f")
      done
      [ -n "${NOBASE:-}" ] && bins=()
      for bin in "${bins[@]}"; do
        echo "== bench $s: $bin"
        timeout 90 "$bin" bench "$X" $B 2>&1 | grep -E "$sel" | cut -c1-400
      done
      # This binary with each of VARIANTS' '|'-separated argument sets (default: none), in turns
      IFS='|' read -r -a variants <<<"${VARIANTS:-}"
      [ ${#variants[@]} -eq 0 ] && variants=("")
      for round in $(seq "${ROUNDS:-1}"); do
        for v in "${variants[@]}"; do
          echo "== bench $s: gridrt $v (round $round)"
          # shellcheck disable=SC2086
          timeout 90 gridrt bench "$X" $B $v 2>&1 | grep -E "$sel" | cut -c1-400
        done
      done
    done
  } 2>&1 | tee "$out/${PART}.txt"
  ;;
variants)
  # Every staged binary (gridrt-base, the intermediate builds gridrt-A, gridrt-B, ..., this one)
  # in turns on the three frames and the atrium at their defaults beside the RT pipeline, then the
  # driver's statistics of each one's pipelines on Sibenik (registers of the trace)
  sel='^\| (grid|rtx)|^agreement|error'
  B="--backend vulkan --traversal exact --vk-build compute --frames 30 --warmup 5 --rtx"
  bins=("$E/gridrt-base")
  for f in "$E"/gridrt-[A-Z]*; do
    case $f in *.xz) continue ;; esac
    [ -f "$f" ] && chmod +x "$f" && bins+=("$f")
  done
  bins+=(gridrt)
  {
    for s in "${scenes[@]}" builtin:atrium; do
      X=$E/$s.gridscene
      [ "$s" = builtin:atrium ] && X=$s
      for bin in "${bins[@]}"; do
        echo "== variants $s: $bin"
        # shellcheck disable=SC2086
        timeout 90 "$bin" bench "$X" $B 2>&1 | grep -E "$sel" | cut -c1-400
      done
    done
    for bin in "${bins[@]}"; do
      echo "== pipeline statistics sibenik-teapots: $bin"
      GRIDRT_VK_PIPELINE_STATS=1 timeout 90 "$bin" bench $E/sibenik-teapots.gridscene --backend vulkan --traversal exact \
        --vk-build compute --frames 1 --warmup 0 2>&1 | grep -E '^pipeline statistics.*trace|error' | sort -u | cut -c1-300
    done
  } 2>&1 | tee "$out/variants.txt"
  ;;
stats)
  # The driver's statistics of every compute pipeline (GRIDRT_VK_PIPELINE_STATS=1: registers,
  # local memory, ...), the trace's included, from one short frame of each scene
  {
    for s in "${scenes[@]}"; do
      echo "== pipeline statistics $s"
      GRIDRT_VK_PIPELINE_STATS=1 timeout 90 gridrt bench $E/$s.gridscene --backend vulkan --traversal exact \
        --vk-build compute --frames 1 --warmup 0 2>&1 | grep -E '^pipeline statistics|error' | sort -u | cut -c1-600
    done
  } 2>&1 | tee "$out/stats.txt"
  ;;
portal)
  INSTANCED_ONLY=1 G=$G OUT=$out bash tools/gpu/portal-bench.sh > "$out/portal-stdout.txt" 2>&1
  echo "portal-bench exit $?" | tee -a "$out/portal-stdout.txt"
  ;;
esac
