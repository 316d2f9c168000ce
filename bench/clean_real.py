#!/usr/bin/env python3
"""bench/clean_real.py — clean (stage 3) on a real hole-heavy polygon layer.

  bench/clean_real.py [--input PATH] [--runs 3] [--threads 0]
                      [--build-dir build/release] [--out bench/report]
                      [--baseline-build-dir DIR] [--tileset METRES] [--jobs N]

The input (default: the optional earth-seas set of scripts/fetch-data,
@geo-maps/earth-seas-10m: the world ocean as one polygon of 239372 shell
vertices and 60798 holes, 1.77e6 vertices in all) is built as a new user
would after the tool's own advice for a world layer (a package holds
+-2147 km from its origin): the default frame (Equal Earth for world data,
its origin the data's centre) and an --extent of 4000 km around that
origin, which a first dry run with an extent beyond the data reports
(frame.origin; nothing reaches GEOS). In one run, alternating, --runs times each:
  ogr2ogr   `ogr2ogr -f FlatGeobuf` of the same file (the floor);
  dry-run   `decalprep build --dry-run --report`: read, project and clean
            timings from the report;
  build     the whole `decalprep build -o`.
With --tileset METRES, also the same build as a tileset of that tile size
(`tileset`: `build --tile-size METRES -o DIR`) and with overview levels
(`tileset+levels`: `--levels auto`), each against the same floor, with
--jobs N tiles built side by side (default 1, the tool's default).
With --baseline-build-dir (another build, e.g. of the previous commit), its
dry-run and build (`dry-run@base`, `build@base`) alternate with the others in
the same runs, so that before and after are compared under the same load.
Prints a table of the best (lowest wall) run of each and the ratios the
target needs: clean / (read + project), and build / ogr2ogr; writes
clean_real.csv (every run, then the best). Wall, CPU and peak RSS of each
child come from wait4 (bench/measure.py); the 1-minute load average is
recorded beside each run (the machine may be shared).
Standard library only; needs ogr2ogr.
"""
import argparse
import csv
import json
import os
import shutil
import sys
import tempfile

from measure import measured  # beside this script

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CACHE = os.environ.get("DECALPREP_DATA_CACHE", "/var/cache/decalprep")
SEAS = os.path.join(CACHE, "earth-seas", "package", "map.geo.json")
HALF = 2000000.0  # metres each side of the origin: inside a package's +-2147 km


