#!/usr/bin/env bash
# Installs the Debian packages terravt needs, only when some are missing. Safe to re-run.
set -euo pipefail

packages=(
  build-essential cmake pkg-config git
  libvulkan-dev vulkan-validationlayers mesa-vulkan-drivers glslang-tools
  libglm-dev libopenimageio-dev libopencv-imgproc-dev libzstd-dev zstd
  nlohmann-json3-dev libcli11-dev libgtest-dev libxxhash-dev
  clang libclang-rt-14-dev
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "setup: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
