#!/bin/sh
# Renders the README's screenshots: every bundled model (data/vox, CC BY 4.0, credits in
# data/vox/ATTRIBUTION.md) with lit shading (sun shadows, ambient occlusion, sky) from the
# default camera, 800x600, into this folder.
# Usage: viewer/screenshots/render.sh [VOXFIELD]   (default: build/viewer/voxfield)
set -eu
here=$(dirname "$0")
root=$here/../..
voxfield=${1:-$root/build/viewer/voxfield}
for model in "$root"/data/vox/*.vox; do
    name=$(basename "$model" .vox)
    "$voxfield" render "$model" -o "$here/$name.png" --width 800 --height 600 --shading lit
done
