#!/bin/sh
# Renders the README's pictures of the implicit-part gallery: each part discretised at its
# voxel_size and traced on the trilinear interpolant of its crossed voxels' corners, lit, from
# the default camera, 480x360, into this folder.
# Usage: data/parts/render.sh [VOXFIELD]   (default: build/viewer/voxfield)
set -eu
here=$(dirname "$0")
voxfield=${1:-$here/../../build/viewer/voxfield}
for part in "$here"/*.sdf.json; do
    name=$(basename "$part" .sdf.json)
    "$voxfield" render "$part" -o "$here/$name.png" --width 480 --height 360 --shading lit
done
