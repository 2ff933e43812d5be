#!/bin/sh
# Packs a voxfield binary (or any program built here) with the shared libraries it needs, for a
# machine without this project's Debian packages (a GPU host with only its driver):
#   bench/bundle.sh build/viewer/voxfield DIR [NAME]
# gives DIR/bin/NAME.gz (default NAME: the binary's name), DIR/lib/ (every library ldd lists,
# less the C library and loader, which the host has, plus ocl-icd's libOpenCL.so.1) and
# DIR/commit_NAME. There: gunzip DIR/bin/NAME.gz, export LD_LIBRARY_PATH=DIR/lib, and register
# the host's OpenCL driver with ocl-icd (for NVIDIA: echo libnvidia-opencl.so.1 >
# /etc/OpenCL/vendors/nvidia.icd). bench/README.md, "Running on a GPU host".
set -eu
if [ $# -lt 2 ]; then
    echo "usage: bench/bundle.sh BINARY DIR [NAME]" >&2
    exit 2
fi
bin=$1
dst=$2
name=${3:-$(basename "$bin")}
[ -x "$bin" ] || { echo "bundle.sh: $bin is not an executable" >&2; exit 2; }
mkdir -p "$dst/bin" "$dst/lib"
gzip -c "$bin" > "$dst/bin/$name.gz"
ldd "$bin" | awk '/=> \//{print $3}' | while read -r lib; do
    case $(basename "$lib") in
        libc.so.*|libm.so.*|libpthread.so.*|libdl.so.*|librt.so.*|ld-linux*) ;;
        *) cp -L "$lib" "$dst/lib/" ;;
    esac
done
for lib in /usr/lib/x86_64-linux-gnu/libOpenCL.so.1; do
    [ -e "$lib" ] && cp -L "$lib" "$dst/lib/"
done
git -C "$(dirname "$bin")" rev-parse HEAD > "$dst/commit_$name" 2>/dev/null || true
du -sh "$dst"
