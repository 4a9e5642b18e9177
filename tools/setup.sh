#!/usr/bin/env bash
# setup.sh: install gridrt's dependencies (Debian 12 packages), configure and build.
#   bash tools/setup.sh [PRESET]      (default preset: release)
# Idempotent: packages already installed are not reinstalled, the build is incremental.
set -euo pipefail
cd "$(dirname "$0")/.."
preset=${1:-release}
pkgs=(build-essential cmake ninja-build pkg-config
      libglm-dev libembree-dev libgmp-dev zlib1g-dev libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers
      vulkan-tools glslang-tools spirv-tools catch2 libopenimageio-dev openimageio-tools
      libtinyobjloader-dev libtinygltf-dev nlohmann-json3-dev libcli11-dev libbenchmark-dev
      fonts-dejavu-core
      python3  # tools/random_scenes.py: the test of generated scenes
      clang-14 libclang-rt-14-dev
      chromium)  # chromium: the test that loads explain's HTML viewer in a headless browser
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  sudo=""; [ "$(id -u)" -eq 0 ] || sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
cmake --preset "$preset"
cmake --build --preset "$preset" -j "${GRIDRT_JOBS:-2}"
