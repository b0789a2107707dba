#!/usr/bin/env bash
# Installs the Debian 12 packages lightprobe needs (only what is missing).
# Works as root without sudo, and with sudo otherwise.
set -euo pipefail
PACKAGES=(
  build-essential cmake pkg-config ccache git
  libembree-dev libtbb-dev libeigen3-dev
  libopencv-dev libopencv-contrib-dev
  libpcl-dev
  libopenni2-dev openni2-utils libusb-1.0-0-dev
  libglfw3-dev libimgui-dev libglm-dev libgl-dev libgl1-mesa-dri mesa-utils xvfb xauth
  libgtest-dev libgmock-dev libbenchmark-dev
  nlohmann-json3-dev libcli11-dev
  clang libclang-rt-14-dev
  blender python3-numpy
)
missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi
if [ "$(id -u)" -eq 0 ]; then SUDO=(); elif command -v sudo >/dev/null; then SUDO=(sudo); else
  echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -q
"${SUDO[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
