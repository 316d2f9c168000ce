#!/bin/bash
# The builds the Tileset tests share (tests/tools/test_tileset.cpp), made once
# per ctest run: the Monaco sample as one package, and as a 500 m tileset
# with --jobs 2 and with --jobs 1 --threads 1, and with overview levels 1
# and 2 (levels, for render --gpu-budget).
# Usage: tileset_fixture.sh DECALPREP SCENE WORKDIR
set -euo pipefail
tool=$1 scene=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
"$tool" build "$scene" -o "$work/single.decals" --report "$work/single.decals.json" -q
"$tool" build "$scene" -o "$work/tiles" --report "$work/tiles.json" -q --tile-size 500 --jobs 2
"$tool" build "$scene" -o "$work/tiles1" --report "$work/tiles1.json" -q --tile-size 500 \
  --jobs 1 --threads 1
"$tool" build "$scene" -o "$work/levels" -q --tile-size 500 --levels 2 --jobs 2
touch "$work/done"
