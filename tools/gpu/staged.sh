# tools/gpu/staged.sh: the set-up every GPU machine script (tools/gpu/*.sh) starts with, sourced
# from the repository root after `set -u`:
#   G    the staging folder pack.sh made (.gpu unless G says otherwise); its env.sh is sourced
#        (gridrt on PATH, the staged files unpacked)
#   E    its extra files ($G/extra: scenes, baseline binaries, the validation layer)
#   out  where results go ($OUT, else /tmp/gridrt-out), created
# and the validation layer staged in $E on the Vulkan loader's and the linker's paths (a run asks
# for it with gridrt diff, or GRIDRT_VALIDATION=1).
G=${G:-.gpu}
out=${OUT:-/tmp/gridrt-out}
mkdir -p "$out"
# shellcheck disable=SC1091
source "$G/env.sh"
E=$G/extra
export VK_LAYER_PATH=$PWD/$E LD_LIBRARY_PATH=$PWD/$E:$LD_LIBRARY_PATH
