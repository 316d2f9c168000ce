#!/usr/bin/env python3
"""bench/methods.py — the decal, volume and texture methods side by side.

  bench/methods.py [--package P.decals] [--build-dir build/release] [--out bench/report]
                   [--frames 3] [--texture-resolution 1]

`decalprep render --method decal|volume|texture` (thesis §5.2.2) on one
package (default: the Monaco sample, built into the output folder), static
polygons and lines only:
- frame time (sum of the last of --frames frames' pass times, GL timestamps:
  terrain, the method's passes, composite; the texture's one-off
  rasterisation reported apart) top-down over 1600 m at 640x360 and 1920x1080;
- the method's own GPU memory: the package's blobs (decal), the prism vertex
  buffer (volume, 12 bytes a vertex), the texture with mipmaps (texture);
- misclassified pixels against the CPU evaluator (`render --cpu`, decal alpha
  off by more than 0.5) at three zooms (top-down views 3200, 800 and 200 m
  wide, 640x360).
Writes methods.csv and methods.png (gnuplot: misclassified share against frame
time). Standard library only. On llvmpipe the times are CPU times of software
GL, not GPU times.
"""
import argparse
import array
import csv
import json
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
METHODS = ["decal", "volume", "texture"]
SIZES = [(640, 360), (1920, 1080)]
ZOOMS = [3200.0, 800.0, 200.0]  # view widths in metres, centred on the package origin


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if p.returncode != 0:
        raise RuntimeError("%s failed (%d): %s" % (" ".join(cmd), p.returncode, p.stdout[-2000:]))
    return p.stdout


def origin(tool, package):
    meta = json.loads(run([tool, "info", package, "--json"]))
    o = meta.get("origin") or meta.get("metadata", {}).get("origin")
    return float(o["x"]), float(o["y"])


def view(ox, oy, width, w, h):
    half_w, half_h = width / 2, width / 2 * h / w
    return "%.3f,%.3f,%.3f,%.3f" % (ox - half_w, oy - half_h, ox + half_w, oy + half_h)


def render(tool, package, method, extent, w, h, raw, args):
    cmd = [tool, "render", package, "--extent", extent, "--size", "%dx%d" % (w, h),
           "--only", "polygons,lines", "--raw", raw, "-o", raw + ".png"]
    if method == "cpu":
        cmd.append("--cpu")
    else:
        cmd += ["--method", method, "--stats", "--frames", str(args.frames)]
        if method == "texture":
            cmd += ["--texture-resolution", str(args.texture_resolution)]
    return run(cmd)


def frame_ms(stats):
    """Sum of the pass times (GPU ms) of the last frame, the one-off texture
    rasterisation and the total line apart."""
    frame, once = 0.0, 0.0
    for line in stats.splitlines():
        m = re.match(r"^(.*?)\s+([0-9.]+)\s+([0-9.]+)$", line)
        if not m or line.startswith("pass"):
            continue
        name = m.group(1)
        if name.startswith("total"):
            continue
        if name.startswith("texture raster"):
            once += float(m.group(2))
        else:
            frame += float(m.group(2))
    return frame, once


def method_bytes(method, stats, package_bytes):
    if method == "decal":
        return package_bytes
    if method == "volume":
        m = re.search(r"volume: (\d+) prism triangles", stats)
        return int(m.group(1)) * 3 * 12 if m else 0
    m = re.search(r"texture: \d+x\d+ texels at [0-9.]+ m, (\d+) bytes", stats)
    return int(m.group(1)) if m else 0


def alpha(raw):
    a = array.array("f")
    with open(raw, "rb") as f:
        a.frombytes(f.read())
    return a[3::4]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--package")
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--texture-resolution", type=float, default=1.0)
    args = ap.parse_args()
    tool = os.path.join(args.build_dir, "tools", "decalprep", "decalprep")
    os.makedirs(args.out, exist_ok=True)
    work = os.path.join(args.out, "methods")
    os.makedirs(work, exist_ok=True)
    package = args.package
    if not package:
        package = os.path.join(work, "monaco.decals")
        if not os.path.exists(package):
            run([tool, "build", os.path.join(ROOT, "samples", "monaco", "scene.toml"), "-o", package, "-q"])
    ox, oy = origin(tool, package)
    # The decal method's GPU data: the blobs as uploaded (uncompressed sizes).
    info = json.loads(run([tool, "info", package, "--json"]))
    package_bytes = sum(int(b.get("raw_size", 0)) for b in info.get("blobs", []) if b.get("name") != "manifest_entries")

    rows = []
    for method in METHODS:
        row = {"method": method}
        for w, h in SIZES:
            raw = os.path.join(work, "%s_%dx%d.rgba" % (method, w, h))
            stats = render(tool, package, method, view(ox, oy, 1600.0, w, h), w, h, raw, args)
            frame, once = frame_ms(stats)
            row["frame_ms_%dx%d" % (w, h)] = round(frame, 3)
            if method == "texture":
                row["raster_once_ms"] = round(once, 3)
            row["method_bytes"] = method_bytes(method, stats, package_bytes)
        for width in ZOOMS:
            ext = view(ox, oy, width, 640, 360)
            raw = os.path.join(work, "%s_zoom%d.rgba" % (method, width))
            oracle = os.path.join(work, "cpu_zoom%d.rgba" % width)
            if not os.path.exists(oracle):
                render(tool, package, "cpu", ext, 640, 360, oracle, args)
            render(tool, package, method, ext, 640, 360, raw, args)
            a, b = alpha(raw), alpha(oracle)
            wrong = sum(1 for x, y in zip(a, b) if abs(x - y) > 0.5)
            row["misclassified_zoom%d" % width] = wrong
            row["misclassified_share_zoom%d" % width] = round(wrong / len(b), 6)
        rows.append(row)
        print(row, flush=True)

    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    csv_path = os.path.join(args.out, "methods.csv")
    with open(csv_path, "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=keys)
        wr.writeheader()
        wr.writerows(rows)
    dat = os.path.join(work, "methods.dat")
    with open(dat, "w") as f:
        for r in rows:
            err = sum(r["misclassified_share_zoom%d" % z] for z in ZOOMS) / len(ZOOMS)
            f.write("%s %f %f %f\n" % (r["method"], r["frame_ms_640x360"], r["frame_ms_1920x1080"], err))
    png = os.path.join(args.out, "methods.png")
    script = """set terminal pngcairo size 800,500
set output '%s'
set logscale x
set xlabel 'frame time, ms (all passes of the last frame; llvmpipe: CPU time)'
set ylabel 'misclassified share vs CPU evaluator (mean of 3 zooms)'
set key bottom left
set offsets graph 0.05, graph 0.15, graph 0.1, graph 0.05
plot '%s' using 2:4:1 with labels point pt 7 offset 1,1 title '640x360', \\
     '%s' using 3:4:1 with labels point pt 5 offset 1,-1 title '1920x1080'
""" % (png, dat, dat)
    try:
        subprocess.run(["gnuplot"], input=script, text=True, check=True)
    except (OSError, subprocess.CalledProcessError) as e:
        print("gnuplot failed: %s" % e, file=sys.stderr)
    print("wrote %s and %s" % (csv_path, png))


if __name__ == "__main__":
    main()
