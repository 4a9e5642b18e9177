#!/usr/bin/env bash
# tutorial.sh: make every figure of docs/TUTORIAL.md with the gridrt tool itself.
#   bash tools/tutorial.sh [OUT]      (default OUT: docs/img/tutorial)
# Environment: GRIDRT (the tool; default build/release/apps/gridrt), TUTORIAL_WIDTH and
# TUTORIAL_HEIGHT (the views' image size; default 320 x 180; the test runs it at 64 x 36),
# TUTORIAL_THREADS (default 2).
# Every command below is the one TUTORIAL.md quotes beside its figure.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-docs/img/tutorial}
g=${GRIDRT:-build/release/apps/gridrt}
w=${TUTORIAL_WIDTH:-320}
h=${TUTORIAL_HEIGHT:-180}
threads=${TUTORIAL_THREADS:-2}
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# The Cornell box on a small grid: 8 x 8 x 8 cells; "roomy" holds every reference, "tight" has 3
# slots per cell and saturates.
small="--resolution 8,8,8 --threads $threads"
roomy="$small --capacity 32"
tight="$small --capacity 3"
size="--width $w --height $h"
run() { echo "+ gridrt $*"; "$g" "$@" >/dev/null; }
slices() {  # slices NAME ARGS...: stats --slices into a folder of its own, kept as NAME.png
  local name=$1; shift
  mkdir -p "$tmp/$name"
  run stats "$@" --slices "$tmp/$name"
  mv "$tmp/$name/occupancy.png" "$out/$name.png"
}
# One camera ray drawn into the slices: pixel (250, 60) of 320 x 180, scaled to the image size
ray="$size --pixel $((w * 250 / 320)),$((h * 60 / 180)) --slice-axis y"

run render builtin:cornell $size --traversal exact -o "$out/00-cornell.png"
slices 01-build builtin:cornell $roomy
slices 02-saturation builtin:cornell $tight
slices 03a-ray-paper builtin:cornell $roomy $ray
slices 03b-ray-exact builtin:cornell $roomy $ray --traversal exact
run render builtin:cornell $size $roomy --view cells -o "$out/03-cells-paper.png"
run render builtin:cornell $size $roomy --view tests --elongation 0 -o "$out/04-tests-paper-elongation-0.png"
run render builtin:cornell $size $roomy --view tests -o "$out/05-tests-paper.png"
run render builtin:cornell $size $roomy --view cells --traversal exact -o "$out/06-cells-exact.png"
run render builtin:cornell $size $roomy --view tests --traversal exact -o "$out/07-tests-exact.png"
run render builtin:cornell $size $tight --view saturation -o "$out/08-saturation.png"
run render builtin:cornell $size $tight --view gap-fill -o "$out/09-gap-fill.png"
run render builtin:cornell $size $tight --view gap-fill --gap-fill off -o "$out/10-gap-fill-off.png"
run render builtin:cornell $size $tight --view spill --traversal exact -o "$out/11-spill.png"
slices 12-update-t0 builtin:atrium --resolution 16,8,16 --capacity 8 --threads "$threads" --slice-axis y --time 0
slices 13-update-t2 builtin:atrium --resolution 16,8,16 --capacity 8 --threads "$threads" --slice-axis y --time 2
run portal render builtin:level --width $((w * 2)) --height $w -o "$out/14-portal-level.png"
run portal render builtin:level --width $((w * 2)) --height $w --view divs -o "$out/15-portal-divs.png"
run portal render builtin:level --width $((w * 2)) --height $w --view dda -o "$out/16-portal-dda.png"
run portal render builtin:blocks --width $((w * 2)) --height $w -o "$out/17-portal-blocks.png"

n=0
for f in "$out"/*.png; do [ -s "$f" ] && n=$((n + 1)); done
[ "$n" -ge 19 ] || { echo "tutorial: only $n figures in $out" >&2; exit 1; }
echo "tutorial: $n figures in $out"
