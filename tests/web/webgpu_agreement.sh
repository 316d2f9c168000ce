#!/bin/sh
# webgpu_agreement.sh — the WebGPU renderer (web/src/render/) against
# decalprep render: top-down decal layers against `render --cpu` at 4 m and
# 0.5 m pixels (Monaco, and Liechtenstein with casing and dashes), and an
# oblique view (pitch 45°) over flat ground and over a tilted-plane DEM
# against `render --cpu` (decals) and `render` GL (final frame);
# value-coloured layers (baked ramps and `render --ramp` given to setScene),
# hidden layers (setLayerVisible against a package built without them),
# packages of format 1.1 and 1.2 (encoded to the v1.3 layout on upload),
# and present: true (the frame on the page's canvas).
#   tests/web/webgpu_agreement.sh [DECALPREP] [WORKDIR]
# The Liechtenstein extract is read from $DECALPREP_SHARED_DATA (the real-data
# folder of tests/CMakeLists.txt); without it those cases are left out.
# Needs headless Chromium (/usr/bin/chromium), node, gdal_translate, and
# `npm ci` in web/. Exits non-zero when a comparison is below 99.9%.
set -eu
REPO=$(cd "$(dirname "$0")/../.." && pwd)
D=${1:-$REPO/build/release/tools/decalprep/decalprep}
W=${2:-$(mktemp -d)}
LI=${DECALPREP_SHARED_DATA:-/nonexistent}/liechtenstein/liechtenstein-2013-08-03.osm.pbf
H="node $REPO/tests/web/webgpu_harness.mjs"
C="node $REPO/tests/web/webgpu_compare.mjs"
S=480x270
[ -f "$W/monaco.decals" ] || "$D" build "$REPO/samples/monaco/scene.toml" -o "$W/monaco.decals" >/dev/null
if [ ! -f "$W/li.decals" ] && [ -f "$LI" ]; then
  sed "s|@SHARED_DATA@|$DECALPREP_SHARED_DATA|" "$REPO/tests/web/webgpu_liechtenstein.toml" >"$W/li.toml"
  "$D" build "$W/li.toml" -o "$W/li.decals" >/dev/null
fi
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
# An extent (frame CRS) relative to a package's origin: package, extent.
relext() {
  "$D" info "$1" --json 2>/dev/null | E="$2" node -e 'let s="";process.stdin.on("data",c=>s+=c).on("end",()=>{
    const j=JSON.parse(s), o=(j.metadata??j).origin, e=process.env.E.split(",").map(Number);
    process.stdout.write([e[0]-o.x,e[1]-o.y,e[2]-o.x,e[3]-o.y].join(","))})'
}
# Any package top-down: name, package, extent (frame CRS), render options,
# harness package and options. The harness takes the extent relative to
# the harness package's origin.
cmp() {
  "$D" render "$2" --cpu --only polygons,lines --flat --extent="$3" --size $S -o "$W/$1_cpu.png" --decals "$W/$1_cpu_decals.png" $4
  rel=$(relext "$5" "$3")
  $H --pkg "$5" --size $S --extent "$rel" --out "$W/$1_gpu" $6
  printf '%s decals vs cpu: ' "$1"; $C "$W/$1_cpu_decals.png" "$W/$1_gpu_decals.png" || status=1
}
# Value-coloured layers (webgpu_ramp.toml: buildings by way id, streets by
# id, both with colour ramps): the colours the build baked, then render's
# --ramp given to setScene as RAMPS (layer 1 buildings, 3 streets).
[ -f "$W/ramp.decals" ] || "$D" build "$REPO/tests/web/webgpu_ramp.toml" -o "$W/ramp.decals" >/dev/null
RE=-415,-698,545,-158
cmp ramp_baked "$W/ramp.decals" $RE "" "$W/ramp.decals" ""
cmp ramp_restyled "$W/ramp.decals" $RE "--ramp buildings=1e8:#0000ff,2.5e8:#20ff20c0,3e8:#ff000080 --ramp streets=1e7:#00ffff,2e8:#ff00ff" \
  "$W/ramp.decals" "--ramps [[1,[[1e8,0,0,255,255],[2.5e8,32,255,32,192],[3e8,255,0,0,128]]],[3,[[1e7,0,255,255,255],[2e8,255,0,255,255]]]]"
