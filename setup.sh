#!/bin/sh
# Installs the Debian packages voxfield needs (only those missing), then configures and
# builds it (Release) in ./build. Idempotent: with nothing missing and nothing changed it
# only re-checks and returns in seconds. Run as root on Debian 12 (or with sudo available).
set -eu
cd "$(dirname "$0")"

packages="cmake g++ make git ocl-icd-opencl-dev opencl-c-headers opencl-clhpp-headers
pocl-opencl-icd libcli11-dev nlohmann-json3-dev libgtest-dev
libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers glslang-tools libstb-dev
pkg-config libglfw3-dev libimgui-dev xvfb xauth
python3-dev pybind11-dev python3-pybind11 python3-numpy python3-scipy python3-pytest
libopenvdb-dev python3-openvdb python3-dask python3-distributed python3-zarr
python3-skbuild python3-build python3-pip python3-venv python3-wheel python3-setuptools"

missing=""
for p in $packages; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing="$missing $p"
    fi
done
if [ -n "$missing" ]; then
    echo "setup: installing:$missing"
    sudo=""
    if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends $missing
fi

if [ ! -f build/CMakeCache.txt ]; then
    cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
fi
cmake --build build -j "$(nproc)"
