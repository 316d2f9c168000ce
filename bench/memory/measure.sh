#!/usr/bin/env bash
# Measures decalprep build's peak RSS on generated inputs of a few sizes, for
# the --max-memory model (libprep/memory/memory_estimate.cpp). Writes
# peak_rss.csv (one row per build) next to this script; fit.py fits the model.
# Usage: bench/memory/measure.sh [BUILD_DIR]   (default build/dev)
# Needs /usr/bin/time (package `time`) and ogr2ogr (gdal-bin). ~1 min on 2 cores.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
tool=${1:-$root/build/dev}/tools/decalprep/decalprep
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
csv=$root/bench/memory/peak_rss.csv
echo "input,kind,threads,polygon_vertices,line_vertices,polygon_parts,line_parts,peak_rss_mib,peak_after_read_mib,peak_after_clean_mib,peak_after_build_mib,estimate_after_read_mib,estimate_after_clean_mib,estimate_after_grid_mib,resident_at_grid_mib,grid_cell_mib,geometry_mib,wall_s" > "$csv"

gen() {  # NAME KIND VERTICES
  python3 "$root/bench/gen_synthetic.py" "$2" "$3" "$work/$1.geojsonl"
  ogr2ogr -f FlatGeobuf "$work/$1.fgb" "$work/$1.geojsonl" -a_srs EPSG:32632
}
small() {  # NAME polygons|lines COUNT: many tiny parts (5-vertex squares, 3-vertex lines)
  python3 - "$work/$1.geojsonl" "$2" "$3" <<'PY'
import json, random, sys
path, kind, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
rng = random.Random(3)
with open(path, "w") as f:
    for i in range(n):
        cx, cy = 370000 + rng.random() * 6000, 4840000 + rng.random() * 6000
        if kind == "polygons":
            r = 3 + rng.random() * 5
            g = {"type": "Polygon", "coordinates": [[[cx - r, cy - r], [cx + r, cy - r], [cx + r, cy + r], [cx - r, cy + r], [cx - r, cy - r]]]}
        else:
            g = {"type": "LineString", "coordinates": [[cx, cy], [cx + 10, cy + 3], [cx + 20, cy - 2]]}
        f.write(json.dumps({"type": "Feature", "id": i + 1, "properties": {}, "geometry": g}) + "\n")
PY
  ogr2ogr -f FlatGeobuf "$work/$1.fgb" "$work/$1.geojsonl" -a_srs EPSG:32632
}
run() {  # NAME KIND [ARGS...]
  local name=$1 kind=$2; shift 2
  local threads=${THREADS:-2}
  /usr/bin/time -f "%M %e" -o "$work/$name.time" "$tool" build "$work/$name.fgb" -o "$work/$name.decals" \
    --report "$work/$name.json" -q --kind "$kind" --threads "$threads" "$@"
  python3 - "$work/$name.json" "$work/$name.time" "$name" "$kind" "$threads" >> "$csv" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
rss_kb, wall = open(sys.argv[2]).read().split()[-2:]
e = r["memory_estimate"]["after read"]
p = r["peak_rss_mib_after"]
g = r["memory_estimate"]["after grid"]
print(",".join(str(x) for x in [sys.argv[3], sys.argv[4], sys.argv[5], int(e["polygon_vertices"]), int(e["line_vertices"]),
      int(e["polygon_parts"]), int(e["line_parts"]), round(int(rss_kb) / 1024, 1), round(p["read"], 1),
      round(p["clean"], 1), round(p["build"], 1), round(e["mib"], 1),
      round(r["memory_estimate"]["after clean"]["mib"], 1), round(g["mib"], 1), round(g["resident_mib"], 1),
      round(g["cell_mib"], 1), round(g["geometry_mib"], 1), wall]))
PY
  tail -1 "$csv"
}

for n in 1e5 3e5 1e6; do
  gen "polygons-$n" polygons "$n"; run "polygons-$n" polygon
  gen "lines-$n" lines "$n"; run "lines-$n" line --width 4
done
for n in 20000 100000; do
  small "small-polygons-$n" polygons "$n"; run "small-polygons-$n" polygon
  small "short-lines-$n" lines "$n"; run "short-lines-$n" line --width 4
done
# Wide lines make more grid entries per vertex.
run "lines-3e5" line --width 40
echo "wrote $csv"
