#!/usr/bin/env python3
"""bench/lod_gpu.py — dynamic lines with LOCALIS LOD off and on.

  bench/lod_gpu.py [--build-dir build/release] [--work bench/out/lod_gpu]
                   [--out bench/report] [--size 1280x720] [--frames 3] [--repeats 3]
                   [--data <checkout>/../shared/data/liechtenstein/liechtenstein-2013-08-03.osm.pbf]

Builds Liechtenstein's roads (every highway=* line of the 2013 OSM extract)
as dynamic lines of a layer with `lod = true` (flat terrain: no DEM for it),
then renders the dynamic lines alone (`decalprep render --only dynamic`) in
perspective at three zooms (near: Vaduz from 560 m; middle: Vaduz from
5.8 km; far: the whole country from 30 km), fov 40°, with `--lod off`
and `--lod on` (0.5 px), alternating off and on --repeats times, each a
render of --frames frames (the last one's pass times count: warm).

Per render (one CSV row): segments drawn and linked-list nodes (fragments
pushed: `dynamic lines: ...`), the LOD counts (selected, drawn, full detail), the GL timestamp
time of each dynamic-line pass of the last frame (update, LOD selection,
lists, composite) and their sum (dyn_ms), and the frame's pass sum
(frame_ms: terrain, the dynamic passes, composite). Writes lod_gpu.csv (the
load average before and after as '#' lines) and prints the medians as a
Markdown table for bench/REPORT.md. Standard library only. On llvmpipe the
times are CPU times of software GL, not GPU times; skips, saying so, when
the data is missing.
"""
import argparse
import csv
import os
import re
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# (name, eye, target): near and middle look at Vaduz, far at the frame origin.
VIEWS = [
    ("near", "-3010,-1800,250", "-2860,-1300,0"),
    ("middle", "-2360,-6300,3000", "-2860,-1300,0"),
    ("far", "0,-26000,16000", "0,0,0"),
]
PASSES = {
    "dynamic update": "update_ms",
    "dynamic LOD": "lod_ms",
    "dynamic lists": "lists_ms",
    "dynamic composite": "composite_ms",
}


def scene(data):
    return (
        f'source = "{data}"\nextent = [9.47, 47.04, 9.64, 47.27]\nextent_crs = "EPSG:4326"\n'
        'resolution = 0\n[[layer]]\nname = "roads"\nlayer = "lines"\n'
        'where = "highway IS NOT NULL"\nkind = "line"\ndynamic = true\nlod = true\n'
        'width = 3\ncolor = "#c03020d0"\n'
    )


def parse(out):
    row = {v: 0.0 for v in PASSES.values()}
    frame = 0.0
    for line in out.splitlines():
        m = re.match(r"^(\S.*?)\s{2,}([\d.]+)\s+([\d.]+)$", line)
        if m and not m.group(1).startswith("total"):
            frame += float(m.group(2))
            for prefix, key in PASSES.items():
                if m.group(1).startswith(prefix):
                    row[key] = float(m.group(2))
        m = re.search(r"dynamic lines: (\d+) vertices kept, (\d+) segments drawn, (\d+) list nodes",
                      line)
        if m:
            row["segments_drawn"], row["list_nodes"] = int(m.group(2)), int(m.group(3))
        m = re.search(
            r"lod: on, .*?: (\d+) LOD segments drawn of (\d+) full-detail .*?; (\d+) selected", line
        )
        if m:
            row["lod_drawn"], row["lod_full"], row["lod_selected"] = map(int, m.groups())
    row["dyn_ms"] = round(sum(row[v] for v in PASSES.values()), 3)
    row["frame_ms"] = round(frame, 3)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--work", default=os.path.join(ROOT, "bench", "out", "lod_gpu"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--data",
        default=os.path.join(
            os.path.dirname(ROOT), "shared", "data", "liechtenstein",
            "liechtenstein-2013-08-03.osm.pbf",
        ),
    )
    a = ap.parse_args()
    if not os.path.exists(a.data):
        print(f"bench/lod_gpu.py: skipped, Liechtenstein data missing: {a.data}")
        return 0
    tool = os.path.join(a.build_dir, "tools", "decalprep", "decalprep")
    os.makedirs(a.work, exist_ok=True)
    os.makedirs(a.out, exist_ok=True)
    toml = os.path.join(a.work, "roads.toml")
    with open(toml, "w") as f:
        f.write(scene(os.path.abspath(a.data)))
    pkg = os.path.join(a.work, "roads.decals")
    subprocess.run([tool, "build", toml, "-o", pkg, "-q"], check=True)
    load0 = os.getloadavg()
    rows = []
    for rep in range(a.repeats):
        for name, eye, target in VIEWS:
            for lod in ("off", "on"):
                cmd = [tool, "render", pkg, "--only", "dynamic", "--flat", "--eye", eye,
                       "--target", target, "--fov", "40", "--size", a.size, "--frames",
                       str(a.frames), "--lod", lod, "--stats", "-o",
                       os.path.join(a.work, f"{name}_{lod}.png")]
                r = subprocess.run(cmd, capture_output=True, text=True)
                if r.returncode != 0:
                    sys.exit(f"bench/lod_gpu.py: {' '.join(cmd)} failed:\n{r.stdout}{r.stderr}")
                row = {"view": name, "lod": lod, "repeat": rep, "size": a.size}
                row.update(parse(r.stdout))
                rows.append(row)
                print(f"{name} lod {lod}: {row.get('segments_drawn', 0)} segments, "
                      f"dynamic {row['dyn_ms']:.1f} ms, frame {row['frame_ms']:.1f} ms",
                      flush=True)
    load1 = os.getloadavg()
    fields = ["view", "lod", "repeat", "size", "segments_drawn", "list_nodes", "lod_selected",
              "lod_drawn", "lod_full", "update_ms", "lod_ms", "lists_ms", "composite_ms", "dyn_ms", "frame_ms"]
    path = os.path.join(a.out, "lod_gpu.csv")
    with open(path, "w", newline="") as f:
        f.write(f"# load average before {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}\n")
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)
        f.write(f"# load average after {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}\n")
    print(f"wrote {path}\n")
    print("| view | segments drawn, off | on (selected) | on/off | list nodes, off | on | "
          "dynamic ms, off | on (of which LOD) | on/off | frame ms, off | on | on/off |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")

    def med(view, lod, key):
        return statistics.median(r.get(key, 0) for r in rows if r["view"] == view and r["lod"] == lod)

    for name, _, _ in VIEWS:
        s0, s1 = med(name, "off", "segments_drawn"), med(name, "on", "segments_drawn")
        sel = med(name, "on", "lod_selected")
        d0, d1, dl = med(name, "off", "dyn_ms"), med(name, "on", "dyn_ms"), med(name, "on", "lod_ms")
        f0, f1 = med(name, "off", "frame_ms"), med(name, "on", "frame_ms")
        n0, n1 = med(name, "off", "list_nodes"), med(name, "on", "list_nodes")
        print(f"| {name} | {s0:.0f} | {s1:.0f} ({sel:.0f}) | {s1 / s0:.2f} | {n0:.0f} | {n1:.0f} | "
              f"{d0:.1f} | "
              f"{d1:.1f} ({dl:.1f}) | {d1 / d0:.2f} | {f0:.1f} | {f1:.1f} | {f1 / f0:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
