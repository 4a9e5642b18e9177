#!/usr/bin/env bash
# Meshes built to be hard (tools/hostile_meshes.py) on the GPU machine: `gridrt diff` (the
# reference against the shaders, bit for bit, validation on; both traversals, with the GPU frame's
# passes). Bit for bit there, the shaders inherit the reference's `gridrt verify` figures
# (docs/ACCURACY.md "Meshes built to be hard"; the gpu build has no Embree). Staged as tools/gpu/speed-and-trust.sh says, plus the
# meshes: python3 tools/hostile_meshes.py /tmp/hm; pack.sh ... -- /tmp/hm/*.obj
# There: bash tools/gpu/hostile.sh (G=.gpu by default); log in $OUT/hostile.txt.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
{
  nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
  for m in soup needles scalemix uvsphere coplanar lattice flat tjunction faraway slivers cone300 prisms; do
    for tr in exact paper; do
      echo "== diff $m $tr --gpu-frame 480x270, 2 frames"
      timeout 120 gridrt diff "$E/$m.obj" --traversal $tr --gpu-frame --width 480 --height 270 --frames 2 2>&1 |
        grep -E '^(AGREE|DIFFER)|error|validation' | tail -3
    done
  done
} 2>&1 | tee "$out/hostile.txt"
