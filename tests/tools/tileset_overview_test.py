#!/usr/bin/env python3
"""A whole-extent view of a big tileset draws from its overview levels.

  tileset_overview_test.py DECALPREP ROOT WORK_DIR VERTICES [TILE_SIZE [GL]]

Generates VERTICES synthetic vertices (bench/gen_synthetic.py "mix", as
bench/tileset_scale.py: star polygons with holes and 3 m lines in
EPSG:32632, converted to FlatGeobuf by ogr2ogr), builds them as a tileset
with `--tile-size TILE_SIZE --levels auto`, and renders the whole extent
top-down at 1280x720 (square pixels: the extent widened to 16:9) with the
CPU evaluator twice: `--level auto` (the default) and `--level 0` (full
detail). Passes when
  - the auto view draws no level-0 tile (the coarse levels only),
  - it loads less than 5% of the package bytes the full-detail view loads,
    both as `--stats` reports them and as the sums of tileset.json's tile
    bytes over the tiles the stderr line says were drawn (the full-detail
    figure must equal the sum of the level-0 tiles meeting the view,
    computed here from the index),
  - the two decal layers (--raw, float32 RGBA) differ on less than 1% of
    the pixels (a channel more than 1/255 apart).
With GL (7th argument "gl"), also renders both views with GL and prints
the frame times (no assertion on them). Prints bytes, pixels, frame times.
Exit 77 (skipped) without ogr2ogr.
"""
import array
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time

W, H = 1280, 720
MAX_BYTES_SHARE = 0.05
MAX_PIXELS_SHARE = 0.01


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def run(cmd, what):
    t0 = time.monotonic()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wall = time.monotonic() - t0
    if p.returncode != 0:
        fail("%s exited %d: %s\n%s" % (what, p.returncode, " ".join(cmd), p.stderr[-3000:]))
    return p.stdout, p.stderr, wall


def stats_of(out):
    """tiles per level, loaded bytes, full-detail bytes, frame ms from --stats."""
    m = re.search(r"^tiles: (\d+) drawn \(([^)]*)\)", out, re.M)
    b = re.search(r"^bytes: (\d+) package bytes loaded, [0-9.]+% of the full-detail (\d+) of this "
                  r"view; (\d+) blob bytes uploaded", out, re.M)
    f = re.search(r"^frame: ([0-9.]+) ms", out, re.M)
    if not (m and b and f):
        fail("--stats does not say tiles, bytes and frame:\n" + out)
    per_level = {int(l): int(n) for l, n in re.findall(r"level (\d+): (\d+)", m.group(2))}
    return {"tiles": int(m.group(1)), "per_level": per_level, "bytes": int(b.group(1)),
            "full_bytes": int(b.group(2)), "blob_bytes": int(b.group(3)),
            "frame_ms": float(f.group(1))}


