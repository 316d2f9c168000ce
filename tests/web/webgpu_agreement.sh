#!/bin/sh
# webgpu_agreement.sh — the WebGPU renderer (web/src/render/) against
# decalprep render: top-down decal layers against `render --cpu` at 4 m and
# 0.5 m pixels (Monaco, and Liechtenstein with casing and dashes), and an
# oblique view (pitch 45°) over flat ground and over a tilted-plane DEM
# against `render --cpu` (decals) and `render` GL (final frame).
#   tests/web/webgpu_agreement.sh [DECALPREP] [WORKDIR]
# Needs headless Chromium (/usr/bin/chromium), node, gdal_translate, and
# `npm ci` in web/. Exits non-zero when a comparison is below 99.9%.
set -eu
REPO=$(cd "$(dirname "$0")/../.." && pwd)
D=${1:-$REPO/build/release/tools/decalprep/decalprep}
W=${2:-$(mktemp -d)}
LI=/work/shared/data/liechtenstein/liechtenstein-2013-08-03.osm.pbf
H="node $REPO/tests/web/webgpu_harness.mjs"
C="node $REPO/tests/web/webgpu_compare.mjs"
S=480x270
[ -f "$W/monaco.decals" ] || "$D" build "$REPO/samples/monaco/scene.toml" -o "$W/monaco.decals" >/dev/null
[ -f "$W/li.decals" ] || [ ! -f "$LI" ] || "$D" build "$REPO/tests/web/webgpu_liechtenstein.toml" -o "$W/li.decals" >/dev/null
status=0
topdown() {  # package, name, extent (relative = absolute: both frames have origin 0, 0)
  "$D" render "$W/$1.decals" --cpu --only polygons,lines --flat --extent="$3" --size $S -o "$W/$2_cpu.png" --decals "$W/$2_cpu_decals.png"
  $H --pkg "$W/$1.decals" --size $S --extent "$3" --out "$W/$2_gpu"
  printf '%s decals vs cpu: ' "$2"; $C "$W/$2_cpu_decals.png" "$W/$2_gpu_decals.png" || status=1
}
topdown monaco m4 -400,-300,1520,780
topdown monaco m05 300,0,540,135
if [ -f "$W/li.decals" ]; then
  topdown li l4 -3400,-1900,-1480,-820
  topdown li l05 -2740,-1350,-2500,-1215
fi
# Oblique views: render's --eye/--target camera (render_request.cpp: near =
# max(0.1, dist / 1000), depth range 4 dist, up z).
node -e '
const [eye, target, out] = [process.argv[1], process.argv[2], process.argv[3]];
const e = eye.split(",").map(Number), t = target.split(",").map(Number);
const dist = Math.hypot(e[0] - t[0], e[1] - t[1], e[2] - t[2]);
require("fs").writeFileSync(out, JSON.stringify({projection: "perspective", eye: e, target: t, up: [0, 0, 1],
  fovYDeg: 45, orthoW: 0, orthoH: 0, near: Math.max(0.1, dist * 1e-3), depthRange: 4 * dist, topdownExtent: null}));
' 400,-400,500 400,100,0 "$W/cam_flat.json"
node -e '
const [eye, target, out] = [process.argv[1], process.argv[2], process.argv[3]];
const e = eye.split(",").map(Number), t = target.split(",").map(Number);
const dist = Math.hypot(e[0] - t[0], e[1] - t[1], e[2] - t[2]);
require("fs").writeFileSync(out, JSON.stringify({projection: "perspective", eye: e, target: t, up: [0, 0, 1],
  fovYDeg: 45, orthoW: 0, orthoH: 0, near: Math.max(0.1, dist * 1e-3), depthRange: 4 * dist, topdownExtent: null}));
' 400,-400,690 400,100,190 "$W/cam_plane.json"
# The tilted plane z = 100 + 0.2 x + 0.1 y: any mesh of it is the same
# surface, so the Terrain here and render's DEM mesh agree exactly.
node -e '
const fs = require("fs"), w = process.argv[1], f = (x, y) => 100 + 0.2 * x + 0.1 * y;
const cell = 30, x0 = -1800, y0 = -2500, n = 140;
let asc = `ncols ${n}\nnrows ${n}\nxllcorner ${x0}\nyllcorner ${y0}\ncellsize ${cell}\n`;
for (let r = 0; r < n; ++r) {
  const yc = y0 + (n - 1 - r + 0.5) * cell, row = [];
  for (let c = 0; c < n; ++c) row.push(f(x0 + (c + 0.5) * cell, yc).toFixed(6));
  asc += row.join(" ") + "\n";
}
fs.writeFileSync(w + "/plane.asc", asc);
const tx = -1785, ty = -2485, m = 139, z = [];
for (let j = 0; j < m; ++j) for (let i = 0; i < m; ++i) z.push(f(tx + 30 * i, ty + 30 * j));
fs.writeFileSync(w + "/plane_terrain.json", JSON.stringify({x0: tx, y0: ty, dx: 30, dy: 30, nx: m, ny: m, z,
  zmin: Math.min(...z), zmax: Math.max(...z)}));
' "$W"
"$D" info "$W/monaco.decals" --json 2>/dev/null | node -e 'let s="";process.stdin.on("data",c=>s+=c).on("end",()=>{const j=JSON.parse(s);const m=j.metadata??j;process.stdout.write(m.crs_wkt)})' > "$W/plane.prj" || true
gdal_translate -q -a_srs "$W/plane.prj" -ot Float64 "$W/plane.asc" "$W/plane.tif"
oblique() {  # name, camera, eye, target, render terrain option, harness terrain option
  "$D" render "$W/monaco.decals" --cpu --only polygons,lines $5 --eye "$3" --target "$4" --size $S -o "$W/$1_cpu.png" --decals "$W/$1_cpu_decals.png"
  "$D" render "$W/monaco.decals" --aa none --only polygons,lines $5 --eye "$3" --target "$4" --size $S -o "$W/$1_gl.png" --decals "$W/$1_gl_decals.png"
  $H --pkg "$W/monaco.decals" --size $S --camera "$W/$2" $6 --out "$W/$1_gpu"
  printf '%s decals vs cpu: ' "$1"; $C "$W/$1_cpu_decals.png" "$W/$1_gpu_decals.png" || status=1
  printf '%s frame vs gl: ' "$1"; $C "$W/$1_gl.png" "$W/$1_gpu_rgba.png" || status=1
}
oblique mo_flat cam_flat.json 400,-400,500 400,100,0 --flat ""
oblique mo_plane cam_plane.json 400,-400,690 400,100,190 "--dem $W/plane.tif" "--terrain $W/plane_terrain.json"
exit $status
