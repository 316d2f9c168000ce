#!/usr/bin/env python3
"""bench/overview.py — a tileset's overview levels: bytes against visual error.

  bench/overview.py [--vertices 1e6] [--tile-size 1000] [--size 1280x720] [--no-gl]
                    [--build-dir build/release] [--out bench/report] [--report-md bench/REPORT.md]

Builds synthetic polygons and 3 m lines (bench/gen_synthetic.py "mix", as
bench/tileset_scale.py) as a tileset with `--levels auto`, then for each
level L: the package bytes of the level (tileset.json), and at the view that
level is chosen for (a top-down view centred on the data whose pixel is
r_L * sqrt(2) ground metres, between r_L and r_(L+1) = 2 r_L, where `render
--level auto` picks L; level 0 at r_1 / sqrt(2)) the CPU render with
`--level L` against the CPU render with `--level 0`: pixels whose decal
layer differs by more than 1/255 in a channel (point-sampled, --raw
float32), and pixels that differ by more than 1/8 after a 4x4 box filter
(both rendered at 4x4 samples a pixel; tests/tools/raw_compare.cpp, the
metric of tests/tools/tileset_overview_test.py), the bytes
that view loads against full detail, and the frame time of the render call
(`--stats`: CPU, and GL unless --no-gl). Prints, writes
bench/report/overview.csv and overview.png (gnuplot: bytes per level against
visual error) and the section "## Overview levels" of bench/REPORT.md
(bench/run keeps it).
"""
import argparse
import csv
import json
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

import gen_synthetic  # beside this script
from measure import add_build_and_out, decalprep_of  # beside this script

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BEGIN = "<!-- begin bench/overview.py -->"
END = "<!-- end bench/overview.py -->"
HEAD = "## Overview levels"
FIELDS = ["level", "tile_size_m", "resolution_m", "tiles", "package_bytes", "view_pixel_m",
          "view_width_m", "auto_levels", "view_tiles", "view_bytes", "full_view_bytes",
          "bytes_share", "view_blob_bytes", "full_view_blob_bytes", "blob_share",
          "pixels_differing", "pixels", "differing_share", "filtered_differing",
          "filtered_share", "cpu_frame_ms", "gl_frame_ms", "full_cpu_frame_ms", "full_gl_frame_ms"]


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise RuntimeError("%s failed (%d): %s" % (" ".join(cmd), p.returncode, p.stderr[-2000:]))
    return p.stdout, p.stderr


def stats(out):
    m = re.search(r"^tiles: (\d+) drawn \(([^)]*)\)", out, re.M)
    b = re.search(r"^bytes: (\d+) package bytes loaded, [0-9.]+% of the full-detail (\d+) of this "
                  r"view; (\d+) blob bytes uploaded", out, re.M)
    f = re.search(r"^frame: ([0-9.]+) ms", out, re.M)
    levels = {int(l): int(n) for l, n in re.findall(r"level (\d+): (\d+)", m.group(2))}
    return {"tiles": int(m.group(1)), "levels": {l: n for l, n in levels.items() if n},
            "bytes": int(b.group(1)), "full_bytes": int(b.group(2)),
            "blob_bytes": int(b.group(3)), "frame_ms": float(f.group(1))}


def compare(tool, a, b, w, h, s):
    out, _ = run([tool, a, b, str(w), str(h), str(s), str(1 / 8)])
    m = re.match(r"point (\d+) filtered (\d+) pixels (\d+)", out)
    return [int(g) for g in m.groups()]


