#!/usr/bin/env python3
"""Peak RSS of `decalprep build` on generated GeoJSON against the file's size:
GDAL's GeoJSON driver reads the whole file and builds an object tree of it
before the first feature comes out, so the read stage, not the build, holds
the peak. Writes geojson_peak_rss.csv beside this script (the fit the
before-read estimate of libprep/memory/memory_estimate.cpp cites).

  bench/memory/geojson.py DECALPREP [WORK_DIR] [--sizes 10,50,150]
      [--kinds polygons,lines,one_line] [--one-sizes 10,50]

Each size (MB) and kind is one file: small polygons (a 12-vertex ring and
three attributes each), lines (40 vertices, one attribute), or one_line, a
single LineString feature of the whole size; coordinates with 7 decimals in
lon/lat as GeoJSON writers emit them. Each is read by a dry run (read,
project, clean; --threads 2) alone, its peak the child's ru_maxrss (wait4)
and the peak after read from its report. The build stage's own memory is
the after-read model's (bench/memory/peak_rss.csv), not measured here.

Measured 2026-11-27 (release, 2 busy cores): collections of small features
0.3-0.9 MiB per MB after read (GDAL streams them a feature at a time), one
large feature 22 MiB per MB (its object parsed whole): a file's size
bounds the read from below only, so --max-memory watches the resident set
while reading (prep/memory_estimate.hpp RssWatch).
"""
import argparse
import csv
import json
import os
import random
import subprocess
import sys
import time


def write_geojson(path, megabytes, kind, seed=1):
    """Features until the file reaches `megabytes` MB (10^6 bytes)."""
    rng = random.Random(seed)
    target = int(megabytes * 1e6)
    with open(path, "w") as f:
        f.write('{"type": "FeatureCollection", "features": [\n')
        written, k = 0, 0
        while written < target:
            lon, lat = 7.0 + rng.random() * 0.5, 43.5 + rng.random() * 0.5
            if kind == "polygons":
                pts = [(lon + 1e-4 * (1 + 0.3 * rng.random()) * c, lat + 1e-4 * s)
                       for c, s in ((1, 0), (0.87, 0.5), (0.5, 0.87), (0, 1), (-0.5, 0.87), (-0.87, 0.5),
                                    (-1, 0), (-0.87, -0.5), (-0.5, -0.87), (0, -1), (0.5, -0.87), (0.87, -0.5))]
                pts.append(pts[0])
                coords = "[[" + ",".join(f"[{x:.7f},{y:.7f}]" for x, y in pts) + "]]"
                geom = f'{{"type":"Polygon","coordinates":{coords}}}'
                props = f'{{"id":{k},"name":"parcel {k}","area":{rng.random() * 1000:.2f}}}'
            elif kind == "one_line":
                # The whole file one LineString: written in one go below.
                break
            else:
                pts = [(lon + 2e-5 * i, lat + 1e-5 * rng.random()) for i in range(40)]
                coords = "[" + ",".join(f"[{x:.7f},{y:.7f}]" for x, y in pts) + "]"
                geom = f'{{"type":"LineString","coordinates":{coords}}}'
                props = f'{{"id":{k}}}'
            line = ("," if k else "") + f'{{"type":"Feature","properties":{props},"geometry":{geom}}}\n'
            f.write(line)
            written += len(line)
            k += 1
        if kind == "one_line":
            per = target // 24
            f.write('{"type":"Feature","properties":{"id":0},"geometry":{"type":"LineString",'
                    '"coordinates":[')
            f.write(",".join(f"[{7.0 + 1e-7 * i:.7f},{43.5 + 1e-5 * rng.random():.7f}]"
                             for i in range(per)))
            f.write("]}}\n")
            k = 1
        f.write("]}\n")
    return k


# The resident set before any source is read (GDAL, PROJ, GEOS loaded):
# memory_estimate.cpp's read base.
BASE_MIB = 55.0


def peak_of(args):
    """(exit code, peak RSS MiB, seconds) of decalprep with `args`."""
    t0 = time.time()
    p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, ru = os.wait4(p.pid, 0)
    return os.waitstatus_to_exitcode(status), ru.ru_maxrss / 1024.0, time.time() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("tool")
    ap.add_argument("work", nargs="?", default="/tmp/geojson-memory")
    ap.add_argument("--sizes", default="10,50,150")
    ap.add_argument("--kinds", default="polygons,lines,one_line")
    ap.add_argument("--one-sizes", default="10,50")
    ap.add_argument("--csv", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                  "geojson_peak_rss.csv"))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    rows = []
    for kind in a.kinds.split(","):
        sizes = a.one_sizes if kind == "one_line" else a.sizes
        for mb in (float(x) for x in sizes.split(",")):
            src = os.path.join(a.work, f"{kind}-{mb:g}.geojson")
            features = write_geojson(src, mb, kind)
            size = os.path.getsize(src)
            report = os.path.join(a.work, "report.json")
            lk = "polygon" if kind == "polygons" else "line"
            code, peak, secs = peak_of([a.tool, "build", src, "--kind", lk, "-q", "--threads", "2",
                                        "--dry-run", "--report", report])
            after_read = json.load(open(report))["peak_rss_mib_after"]["read"] if code == 0 else None
            row = {"kind": kind, "file_mb": round(size / 1e6, 1), "features": features, "exit": code,
                   "peak_after_read_mib": after_read, "peak_dry_run_mib": round(peak, 1),
                   "read_mib_per_file_mb": round((after_read - BASE_MIB) / (size / 1e6), 2)
                   if after_read else None, "seconds": round(secs, 1)}
            print(row, flush=True)
            rows.append(row)
            os.remove(src)
    with open(a.csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print("wrote", a.csv)


if __name__ == "__main__":
    sys.exit(main())
