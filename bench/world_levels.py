#!/usr/bin/env python3
"""bench/world_levels.py — a world land layer as a 500 km tileset with overview levels.

  bench/world_levels.py [--input PATH] [--runs 2] [--tile-size 500000] [--jobs 2]
                        [--size 2000x980] [--build-dir build/release] [--out bench/report]

The input (default: the optional countries-land set of scripts/fetch-data,
@geo-maps/countries-land-1m: 250 countries, 9.52e6 vertices, 838,960
holes) is built as a new user would: `decalprep build INPUT --kind polygon
--tile-size 500000 --levels auto --jobs 2` (the default frame: Equal Earth
for world data). In one run, alternating, --runs times each: that build and
`ogr2ogr -f FlatGeobuf` of the same file (the floor; GeoJSON objects of any
size allowed, as decalprep's reader allows them). Then, on the last build,
top-down renders of the whole extent at --size: GL (--aa none) and --cpu, each at
`--level auto` (the coarsest level within a pixel) and `--level 0`; the
share of pixels of each auto render that differ from the level-0 render of
the same renderer, and GL against --cpu. Prints the figures and writes
world_levels.csv (every run and render). Standard library only; needs
ogr2ogr, and GL for the GL renders.
"""
import argparse
import json
import os
import shutil
import struct
import sys
import tempfile

from measure import add_build_and_out, decalprep_of, measured, write_rows

CACHE = os.environ.get("DECALPREP_DATA_CACHE", "/var/cache/decalprep")
LAND = os.path.join(CACHE, "countries-land", "package", "map.geo.json")


def raw_pixels(path):
    """The --raw float32 RGBA image as one tuple of pixels (RGBA tuples)."""
    data = open(path, "rb").read()
    v = struct.unpack("<%df" % (len(data) // 4), data)
    return [v[i:i + 4] for i in range(0, len(v), 4)]


def differ(a, b):
    """How many pixels differ by more than 1/255 in some channel."""
    return sum(1 for p, q in zip(a, b) if max(abs(x - y) for x, y in zip(p, q)) > 1.0 / 255)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--input", default=LAND)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--tile-size", default="500000")
    ap.add_argument("--jobs", default="2")
    ap.add_argument("--size", default="2000x980")
    add_build_and_out(ap)
    a = ap.parse_args()
    if not os.path.exists(a.input):
        sys.exit("world_levels: %s is missing: run scripts/fetch-data countries-land" % a.input)
    tool = decalprep_of(a)
    work = tempfile.mkdtemp(prefix="world_levels_")
    rows = []
    try:
        tiles = os.path.join(work, "world")
        for run in range(a.runs):
            for what in ("ogr2ogr", "tileset+levels"):
                if what == "ogr2ogr":
                    out = os.path.join(work, "floor.fgb")
                    if os.path.exists(out):
                        os.remove(out)
                    cmd = ["ogr2ogr", "--config", "OGR_GEOJSON_MAX_OBJ_SIZE", "0", "-f",
                           "FlatGeobuf", out, a.input]
                else:
                    shutil.rmtree(tiles, ignore_errors=True)
                    cmd = [tool, "build", a.input, "--kind", "polygon", "--tile-size", a.tile_size,
                           "--levels", "auto", "--jobs", a.jobs, "-o", tiles, "--progress", "none"]
                wall, cpu, rss = measured(cmd)
                rows.append({"run": run, "what": what, "wall_s": wall, "cpu_s": cpu,
                             "peak_rss_mib": rss, "load1": os.getloadavg()[0], "differ_pct": ""})
                print("run %d %-15s wall %7.2f s  cpu %7.2f s  peak %6.0f MiB  load %.1f" %
                      (run, what, wall, cpu, rss, rows[-1]["load1"]), flush=True)
        ix = json.load(open(os.path.join(tiles, "tileset.json")))
        ext = "--extent=%r,%r,%r,%r" % tuple(ix["extent"])
        for level in ix["levels"]:
            kept = sum(layer["vertices_out"] for layer in level["layers"])
            print("level %d: %d tiles, %d vertices, %d bytes" %
                  (level["level"], len(level["tiles"]), kept, sum(t["bytes"] for t in level["tiles"])))
        images = {}
        for renderer in ("gl", "cpu"):
            for level in ("auto", "0"):
                name = "%s_level_%s" % (renderer, level)
                raw = os.path.join(work, name + ".raw")
                cmd = [tool, "render", tiles, ext, "--size", a.size, "--level", level,
                       "-o", os.path.join(work, name + ".png"), "--raw", raw]
                # GL aliased, as the CPU evaluator draws (GL's default is
                # --aa msaa4), so that the two can be compared pixel by pixel.
                cmd += ["--cpu"] if renderer == "cpu" else ["--aa", "none"]
                wall, cpu, rss = measured(cmd)
                images[name] = raw_pixels(raw)
                rows.append({"run": "", "what": "render " + name, "wall_s": wall, "cpu_s": cpu,
                             "peak_rss_mib": rss, "load1": os.getloadavg()[0], "differ_pct": ""})
        for name, ref in (("gl_level_auto", "gl_level_0"), ("cpu_level_auto", "cpu_level_0"),
                          ("gl_level_auto", "cpu_level_auto"), ("gl_level_0", "cpu_level_0")):
            n = differ(images[name], images[ref])
            pct = 100.0 * n / len(images[ref])
            rows.append({"run": "", "what": "%s vs %s" % (name, ref), "wall_s": "", "cpu_s": "",
                         "peak_rss_mib": "", "load1": "", "differ_pct": pct})
            print("%-15s vs %-15s %8d pixels differ (%.3f%%)" % (name, ref, n, pct))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    best = {}
    for r in rows:
        if r["what"] in ("ogr2ogr", "tileset+levels"):
            if r["what"] not in best or r["wall_s"] < best[r["what"]]["wall_s"]:
                best[r["what"]] = r
    for r in rows:
        if r["what"].startswith("render "):
            print("%-24s wall %6.2f s  peak %6.0f MiB" % (r["what"], r["wall_s"], r["peak_rss_mib"]))
    print("tileset+levels / ogr2ogr (best of %d) = %.2f   (target <= 10)" %
          (a.runs, best["tileset+levels"]["wall_s"] / best["ogr2ogr"]["wall_s"]))
    path = os.path.join(a.out, "world_levels.csv")
    write_rows(path, rows)
    print("wrote %s" % path)


if __name__ == "__main__":
    main()
