#!/usr/bin/env python3
"""bench/tileset_scale.py — tileset builds against input size.

  bench/tileset_scale.py [--vertices 1e5,1e6,1e7] [--tile-size 2000] [--jobs 2]
                         [--build-dir build/release] [--out bench/report]

For each size: synthetic polygons and lines (bench/gen_synthetic.py "mix", at
constant density, so the extent grows with the square root of the size) in
FlatGeobuf; then, in the same run, `ogr2ogr -f FlatGeobuf` of that file (the
floor: reading and writing the same features) and `decalprep build
--tile-size` (out of core: ARCHITECTURE.md "3b. tile"). Prints and writes
tileset_scale.csv (wall, CPU, peak RSS of each child from wait4, and per
input vertex; tiles, package bytes per input vertex, the ratio to the floor,
the 1-minute load average as the build ended) and
tileset_scale.png (gnuplot), and the fitted slope of log(wall) against
log(vertices) between the smallest and the largest size.
Standard library only; needs ogr2ogr and gnuplot.
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

import gen_synthetic  # beside this script
from measure import add_build_and_out, decalprep_of, measured, vertex_counts, write_rows

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def slope(xs, ys):
    lx = [math.log(x) for x in xs]
    ly = [math.log(y) for y in ys]
    mx, my = sum(lx) / len(lx), sum(ly) / len(ly)
    den = sum((a - mx) ** 2 for a in lx)
    return sum((a - mx) * (b - my) for a, b in zip(lx, ly)) / den if den > 0 else float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--vertices", default="1e5,1e6")
    ap.add_argument("--tile-size", default="2000")
    ap.add_argument("--jobs", default="2")
    add_build_and_out(ap)
    a = ap.parse_args()
    tool = decalprep_of(a)
    work = tempfile.mkdtemp(prefix="tileset_scale_")
    rows = []
    try:
        for v in vertex_counts(a.vertices):
            scene, fgb = gen_synthetic.mix_scene(work, v, "mix%d" % v)
            floor = os.path.join(work, "floor%d.fgb" % v)
            f_wall, f_cpu, f_rss = measured(["ogr2ogr", "-f", "FlatGeobuf", floor, fgb])
            out = os.path.join(work, "tiles%d" % v)
            report = os.path.join(work, "tiles%d.json" % v)
            wall, cpu, rss = measured([tool, "build", scene, "-o", out, "--tile-size", a.tile_size,
                                       "--jobs", a.jobs, "--report", report, "-q"])
            ts = json.load(open(report))["tileset"]
            row = {"vertices": v, "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
                   "peak_rss_mib": round(rss, 1), "tiles": ts["tiles"], "bytes": ts["bytes"],
                   "bytes_per_vertex": round(ts["bytes"] / v, 2),
                   "ogr2ogr_fgb_wall_s": round(f_wall, 3), "ratio_to_floor": round(wall / f_wall, 2),
                   "peak_rss_bytes_per_vertex": round(rss * 1048576.0 / v, 1),
                   "ogr2ogr_peak_rss_mib": round(f_rss, 1),
                   "loadavg_1min": round(os.getloadavg()[0], 2)}
            rows.append(row)
            print("%(vertices)d vertices: %(wall_s)s s wall, %(cpu_s)s s CPU, %(peak_rss_mib)s MiB "
                  "peak (%(peak_rss_bytes_per_vertex)s B/vertex), %(tiles)d tiles, "
                  "%(bytes_per_vertex)s package B/vertex; ogr2ogr %(ogr2ogr_fgb_wall_s)s s "
                  "(x%(ratio_to_floor)s), load %(loadavg_1min)s" % row, flush=True)
            shutil.rmtree(out, ignore_errors=True)
            for p in (fgb, floor):
                os.remove(p)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    csv_path = os.path.join(a.out, "tileset_scale.csv")
    write_rows(csv_path, rows)
    if len(rows) > 1:
        s = slope([r["vertices"] for r in rows], [r["wall_s"] for r in rows])
        m = rows[-1]["peak_rss_mib"] / rows[-2]["peak_rss_mib"]
        c = slope([r["vertices"] for r in rows], [r["cpu_s"] for r in rows])
        print("fitted slope on log(vertices): log(wall) %.3f, log(CPU) %.3f; peak RSS %d / %d "
              "vertices: x%.2f" % (s, c, rows[-1]["vertices"], rows[-2]["vertices"], m))
    if shutil.which("gnuplot"):
        png = os.path.join(a.out, "tileset_scale.png")
        script = """set terminal pngcairo size 800,500
set output '%s'
set datafile separator ','
set logscale xy
set key top left
set xlabel 'input vertices'
set ylabel 'seconds'
plot '%s' using 1:2 skip 1 with linespoints title 'decalprep build --tile-size (wall)', \\
     '%s' using 1:8 skip 1 with linespoints title 'ogr2ogr -f FlatGeobuf (floor)'
""" % (png, csv_path, csv_path)
        subprocess.run(["gnuplot"], input=script.encode(), check=False)
    print("wrote", csv_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
