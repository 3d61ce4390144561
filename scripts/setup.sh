#!/usr/bin/env bash
# Sourced by demo.sh and test.sh: installs missing Debian packages, then configures and builds Release into build/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

PACKAGES=(cmake g++ make pkg-config
  libglfw3-dev libglm-dev libopenimageio-dev openimageio-tools
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev
  libgeographiclib-dev libgdal-dev libtiff-dev libdeflate-dev libzstd-dev libjpeg-dev libpng-dev
  libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri libepoxy-dev
  libgtest-dev libbenchmark-dev libcli11-dev nlohmann-json3-dev libstb-dev libimgui-dev libcitygml-dev libtinyobjloader-dev
  xvfb xauth)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "Installing ${#missing[@]} missing packages: ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

WERROR=OFF
[ -n "${CI:-}" ] && WERROR=ON
JOBS="$(nproc 2>/dev/null || echo 2)"
cmake -S "$ROOT" -B "$ROOT/build" -DCMAKE_BUILD_TYPE=Release -DSEASONVIEW_WERROR="$WERROR" >/dev/null
cmake --build "$ROOT/build" -j "$JOBS"