# present: true (two frames): the page's canvas, read back through a 2D
# canvas, holds the frame exactly, by whichever path the renderer chose
# (headless SwiftShader: "2d", the WebGPU canvas context loses the device);
# the frame against GL and its decals against --cpu.
rel=$(relext "$W/ramp.decals" $RE)
"$D" render "$W/ramp.decals" --aa none --only polygons,lines --flat --extent=$RE --size $S -o "$W/present_gl.png"
"$D" render "$W/ramp.decals" --cpu --only polygons,lines --flat --extent=$RE --size $S -o "$W/present_cpu.png" --decals "$W/present_cpu_decals.png"
out=$($H --pkg "$W/ramp.decals" --size $S --extent "$rel" --present 1 --frames 2 --out "$W/present_gpu") || status=1
echo "$out"
case "$out" in *"presentPath 2d"*|*"presentPath webgpu"*) ;; *) echo "present: no frame shown"; status=1 ;; esac
printf 'present canvas vs frame: '; $C "$W/present_gpu_rgba.png" "$W/present_gpu_canvas.png" --tol 0 --min 1 --all || status=1
printf 'present frame vs gl: '; $C "$W/present_gl.png" "$W/present_gpu_rgba.png" || status=1
printf 'present decals vs cpu: '; $C "$W/present_cpu_decals.png" "$W/present_gpu_decals.png" || status=1
# Hidden layers: render has no per-layer option, so the reference is the
# same scene built without the buildings and streets layers.
awk -v src="source = \"$REPO/samples/monaco/monaco.osm.pbf\"" '
  function flush() { if (block !~ /name = "(buildings|streets)"/) printf "%s", block; block = "" }
  /^\[\[layer\]\]/ { flush() }
  /^source = / { $0 = src }
  { block = block $0 "\n" }
  END { flush() }' "$REPO/tests/web/webgpu_ramp.toml" > "$W/ramp_hidden.toml"
[ -f "$W/ramp_hidden.decals" ] || "$D" build "$W/ramp_hidden.toml" -o "$W/ramp_hidden.decals" >/dev/null
cmp ramp_hidden "$W/ramp_hidden.decals" $RE "" "$W/ramp.decals" "--hide 1,3"
# Packages of format 1.1 and 1.2 (the v1.2 layout; 1.1 ranks lines over
# every polygon), encoded to the v1.3 layout on upload.
for v in 1_1 1_2; do
  G=$REPO/tests/formats/legacy/golden_v$v.decals
  cmp legacy_${v}_w "$G" 300,-615,700,-390 "" "$G" ""
  cmp legacy_${v}_z "$G" 420,-560,540,-492.5 "" "$G" ""
