#!/usr/bin/env python3
"""bench/zstd_levels.py — the size/time curve of the zstd level of stage 5.

  bench/zstd_levels.py [--vertices 1e6] [--levels 1,3,6,9,12,19] [--repeat 3]
                       [--threads N] [--build-dir build/release] [--out bench/report]
                       [--no-monaco]
  bench/zstd_levels.py --from-csv [--out bench/report]

Builds two models once each, through the real pipeline (read, clean, build):
  synthetic  --vertices of star polygons with holes (bench/gen_synthetic.py
             "polygons", converted to FlatGeobuf with ogr2ogr, EPSG:32632),
             one polygon layer;
  monaco     samples/monaco/scene.toml (polygons, lines, dynamic lines);
then times write_model on each at codec none and every level, serial (one
thread) and with --threads (default: all), alternating, median of --repeat
(`bench_io --levels`, bench/bench_io.cpp). Writes OUT/zstd_levels.csv (one
row per scene, level and thread count: seconds, package bytes, raw model blob
bytes, raw / package, the machine's parallel capacity at the time, the load
average, the 1-thread / N-thread ratio predicted for N idle cores, and on the
1-thread rows the writer's CPU seconds, which a loaded shared machine
disturbs far less than the wall seconds; see bench_io.cpp) and
OUT/zstd_levels.png (gnuplot: compression ratio against write seconds, one
curve per scene and thread count plus one of the 1-thread CPU seconds, points
labelled by level), and prints the table. Standard library only; needs
ogr2ogr and gnuplot.
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import gen_synthetic  # noqa: E402


def synthetic_scene(work, vertices):
    gj = os.path.join(work, "polygons.geojsonl")
    fgb = os.path.join(work, "polygons.fgb")
    gen_synthetic.write("polygons", vertices, gj)
    subprocess.run(["ogr2ogr", "-f", "FlatGeobuf", fgb, gj, "-a_srs", "EPSG:32632", "-nln",
                    "polygons"], check=True)
    os.remove(gj)
    scene = os.path.join(work, "polygons.toml")
    with open(scene, "w") as f:
        f.write('source = "%s"\ncrs = "EPSG:32632"\n[[layer]]\nname = "polygons"\n'
                'kind = "polygon"\n' % fgb)
    return scene


def plot(csv_path, png):
    rows = list(csv.DictReader(open(csv_path)))
    series = []  # (scene label, threads, time column) -> rows
    for r in rows:
        if int(r["level"]) == 0:
            continue
        keys = [(r["scene"], r["vertices"], r["threads"], "seconds")]
        if r["threads"] == "1" and r.get("cpu_seconds", "nan") not in ("", "nan"):
            keys.append((r["scene"], r["vertices"], r["threads"], "cpu_seconds"))
        for key in keys:
            if key not in [s[0] for s in series]:
                series.append((key, []))
            next(s for s in series if s[0] == key)[1].append(r)
    work = tempfile.mkdtemp(prefix="zstd_levels_plot-")
    plots = []
    for i, ((scene, vertices, threads, column), rs) in enumerate(series):
        data = os.path.join(work, "s%d.dat" % i)
        with open(data, "w") as f:
            for r in rs:
                f.write("%s %s %s\n" % (r[column], r["ratio"], r["level"]))
        title = "%s (%s vertices), %s thread%s%s" % (
            scene, vertices, threads, "" if threads == "1" else "s",
            ", CPU seconds" if column == "cpu_seconds" else "")
        plots.append("'%s' using 1:2 with linespoints title '%s'" % (data, title))
        plots.append("'%s' using 1:2:3 with labels offset 0.8,0.6 left font ',9' notitle" % data)
    script = "\n".join([
        "set terminal pngcairo size 900,520 noenhanced font 'Sans,10'",
        "set output '%s'" % png,
        "set title 'zstd level: package compression ratio against write_model seconds'",
        "set xlabel 'write_model seconds, wall or CPU (median)'",
        "set ylabel 'raw model bytes / package bytes'",
        "set logscale x",
        "set grid",
        "set key outside bottom center horizontal",
        "plot " + ", \\\n  ".join(plots),
    ]) + "\n"
    r = subprocess.run(["gnuplot"], input=script, text=True, capture_output=True)
    if r.returncode != 0:
        raise RuntimeError("gnuplot: " + r.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--vertices", type=float, default=1e6)
    ap.add_argument("--levels", default="1,3,6,9,12,19")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))
    ap.add_argument("--no-monaco", action="store_true")
    ap.add_argument("--from-csv", action="store_true", help="only redraw the chart")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    csv_path = os.path.join(a.out, "zstd_levels.csv")
    if not a.from_csv:
        with tempfile.TemporaryDirectory(prefix="zstd_levels-") as work:
            cmd = [os.path.join(a.build_dir, "bench", "bench_io"), "--levels", csv_path,
                   "--scene", synthetic_scene(work, int(a.vertices)), "--zstd", a.levels,
                   "--repeat", str(a.repeat)]
            if not a.no_monaco:
                cmd += ["--scene", os.path.join(ROOT, "samples", "monaco", "scene.toml")]
            if a.threads:
                cmd += ["--threads", str(a.threads)]
            subprocess.run(cmd, check=True)
        # Scene labels instead of paths (the synthetic one is temporary).
        rows = list(csv.DictReader(open(csv_path)))
        for r in rows:
            r["scene"] = "monaco" if r["scene"].endswith("scene.toml") else "synthetic"
        with open(csv_path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    plot(csv_path, os.path.join(a.out, "zstd_levels.png"))
    print("wrote %s and %s" % (csv_path, os.path.join(a.out, "zstd_levels.png")))


if __name__ == "__main__":
    main()
