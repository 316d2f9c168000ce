#!/usr/bin/env python3
"""A tileset build's peak RSS against its --max-memory estimate per tile.

  bench/memory/tiles.py [BUILD_DIR]     (default build/release; ~2 min on 2 cores)

Builds generated inputs (bench/gen_synthetic.py: star polygons with holes,
10^5 and 10^6 vertices; its "mix" of polygons and 3 m wide lines, 10^6) and
the Monaco sample as tilesets of several tile sizes with --jobs 1 and 2, and
compares the kernel's peak resident set of each build (wait4's ru_maxrss)
with the largest tile's estimate in the report (memory_estimate.tile: the
resident set when the tiles began plus the jobs times the tile's build
part, libprep/memory/memory_estimate.cpp). The estimate must never be
below the peak. Writes tile_peak_rss.csv next to this script and prints a
Markdown table.
"""
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import gen_synthetic  # noqa: E402


def polygons(work, vertices):
    geojsonl = os.path.join(work, "p%d.geojsonl" % vertices)
    fgb = os.path.join(work, "p%d.fgb" % vertices)
    gen_synthetic.write("polygons", vertices, geojsonl)
    subprocess.run(["ogr2ogr", "-f", "FlatGeobuf", fgb, geojsonl, "-a_srs", "EPSG:32632"], check=True)
    os.remove(geojsonl)
    return [fgb, "--kind", "polygon"]


def build(tool, work, source, tile, jobs):
    out = os.path.join(work, "tiles")
    report = os.path.join(work, "tiles.json")
    shutil.rmtree(out, ignore_errors=True)
    p = subprocess.Popen([tool, "build"] + source + ["-o", out, "--tile-size", str(tile), "--jobs",
                                                     str(jobs), "--report", report, "-q"],
                         stderr=subprocess.PIPE)
    err = p.stderr.read()
    _, status, ru = os.wait4(p.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit("build failed: %s" % err.decode()[-2000:])
    r = json.load(open(report))
    e = r["memory_estimate"]["tile"]
    shutil.rmtree(out)
    return {"tiles": r["tileset"]["tiles"], "peak_mib": round(ru.ru_maxrss / 1024, 1),
            "resident_mib": round(e["resident_mib"], 1), "estimate_mib": round(e["mib"], 1),
            "ratio": round(e["mib"] / (ru.ru_maxrss / 1024), 2), "tile": e["tile"],
            "polygon_vertices": int(e["polygon_vertices"]), "line_vertices": int(e["line_vertices"])}


def main():
    build_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "release")
    tool = os.path.join(build_dir, "tools", "decalprep", "decalprep")
    work = tempfile.mkdtemp(prefix="decalprep-tiles-mem-")
    try:
        mix_scene, _ = gen_synthetic.mix_scene(work, 1_000_000, extent=4000 * math.sqrt(10), seed=3)
        inputs = [
            ("polygons 1e5", polygons(work, 100_000), (500, 2000)),
            ("polygons 1e6", polygons(work, 1_000_000), (2000, 5000, 20000)),
            ("mix 1e6", [mix_scene], (1000, 4000, 12000)),
            ("Monaco scene", [os.path.join(ROOT, "samples", "monaco", "scene.toml")], (500, 2000)),
        ]
        rows = []
        for name, source, tiles in inputs:
            for tile in tiles:
                for jobs in (1, 2):
                    row = {"input": name, "tile_m": tile, "jobs": jobs}
                    row.update(build(tool, work, source, tile, jobs))
                    rows.append(row)
                    print("%-13s %6d m  %d job(s): peak %6.1f MiB, estimate %6.1f (x%.2f), resident "
                          "%6.1f, largest tile %s" % (name, tile, jobs, row["peak_mib"],
                                                       row["estimate_mib"], row["ratio"],
                                                       row["resident_mib"], row["tile"]), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    path = os.path.join(HERE, "tile_peak_rss.csv")
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print("\n| input | tile | jobs | tiles | resident MiB | peak MiB | estimate MiB | estimate / peak "
          "| largest tile: polygon / line vertices |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| %s | %d m | %d | %d | %.1f | %.1f | %.1f | %.2f | %d / %d |"
              % (r["input"], r["tile_m"], r["jobs"], r["tiles"], r["resident_mib"], r["peak_mib"],
                 r["estimate_mib"], r["ratio"], r["polygon_vertices"], r["line_vertices"]))
    low = [r for r in rows if r["ratio"] < 1]
    print("\nestimate / peak: %.2f-%.2f over %d builds; %s (%s)"
          % (min(r["ratio"] for r in rows), max(r["ratio"] for r in rows), len(rows),
             "below the peak in %d" % len(low) if low else "never below the peak", path))
    return 1 if low else 0


if __name__ == "__main__":
    sys.exit(main())