done
# Oblique views: render's --eye/--target camera (render_request.cpp: near =
# max(0.1, dist / 1000), depth range 4 dist, up z).
camera_json() {  # eye target out
  node -e '
const [eye, target, out] = [process.argv[1], process.argv[2], process.argv[3]];
const e = eye.split(",").map(Number), t = target.split(",").map(Number);
const dist = Math.hypot(e[0] - t[0], e[1] - t[1], e[2] - t[2]);
require("fs").writeFileSync(out, JSON.stringify({projection: "perspective", eye: e, target: t, up: [0, 0, 1],
  fovYDeg: 45, orthoW: 0, orthoH: 0, near: Math.max(0.1, dist * 1e-3), depthRange: 4 * dist, topdownExtent: null}));
' -- "$@"
}
camera_json 400,-400,500 400,100,0 "$W/cam_flat.json"
camera_json 400,-400,690 400,100,190 "$W/cam_plane.json"
# plane_dem NAME PACKAGE A B: the plane z = 100 + A x + B y (frame metres)
# as NAME.tif (a 140 x 140 grid of 30 m cells in the package's CRS) and as
# the harness's Terrain NAME_terrain.json (metres relative to the package
# origin, written to NAME_origin). Any mesh of a plane is the same surface,
# so the Terrain and render's DEM mesh agree exactly.
plane_dem() {
  "$D" info "$2" --json 2>/dev/null | node -e '
let s = ""; process.stdin.on("data", (c) => (s += c)).on("end", () => {
  const fs = require("fs"), [w, name, a, b] = process.argv.slice(1), j = JSON.parse(s), m = j.metadata ?? j;
  const f = (x, y) => 100 + Number(a) * x + Number(b) * y, cell = 30, x0 = -1800, y0 = -2500, n = 140;
  let asc = `ncols ${n}\nnrows ${n}\nxllcorner ${x0}\nyllcorner ${y0}\ncellsize ${cell}\n`;
  for (let r = 0; r < n; ++r) {
    const yc = y0 + (n - 1 - r + 0.5) * cell, row = [];
    for (let c = 0; c < n; ++c) row.push(f(x0 + (c + 0.5) * cell, yc).toFixed(6));
    asc += row.join(" ") + "\n";
  }
  fs.writeFileSync(`${w}/${name}.asc`, asc);
  fs.writeFileSync(`${w}/${name}.prj`, m.crs_wkt);
  const ox = m.origin.x, oy = m.origin.y, tx = -1785 - ox, ty = -2485 - oy, k = 139, z = [];
  for (let j = 0; j < k; ++j) for (let i = 0; i < k; ++i) z.push(f(tx + 30 * i + ox, ty + 30 * j + oy));
  fs.writeFileSync(`${w}/${name}_terrain.json`, JSON.stringify({x0: tx, y0: ty, dx: 30, dy: 30, nx: k, ny: k, z,
    zmin: Math.min(...z), zmax: Math.max(...z)}));
  fs.writeFileSync(`${w}/${name}_origin`, `${ox},${oy}`);
})' "$W" "$1" "$3" "$4"
  gdal_translate -q -a_srs "$W/$1.prj" -ot Float64 "$W/$1.asc" "$W/$1.tif"
}
plane_dem plane "$W/monaco.decals" 0.2 0.1
oblique() {  # name, camera, eye, target, render terrain option, harness terrain option[, package]
  P=${7:-$W/monaco.decals}
  "$D" render "$P" --cpu --only polygons,lines $5 --eye "$3" --target "$4" --size $S -o "$W/$1_cpu.png" --decals "$W/$1_cpu_decals.png"
  "$D" render "$P" --aa none --only polygons,lines $5 --eye "$3" --target "$4" --size $S -o "$W/$1_gl.png" --decals "$W/$1_gl_decals.png"
  $H --pkg "$P" --size $S --camera "$W/$2" $6 --out "$W/$1_gpu"
  printf '%s decals vs cpu: ' "$1"; $C "$W/$1_cpu_decals.png" "$W/$1_gpu_decals.png" || status=1
  printf '%s frame vs gl: ' "$1"; $C "$W/$1_gl.png" "$W/$1_gpu_rgba.png" || status=1
}
# Slope widths (webgpu_slope.toml: paths bevel, streets round, main roads
# miter with casing measured along the terrain; rail and the polygons in
# plan) over the steep plane z = 100 + 0.8 x + 0.4 y (41.8°, lines across
# it 34% narrower in plan), top-down (the gradient under the pixel centre)
# and oblique, against render --cpu (decals) and GL (final frame).
[ -f "$W/slope.decals" ] || "$D" build "$REPO/tests/web/webgpu_slope.toml" -o "$W/slope.decals" >/dev/null
plane_dem steep "$W/slope.decals" 0.8 0.4
SO=$(cat "$W/steep_origin")
steep_topdown() {  # name, extent (frame CRS)
  rel=$(E="$2" O="$SO" node -e 'const e = process.env.E.split(",").map(Number), o = process.env.O.split(",").map(Number);
    process.stdout.write([e[0] - o[0], e[1] - o[1], e[2] - o[0], e[3] - o[1]].join(","))')
  "$D" render "$W/slope.decals" --cpu --only polygons,lines --dem "$W/steep.tif" --extent="$2" --size $S -o "$W/$1_cpu.png" --decals "$W/$1_cpu_decals.png"
  "$D" render "$W/slope.decals" --cpu --only polygons,lines --dem "$W/steep.tif" --slope-widths off --extent="$2" --size $S -o "$W/$1_plan.png" --decals "$W/$1_plan_decals.png"
  $H --pkg "$W/slope.decals" --size $S --extent "$rel" --terrain "$W/steep_terrain.json" --out "$W/$1_gpu"
  # Every pixel counts here: plan widths differ from the reference mostly
  # on the lines' edges, in the edge band.
  printf '%s decals vs cpu, all pixels: ' "$1"; $C "$W/$1_cpu_decals.png" "$W/$1_gpu_decals.png" --all --min 0.9999 || status=1
  printf '%s (what the check tells apart: cpu in plan widths vs cpu): ' "$1"; $C "$W/$1_cpu_decals.png" "$W/$1_plan_decals.png" --all --min 0.9999 || true
}
steep_topdown slope1 -215,-496,265,-226
steep_topdown slope05 0,-400,240,-265
oblique mo_flat cam_flat.json 400,-400,500 400,100,0 --flat ""
oblique mo_plane cam_plane.json 400,-400,690 400,100,190 "--dem $W/plane.tif" "--terrain $W/plane_terrain.json"
# The slope package over the steep plane, oblique, looking east up the
# slope (render's --eye and --target are relative to the package origin,
# as the harness camera is).
camera_json -100,-300,900 400,-300,300 "$W/cam_steep.json"
oblique slope_oblique cam_steep.json -100,-300,900 400,-300,300 "--dem $W/steep.tif" "--terrain $W/steep_terrain.json" "$W/slope.decals"
printf 'slope_oblique decals vs cpu, all pixels: '; $C "$W/slope_oblique_cpu_decals.png" "$W/slope_oblique_gpu_decals.png" --all --min 0.9999 || status=1
"$D" render "$W/slope.decals" --cpu --only polygons,lines --dem "$W/steep.tif" --slope-widths off --eye -100,-300,900 --target 400,-300,300 --size $S -o "$W/slope_oblique_plan.png" --decals "$W/slope_oblique_plan_decals.png"
printf 'slope_oblique (what the check tells apart: cpu in plan widths vs cpu): '; $C "$W/slope_oblique_cpu_decals.png" "$W/slope_oblique_plan_decals.png" --all --min 0.9999 || true
exit $status