def main():
    if len(sys.argv) < 5:
        print(__doc__)
        return 2
    tool, root, work, vertices = sys.argv[1], sys.argv[2], sys.argv[3], int(float(sys.argv[4]))
    tile = sys.argv[5] if len(sys.argv) > 5 else "2000"
    gl = len(sys.argv) > 6 and sys.argv[6] == "gl"
    if not shutil.which("ogr2ogr"):
        print("SKIP: no ogr2ogr")
        return 77
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    gj, fgb = os.path.join(work, "mix.geojsonl"), os.path.join(work, "mix.fgb")
    subprocess.run([sys.executable, os.path.join(root, "bench", "gen_synthetic.py"), "mix",
                    str(vertices), gj], check=True)
    subprocess.run(["ogr2ogr", "-f", "FlatGeobuf", fgb, gj, "-a_srs", "EPSG:32632", "-nln", "mix"],
                   check=True)
    os.remove(gj)
    scene = os.path.join(work, "mix.toml")
    with open(scene, "w") as f:
        f.write('source = "%s"\ncrs = "EPSG:32632"\n' % fgb)
        f.write('[[layer]]\nname = "polygons"\nkind = "polygon"\n'
                'sql = "SELECT * FROM mix WHERE OGR_GEOMETRY = \'POLYGON\'"\n')
        f.write('[[layer]]\nname = "lines"\nkind = "line"\nwidth = 3\n'
                'sql = "SELECT * FROM mix WHERE OGR_GEOMETRY = \'LINESTRING\'"\n')
    ts = os.path.join(work, "tiles")
    _, _, build_s = run([tool, "build", scene, "-o", ts, "--tile-size", tile, "--levels", "auto",
                         "--jobs", "2", "-q"], "build")
    index = json.load(open(os.path.join(ts, "tileset.json")))
    levels = index.get("levels") or []
    if not levels:
        fail("tileset.json lists no overview levels after --levels auto")

    # The whole extent, widened to 16:9 about its centre: square pixels.
    x0, y0, x1, y1 = index["extent"]
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    half_w = max(x1 - x0, (y1 - y0) * W / H) / 2 * 1.001
    half_h = half_w * H / W
    view = (cx - half_w, cy - half_h, cx + half_w, cy + half_h)
    pixel = 2 * half_w / W
    extent_arg = "%.3f,%.3f,%.3f,%.3f" % view

    def meets(sq):
        return sq[0] < view[2] and view[0] < sq[2] and sq[1] < view[3] and view[1] < sq[3]

    full_bytes = sum(t["bytes"] for t in index["tiles"] if meets(t["square"]))
    level_bytes = {0: sum(t["bytes"] for t in index["tiles"])}
    for lv in levels:
        level_bytes[lv["level"]] = sum(t["bytes"] for t in lv["tiles"])

    renders = {}
    for name, level in (("auto", "auto"), ("full", "0")):
        raw = os.path.join(work, name + ".raw")
        out, err, wall = run([tool, "render", ts, "--extent", extent_arg, "--size", "%dx%d" % (W, H),
                              "--cpu", "--flat", "--level", level, "--stats", "--raw", raw, "-o",
                              os.path.join(work, name + ".png")], "render --level " + level)
        s = stats_of(out)
        s["wall_s"] = wall
        a = array.array("f")
        with open(raw, "rb") as f:
            a.frombytes(f.read())
        s["raw"] = a
        renders[name] = s
        os.remove(raw)
    auto, full = renders["auto"], renders["full"]
    if auto["per_level"].get(0, 0) != 0:
        fail("the whole-extent view draws %d full-detail tiles: %s" % (auto["per_level"][0],
                                                                        auto["per_level"]))
    if full["full_bytes"] != full_bytes or auto["full_bytes"] != full_bytes:
        fail("--stats says the full-detail view holds %d / %d bytes; tileset.json's level-0 tiles "
             "meeting the view hold %d" % (full["full_bytes"], auto["full_bytes"], full_bytes))
    if full["bytes"] != full_bytes:
        fail("--level 0 loaded %d bytes, not the level-0 tiles' %d" % (full["bytes"], full_bytes))
    share = auto["bytes"] / full_bytes
    n = W * H
    a, b = auto["raw"], full["raw"]
    if len(a) != 4 * n or len(b) != 4 * n:
        fail("--raw holds %d and %d floats, not %d" % (len(a), len(b), 4 * n))
    differ = 0
    for k in range(n):
        i = 4 * k
        if (abs(a[i] - b[i]) > 1 / 255 or abs(a[i + 1] - b[i + 1]) > 1 / 255 or
                abs(a[i + 2] - b[i + 2]) > 1 / 255 or abs(a[i + 3] - b[i + 3]) > 1 / 255):
            differ += 1
    covered = sum(1 for k in range(n) if b[4 * k + 3] > 0)
    print("%d vertices, %s m tiles, levels 1..%d (build %.1f s); view %.0f x %.0f m at %dx%d "
          "(%.2f m pixels)" % (vertices, tile, len(levels), build_s, 2 * half_w, 2 * half_h, W, H,
                               pixel))
    print("package bytes per level: " + ", ".join("L%d %d" % kv for kv in sorted(level_bytes.items())))
    print("auto: tiles %s, %d bytes loaded (%.3f%% of full detail's %d; %d blob bytes), CPU frame "
          "%.1f ms" % (auto["per_level"], auto["bytes"], 100 * share, full_bytes,
                       auto["blob_bytes"], auto["frame_ms"]))
    print("full: %d level-0 tiles, %d bytes (%d blob bytes), CPU frame %.1f ms"
          % (full["tiles"], full["bytes"], full["blob_bytes"], full["frame_ms"]))
    print("pixels differing: %d of %d (%.3f%%); pixels with a decal at full detail: %d (%.1f%%)"
          % (differ, n, 100.0 * differ / n, covered, 100.0 * covered / n))
    if gl:
        for name, level in (("auto", "auto"), ("full", "0")):
            p = subprocess.run([tool, "render", ts, "--extent", extent_arg, "--size",
                                "%dx%d" % (W, H), "--flat", "--level", level, "--stats", "-o",
                                os.path.join(work, name + "_gl.png")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            if p.returncode != 0:
                print("GL %s: exit %d (%s)" % (name, p.returncode, p.stderr.strip()[-300:]))
                continue
            s = stats_of(p.stdout)
            dev = re.search(r"^device: ([^,]*)", p.stdout, re.M)
            print("GL %s (%s): %d tiles, frame %.1f ms" % (name, dev.group(1) if dev else "?",
                                                            s["tiles"], s["frame_ms"]))
    if covered < n // 100:
        fail("the full-detail view draws decals on only %d pixels: nothing to compare" % covered)
    if share >= MAX_BYTES_SHARE:
        fail("the whole-extent view loads %.2f%% of the full-detail bytes (limit %.0f%%)"
             % (100 * share, 100 * MAX_BYTES_SHARE))
    if differ >= MAX_PIXELS_SHARE * n:
        fail("%d pixels (%.2f%%) differ from full detail (limit %.0f%%)"
             % (differ, 100.0 * differ / n, 100 * MAX_PIXELS_SHARE))
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
