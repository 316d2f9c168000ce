#!/usr/bin/env python3
"""bench/render_memory.py — peak host memory of `render` over a whole tileset.

  bench/render_memory.py [--vertices 1e6,1e7] [--tile-size 2000] [--size 2000x1000]
                         [--before OLD_DECALPREP [--before-max-vertices 2e6]]
                         [--build-dir build/release]
                         [--out bench/report]

For each size: synthetic polygons and lines (bench/gen_synthetic.py "mix")
built as a tileset without overview levels, then a top-down render of its
whole extent with `render --cpu` and with GL, each in a child whose peak
resident memory the kernel reports (wait4). The bound each must meet:

  the largest tile's blobs decoded (the sum of raw_size in `info --json`)
  + 2 x the frame (W x H x 36 bytes: the RGBA8 image and the float decal
    and dynamic layers that render returns)
  + 300 MiB.

With --before, the same renders by another decalprep binary (for example
one built from an earlier commit) run in the same pass, so the two sides
share the machine's state; the ratio is before / now. Only up to
--before-max-vertices: a binary that holds every drawn tile in memory needs
about 2.7 GiB per 10^6 vertices here, more than this machine has at 10^7.
Prints a line per render and writes render_memory.csv and render_memory.png
(gnuplot: each render's peak against its bound). Standard library only; needs ogr2ogr (gen_synthetic) and GL for the GL rows (skipped, with a
line saying so, when the GL render fails).
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile

import gen_synthetic  # beside this script
from measure import add_build_and_out, decalprep_of, measured, vertex_counts, write_rows

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MIB = 1024.0 * 1024.0


def decoded_bytes(tool, package):
    info = json.loads(subprocess.run([tool, "info", package, "--json"], check=True,
                                     capture_output=True).stdout)
    return sum(b["raw_size"] for b in info["blobs"])


def chart(rows, out):
    """render_memory.png: each render's peak RSS beside its bound (gnuplot)."""
    if not shutil.which("gnuplot"):
        return
    dat = os.path.join(out, "render_memory.dat")
    with open(dat, "w") as f:
        for r in rows:
            f.write('"%s %s %s" %s %s\n' % ("%.0e" % float(r["vertices"]), r["renderer"],
                                            r["side"], r["peak_rss_mib"], r["bound_mib"]))
    script = """set terminal pngcairo size 900,500
set output '%s'
set style data histograms
set style fill solid 0.6
set logscale y
set ylabel 'peak RSS, MiB'
set xtics rotate by -30
plot '%s' using 2:xtic(1) title 'peak RSS', '' using 3 title 'bound' with linespoints
""" % (os.path.join(out, "render_memory.png"), dat)
    subprocess.run(["gnuplot"], input=script.encode(), check=False)
    os.remove(dat)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_build_and_out(ap)
    ap.add_argument("--vertices", default="1e6,1e7")
    ap.add_argument("--tile-size", default="2000")
    ap.add_argument("--size", default="2000x1000")
    ap.add_argument("--before", help="another decalprep binary to measure beside this build's")
    ap.add_argument("--before-max-vertices", default="2e6")
    a = ap.parse_args()
    tool = decalprep_of(a)
    w, h = (int(v) for v in a.size.split("x"))
    frame_bytes = w * h * 36
    work = tempfile.mkdtemp(prefix="render_memory_")
    rows = []
    try:
        for v in vertex_counts(a.vertices):
            scene, fgb = gen_synthetic.mix_scene(work, v, "mix%d" % v)
            tiles = os.path.join(work, "tiles%d" % v)
            b_wall, _, b_rss = measured([tool, "build", scene, "-o", tiles, "--tile-size",
                                         a.tile_size, "-q"])
            os.remove(fgb)
            index = json.load(open(os.path.join(tiles, "tileset.json")))
            e = index["extent"]
            packages = glob.glob(os.path.join(tiles, "tiles", "*.decals"))
            sizes = [decoded_bytes(tool, p) for p in packages]
            largest = max(sizes)
            total = sum(sizes)
            bound = largest + 2 * frame_bytes + 300 * MIB
            print("%d vertices: tileset of %d tiles built in %.1f s (%.0f MiB peak); blobs "
                  "decoded %.1f MiB in all, %.1f MiB the largest tile; bound %.1f MiB"
                  % (v, len(packages), b_wall, b_rss, total / MIB, largest / MIB, bound / MIB),
                  flush=True)
            sides = [("now", tool)]
            if a.before and v <= float(a.before_max_vertices):
                sides.append(("before", a.before))
            for renderer in ("cpu", "gl"):
                measured_rss = {}
                for side, binary in sides:
                    png = os.path.join(work, "%s_%s.png" % (renderer, side))
                    cmd = [binary, "render", tiles, "--extent=%r,%r,%r,%r" % tuple(e),
                           "--size", a.size, "-o", png] + (["--cpu"] if renderer == "cpu" else [])
                    try:
                        wall, cpu, rss = measured(cmd)
                    except RuntimeError as err:
                        print("  %s %s: failed (%s)" % (renderer, side, str(err)[-300:]))
                        continue
                    measured_rss[side] = rss
                    row = {"vertices": v, "tiles": len(packages), "renderer": renderer,
                           "side": side, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                           "peak_rss_mib": round(rss, 1),
                           "decoded_all_tiles_mib": round(total / MIB, 1),
                           "largest_tile_mib": round(largest / MIB, 1),
                           "frame_mib": round(frame_bytes / MIB, 1),
                           "bound_mib": round(bound / MIB, 1),
                           "within_bound": rss * MIB <= bound}
                    rows.append(row)
                    print("  %(renderer)s (%(side)s): %(wall_s)s s wall, %(peak_rss_mib)s MiB "
                          "peak; bound %(bound_mib)s MiB: %(within_bound)s" % row, flush=True)
                if "before" in measured_rss and "now" in measured_rss:
                    print("  %s peak before / now: x%.2f"
                          % (renderer, measured_rss["before"] / measured_rss["now"]))
            shutil.rmtree(tiles, ignore_errors=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    csv_path = os.path.join(a.out, "render_memory.csv")
    write_rows(csv_path, rows)
    chart(rows, a.out)
    print("wrote", csv_path)
    return 0 if all(r["within_bound"] for r in rows if r["side"] == "now") else 1


if __name__ == "__main__":
    sys.exit(main())
