#!/bin/sh
# Renders the README's pictures of the implicit-part gallery: each part's discretised solid
# (voxel cubes at the part's voxel_size; the smooth tracing of the corner data is not built),
# lit, from the default camera, 480x360, into this folder.
# Usage: data/parts/render.sh [VOXFIELD]   (default: build/viewer/voxfield)
set -eu
here=$(dirname "$0")
voxfield=${1:-$here/../../build/viewer/voxfield}
for part in "$here"/*.sdf.json; do
    name=$(basename "$part" .sdf.json)
    "$voxfield" render "$part" -o "$here/$name.png" --width 480 --height 360 --shading lit
done