def splice(path, block):
    try:
        with open(path) as f:
            text = f.read()
    except OSError:
        text = "# Benchmarks\n"
    if BEGIN in text and END in text:
        a, b = text.index(BEGIN), text.index(END) + len(END)
        text = text[:a] + block + text[b:]
    else:
        section = HEAD + "\n\n" + block + "\n\n"
        i = text.find("\n## Method\n")
        text = text.rstrip("\n") + "\n\n" + section if i < 0 else text[:i + 1] + section + text[i + 1:]
    with open(path, "w") as f:
        f.write(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--vertices", default="1e6")
    ap.add_argument("--tile-size", default="1000")
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--no-gl", action="store_true")
    add_build_and_out(ap)
    ap.add_argument("--report-md", default=os.path.join(ROOT, "bench", "REPORT.md"))
    a = ap.parse_args()
    tool = decalprep_of(a)
    raw_compare = os.path.join(a.build_dir, "tests", "tools", "raw_compare")
    w, h = (int(v) for v in a.size.split("x"))
    v = int(float(a.vertices))
    work = tempfile.mkdtemp(prefix="overview_")
    t_start = time.time()
    load0 = os.getloadavg()
    rows = []
    try:
        scene, _ = gen_synthetic.mix_scene(work, v)
        ts = os.path.join(work, "tiles")
        t0 = time.monotonic()
        run([tool, "build", scene, "-o", ts, "--tile-size", a.tile_size, "--levels", "auto",
             "--jobs", "2", "-q"])
        build_s = time.monotonic() - t0
        index = json.load(open(os.path.join(ts, "tileset.json")))
        levels = [{"level": 0, "tile_size_m": index["tiling"]["tile_size_m"],
                   "resolution_m": 0.0, "tiles": index["tiles"]}]
        for lv in index.get("levels") or []:
            levels.append({"level": lv["level"], "tile_size_m": lv["tile_size_m"],
                           "resolution_m": lv["resolution_m"], "tiles": lv["tiles"]})
        x0, y0, x1, y1 = index["extent"]
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        for i, lv in enumerate(levels):
            if lv["level"] == 0:
                r1 = levels[1]["resolution_m"] if len(levels) > 1 else 1.0
                pixel = r1 / math.sqrt(2)
            else:
                pixel = lv["resolution_m"] * math.sqrt(2)
            vw, vh = pixel * w, pixel * h
            ext = "%.3f,%.3f,%.3f,%.3f" % (cx - vw / 2, cy - vh / 2, cx + vw / 2, cy + vh / 2)
            common = [tool, "render", ts, "--extent", ext, "--flat", "--stats"]
            small = ["--size", a.size]
            out, _ = run(common + small + ["--level", "auto", "--cpu", "-o",
                                           os.path.join(work, "a.png")])
            chosen = stats(out)
            st = {}
            big = ["--size", "%dx%d" % (4 * w, 4 * h)]
            for name, level in (("lv", str(lv["level"])), ("full", "0")):
                out, _ = run(common + small + ["--level", level, "--cpu", "--raw",
                                       os.path.join(work, name + ".raw"), "-o",
                                       os.path.join(work, name + ".png")])
                st[name] = stats(out)
                run(common + big + ["--level", level, "--cpu", "--raw",
                                    os.path.join(work, name + "4.raw"), "-o",
                                    os.path.join(work, name + "4.png")])
                if not a.no_gl:
                    out, _ = run(common + small + ["--level", level, "-o",
                                                   os.path.join(work, "g.png")])
                    st[name]["gl_ms"] = stats(out)["frame_ms"]
            d, _, n = compare(raw_compare, os.path.join(work, "lv.raw"),
                              os.path.join(work, "full.raw"), w, h, 1)
            _, fd, _ = compare(raw_compare, os.path.join(work, "lv4.raw"),
                               os.path.join(work, "full4.raw"), w, h, 4)
            row = {"level": lv["level"], "tile_size_m": lv["tile_size_m"],
                   "resolution_m": round(lv["resolution_m"], 4), "tiles": len(lv["tiles"]),
                   "package_bytes": sum(t["bytes"] for t in lv["tiles"]),
                   "view_pixel_m": round(pixel, 4), "view_width_m": round(vw, 1),
                   "auto_levels": " ".join("L%d:%d" % kv for kv in sorted(chosen["levels"].items())),
                   "view_tiles": st["lv"]["tiles"], "view_bytes": st["lv"]["bytes"],
                   "full_view_bytes": st["full"]["bytes"],
                   "bytes_share": round(st["lv"]["bytes"] / max(1, st["full"]["bytes"]), 5),
                   "view_blob_bytes": st["lv"]["blob_bytes"],
                   "full_view_blob_bytes": st["full"]["blob_bytes"],
                   "blob_share": round(st["lv"]["blob_bytes"] / max(1, st["full"]["blob_bytes"]),
                                       5),
                   "pixels_differing": d, "pixels": n, "differing_share": round(d / n, 6),
                   "filtered_differing": fd, "filtered_share": round(fd / n, 6),
                   "cpu_frame_ms": round(st["lv"]["frame_ms"], 1),
                   "gl_frame_ms": round(st["lv"].get("gl_ms", float("nan")), 1),
                   "full_cpu_frame_ms": round(st["full"]["frame_ms"], 1),
                   "full_gl_frame_ms": round(st["full"].get("gl_ms", float("nan")), 1)}
            rows.append(row)
            print("level %(level)d: %(tiles)d tiles, %(package_bytes)d package bytes, r %(resolution_m)s m;"
                  " view %(view_width_m)s m wide (%(view_pixel_m)s m pixels, auto draws "
                  "%(auto_levels)s): %(view_bytes)d of %(full_view_bytes)d package bytes, "
                  "%(view_blob_bytes)d of %(full_view_blob_bytes)d blob bytes, "
                  "%(pixels_differing)d pixels differ (%(differing_share)s; box-filtered "
                  "%(filtered_differing)d, %(filtered_share)s), CPU %(cpu_frame_ms)s ms "
                  "(full %(full_cpu_frame_ms)s), GL %(gl_frame_ms)s ms (full %(full_gl_frame_ms)s)"
                  % row, flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    csv_path = os.path.join(a.out, "overview.csv")
    with open(csv_path, "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=FIELDS)
        wr.writeheader()
        wr.writerows(rows)
    png = os.path.join(a.out, "overview.png")
    if shutil.which("gnuplot"):
        script = """set terminal pngcairo size 800,500
set output '%s'
set datafile separator ','
set logscale x
set key top right
set xlabel 'package bytes of the level'
set ylabel 'pixels differing from full detail at its view (%%)'
plot '%s' using 5:($18*100):(sprintf('L%%d', $1)) skip 1 with labels offset 1,1 notitle, \\
     '' using 5:($18*100) skip 1 with linespoints title 'point-sampled (> 1/255)', \\
     '' using 5:($20*100) skip 1 with linespoints title 'box-filtered 4x4 (> 1/8)'
""" % (png, csv_path)
        subprocess.run(["gnuplot"], input=script.encode(), check=False)
    load1 = os.getloadavg()
    took = time.time() - t_start
    gl_dev = "Mesa llvmpipe (no GPU)" if not a.no_gl else "not run"
    L = [BEGIN, "",
         "Generated by `bench/overview.py --vertices %s --tile-size %s --size %s` (%s, %.0f s, build "
         "%.1f s; %s, %s). Load average (1/5/15 min) at start %.2f/%.2f/%.2f, at end %.2f/%.2f/%.2f. "
         "[report/overview.csv](report/overview.csv)"
         % (a.vertices, a.tile_size, a.size, time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            took, build_s, platform.platform(), "GL: " + gl_dev, *load0, *load1), "",
         "Each level at the view `render --level auto` chooses it for: a top-down view of the data's "
         "centre whose pixel is r_L·√2 (level 0: r_1/√2), drawn with `--level L` against "
         "`--level 0` (CPU evaluator): pixels whose decal layer differs by more than 1/255 "
         "(point-sampled), and by more than 1/8 after a 4×4 box filter (both rendered at 4×4 "
         "samples a pixel: what an anti-aliased render shows; 3 m lines at pixels of metres hit "
         "pixel centres by chance, so the point-sampled count follows every move of a line). "
         "Package bytes are the files' (tileset.json); blob bytes are the drawn tiles' blobs "
         "decoded, what a render uploads and `--gpu-budget` counts (`--stats`); frame times are the render call's (`--stats`), tiles "
         "loaded before it.", "",
         "| level | tile | r_L | tiles | package bytes | view width | auto draws | view bytes "
         "| of full detail | view blob bytes | of full detail | pixels differing | box-filtered "
         "| CPU frame | GL frame | full-detail CPU / GL |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        L.append("| %d | %g m | %.3f m | %d | %s | %.0f m | %s | %s | %.2f%% | %s | %.2f%% "
                 "| %d (%.3f%%) "
                 "| %d (%.3f%%) | %.1f ms | %.1f ms | %.1f / %.1f ms |"
                 % (r["level"], r["tile_size_m"], r["resolution_m"], r["tiles"],
                    format(r["package_bytes"], ","), r["view_width_m"], r["auto_levels"],
                    format(r["view_bytes"], ","), 100 * r["bytes_share"],
                    format(r["view_blob_bytes"], ","), 100 * r["blob_share"], r["pixels_differing"],
                    100 * r["differing_share"], r["filtered_differing"],
                    100 * r["filtered_share"], r["cpu_frame_ms"], r["gl_frame_ms"],
                    r["full_cpu_frame_ms"], r["full_gl_frame_ms"]))
    L += ["", "![Package bytes per level against the pixels differing from full detail at its view]"
          "(report/overview.png)", "", END]
    splice(a.report_md, "\n".join(L))
    print("wrote", csv_path, png if os.path.exists(png) else "(no gnuplot)", a.report_md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