def frame_origin(tool, path, work):
    """The default frame's origin for `path`: a dry run whose extent lies
    far beyond the data (every part is clipped away before GEOS)."""
    report = os.path.join(work, "origin.json")
    measured([tool, "build", path, "--kind", "polygon", "--dry-run", "--report", report,
              "--extent=9e8,9e8,9.00000001e8,9.00000001e8", "--progress", "none"])
    return json.load(open(report))["frame"]["origin"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--input", default=SEAS)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))
    ap.add_argument("--baseline-build-dir", default=None)
    ap.add_argument("--tileset", type=float, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args()
    if not os.path.exists(a.input):
        sys.exit("clean_real: %s is missing: run scripts/fetch-data earth-seas" % a.input)
    tool = os.path.join(a.build_dir, "tools", "decalprep", "decalprep")
    tools = {"": tool}
    if a.baseline_build_dir:
        tools["@base"] = os.path.join(a.baseline_build_dir, "tools", "decalprep", "decalprep")
    kinds = ("dry-run", "build") + (("tileset", "tileset+levels") if a.tileset > 0 else ())
    whats = ["ogr2ogr"] + ["%s%s" % (w, t) for t in tools for w in kinds]
    os.makedirs(a.out, exist_ok=True)
    work = tempfile.mkdtemp(prefix="clean_real_")
    rows = []
    try:
        ox, oy = frame_origin(tool, a.input, work)
        extent = "%.0f,%.0f,%.0f,%.0f" % (ox - HALF, oy - HALF, ox + HALF, oy + HALF)
        print("frame origin (%.0f, %.0f), --extent=%s" % (ox, oy, extent), flush=True)
        scene = [a.input, "--kind", "polygon", "--extent=" + extent, "--progress", "none",
                 "--threads", str(a.threads)]
        for run in range(a.runs):
            for what in whats:
                report = os.path.join(work, "%s.json" % what)
                exe = tools.get(what[what.find("@"):] if "@" in what else "")
                if what == "ogr2ogr":
                    out = os.path.join(work, "floor.fgb")
                    if os.path.exists(out):
                        os.remove(out)
                    cmd = ["ogr2ogr", "-f", "FlatGeobuf", out, a.input]
                elif what.startswith("dry-run"):
                    cmd = [exe, "build"] + scene + ["--dry-run", "--report", report]
                elif what.startswith("tileset"):
                    out = os.path.join(work, "seas-tiles")
                    shutil.rmtree(out, ignore_errors=True)
                    cmd = [exe, "build"] + scene + ["-o", out, "--tile-size", "%g" % a.tileset,
                                                    "--jobs", str(a.jobs), "--report", report]
                    if what.startswith("tileset+levels"):
                        cmd += ["--levels", "auto"]
                else:
                    cmd = [exe, "build"] + scene + ["-o", os.path.join(work, "seas.decals"),
                                                    "--report", report]
                wall, cpu, rss = measured(cmd)
                row = {"run": run, "what": what, "wall_s": wall, "cpu_s": cpu, "peak_rss_mib": rss,
                       "load1": os.getloadavg()[0]}
                if what.startswith(("dry-run", "build")):
                    t = json.load(open(report))["timings_s"]
                    for stage in ("read", "project", "clean"):
                        row[stage + "_s"] = t.get(stage, float("nan"))
                rows.append(row)
                print("run %d %-13s wall %7.2f s  cpu %7.2f s  load %.1f" %
                      (run, what, wall, cpu, row["load1"]), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    best = {}
    for r in rows:
        if r["what"] not in best or r["wall_s"] < best[r["what"]]["wall_s"]:
            best[r["what"]] = r
    floor = best["ogr2ogr"]
    ratios = {}
    for t in tools:
        dry, build = best["dry-run" + t], best["build" + t]
        ratios[t] = (dry["clean_s"] / (dry["read_s"] + dry["project_s"]),
                     build["wall_s"] / floor["wall_s"])
    print()
    print("best of %d       wall s   cpu s   read s  project s  clean s" % a.runs)
    for what in whats:
        r = best[what]
        print("%-13s %8.2f %7.2f %8s %10s %8s" %
              (what, r["wall_s"], r["cpu_s"], "%.2f" % r["read_s"] if "read_s" in r else "",
               "%.2f" % r["project_s"] if "project_s" in r else "",
               "%.2f" % r["clean_s"] if "clean_s" in r else ""))
    for t in tools:
        print()
        print("clean / (read + project)%-6s = %.2f   (target <= 3)" % (t, ratios[t][0]))
        print("build / ogr2ogr%-15s = %.2f   (target <= 5)" % (t, ratios[t][1]))
        for kind, target in (("tileset", 6), ("tileset+levels", 8)):
            if kind + t in best:
                print("%s / ogr2ogr%-*s = %.2f   (target <= %d)" %
                      (kind, 21 - len(kind), t, best[kind + t]["wall_s"] / floor["wall_s"], target))

    fields = ["run", "what", "wall_s", "cpu_s", "peak_rss_mib", "load1", "read_s", "project_s",
              "clean_s", "clean_over_read_project", "build_over_ogr2ogr"]
    path = os.path.join(a.out, "clean_real.csv")
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, restval="")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("%.3f" % v if isinstance(v, float) else v) for k, v in r.items()})
        for what in whats:
            r = dict(best[what], run="best")
            t = what[what.find("@"):] if "@" in what else ""
            if what.startswith("dry-run"):
                r["clean_over_read_project"] = ratios[t][0]
            if what.startswith("build"):
                r["build_over_ogr2ogr"] = ratios[t][1]
            if what.startswith("tileset"):
                r["build_over_ogr2ogr"] = r["wall_s"] / floor["wall_s"]
            w.writerow({k: ("%.3f" % v if isinstance(v, float) else v) for k, v in r.items()})
    print("wrote %s" % path)


if __name__ == "__main__":
    main()
