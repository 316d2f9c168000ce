#!/usr/bin/env bash
# bench/device_frames.sh — the renderer's frame times on a GPU machine that
# has the driver but none of the build's packages (bench/REPORT.md "GPU frame
# times"). It runs bench/methods.py (decal, volume, texture at 640x360 and
# 1920x1080, misclassified pixels against the CPU evaluator) and
# bench/lod_gpu.py at 1920x1080 with a decalprep built here.
#
#   bench/device_frames.sh CARRY OUT
#
# CARRY holds what the machine lacks, made on the build machine:
#   devlibs.tar.xz   every shared library `ldd decalprep` lists but the C and
#                    C++ runtimes (GDAL, GEOS, PROJ, oneTBB, zstd, the GL
#                    dispatch libraries of libglvnd, ...);
#   share.tar.xz     /usr/share/proj/proj.db and /usr/share/gdal;
#   build/tools/decalprep/decalprep, bin/ogr2ogr (bench/methods.py converts
#                    the synthetic GeoJSON with it);
#   data/*.osm.pbf   the Liechtenstein extract bench/scenes/liechtenstein.toml
#                    names (copied to that relative path).
# The NVIDIA driver's EGL library is found through its glvnd vendor file.
# Writes OUT/methods.csv, OUT/lod_gpu.csv and OUT/log.txt.
set -uo pipefail
CARRY=$(cd "$1" && pwd)
OUT=$2
ROOT=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p /opt/decalprep "$OUT"
tar -xJf "$CARRY/devlibs.tar.xz" -C /opt/decalprep
tar -xJf "$CARRY/share.tar.xz" -C /opt/decalprep
export LD_LIBRARY_PATH=/opt/decalprep:/usr/local/nvidia/lib64:/usr/local/nvidia/lib:${LD_LIBRARY_PATH:-}
export PROJ_DATA=/opt/decalprep/proj GDAL_DATA=/opt/decalprep/gdal
vendor=$(ls /usr/local/nvidia/share/glvnd/egl_vendor.d/*nvidia*.json /usr/share/glvnd/egl_vendor.d/*nvidia*.json 2>/dev/null | head -1)
[ -n "$vendor" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$vendor
export PATH=$CARRY/bin:$PATH PYTHONUNBUFFERED=1
mkdir -p "$ROOT/../shared/data/liechtenstein" && cp "$CARRY"/data/*.pbf "$ROOT/../shared/data/liechtenstein/"
BUILD=$CARRY/build
{
  nvidia-smi -L
  echo "egl vendor file: ${vendor:-none}"
  "$BUILD/tools/decalprep/decalprep" build "$ROOT/samples/monaco/scene.toml" -o /tmp/monaco.decals -q &&
    "$BUILD/tools/decalprep/decalprep" render /tmp/monaco.decals -o "$OUT/monaco_1080.png" \
      --size 1920x1080 --stats --frames 5
  python3 "$ROOT/bench/methods.py" --datasets monaco,liechtenstein,syn1e5,syn1e6 --frames 5 \
    --build-dir "$BUILD" --out "$OUT" --work /tmp/methods --report-md /tmp/REPORT.md
  python3 "$ROOT/bench/lod_gpu.py" --size 1920x1080 --frames 5 --build-dir "$BUILD" \
    --work /tmp/lod_gpu --out "$OUT"
} 2>&1 | tee "$OUT/log.txt"
