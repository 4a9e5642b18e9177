#!/usr/bin/env bash
# Scenes nobody tuned for (tools/random_scenes.py) through `gridrt diff` on the GPU machine: the
# reference against the shaders, bit for bit, validation on, both traversals with the GPU frame's
# passes (tools/random_diff.sh; the gpu build has no Embree, so no verify). Staged as
# tools/gpu/speed-and-trust.sh says, plus the scenes' caches (the gpu build reads no texture file):
#   python3 tools/random_scenes.py /tmp/rs 40 1
#   mkdir /tmp/rsg; for s in /tmp/rs/rand-*.json; do gridrt convert $s -o /tmp/rsg/$(basename $s .json).gridscene; done
#   pack.sh ... -- /tmp/rsg     (staged as .gpu/extra/rsg; RS=rs for a folder of scene files)
# There: bash tools/gpu/random.sh (G=.gpu by default); log in $OUT/random.txt.
set -u
source "$(dirname "${BASH_SOURCE[0]}")/staged.sh"  # G, E, out, env.sh, the validation layer
{
  nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
  VERIFY=0 GRIDRT=gridrt bash tools/random_diff.sh "$E/${RS:-rsg}" "${WIDTH:-480}" "${HEIGHT:-270}"
} 2>&1 | tee "$out/random.txt"
