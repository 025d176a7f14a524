#!/bin/sh
# Unpacks the real scanned meshes the scenes in scenes/real/ use into
# scenes/models/ (not committed: they are not ours). They come from
# Debian's libcgal-demo package: sudo apt-get install libcgal-demo
set -eu
data=/usr/share/doc/libcgal-dev/data.tar.gz
[ -f "$data" ] || { echo "no $data: install libcgal-demo (apt-get install libcgal-demo)" >&2; exit 1; }
dir=$(dirname "$0")/models
mkdir -p "$dir"
tar -xzf "$data" -C "$dir" --strip-components=2 \
    data/meshes/bunny00.off data/meshes/armadillo.off \
    data/meshes/refined_elephant.off data/meshes/ChineseDragon-10kv.off
ls "$dir"
