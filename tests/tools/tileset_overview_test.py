#!/usr/bin/env python3
"""A whole-extent view of a big tileset draws from its overview levels.

  tileset_overview_test.py DECALPREP RAW_COMPARE ROOT WORK_DIR VERTICES TILE_SIZE WxH
                           [gl] [--extent M]

Generates VERTICES synthetic vertices (bench/gen_synthetic.py "mix", as
bench/tileset_scale.py: star polygons with holes and 3 m lines in
EPSG:32632, converted to FlatGeobuf by ogr2ogr; --extent M: over a square
of M metres instead of gen_synthetic's constant density), builds them as a tileset
with `--tile-size TILE_SIZE --levels auto`, and renders the whole extent
top-down at WxH (square pixels: the extent widened to the image's aspect)
with the CPU evaluator: `--level auto` (the default) and `--level 0` (full
detail). Passes when
  - the auto view draws one overview level and no level-0 tile,
  - it uploads less than 20% of the bytes the full-detail view uploads: the
    decoded blob bytes of the drawn tiles (`--stats`; the full-detail figure
    must equal the blob tables' sum over the level-0 tiles that meet the
    view, read here from the files as formats/SPEC.md lays them out, and the
    package bytes loaded the sum of tileset.json's sizes for them); the
    package (file) bytes' share is printed too,
  - the two pictures differ on less than 1% of the pixels, point-sampled at
    WxH (a channel more than 1/255 apart), and also compared as an
    anti-aliased render shows them: both levels rendered at 4x4 samples a
    pixel, box-filtered (premultiplied RGBA averaged over each pixel's 16
    samples) and a pixel counted when a channel differs by more than 1/8
    (RAW_COMPARE, tests/tools/raw_compare.cpp). The point-sampled count is
    the stricter of the two on dense data: 3 m lines at
    pixels of tens of metres hit pixel centres by chance, so any move of a
    line within its half-pixel tolerance changes which pixels it hits.
With "gl", also renders both views with GL and prints the frame times (no
assertion on them). Prints bytes, pixels, frame times. Exit 77 (skipped)
without ogr2ogr. KEEP_WORK=1 keeps WORK_DIR (the tileset, the renders).
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tileset_util import blob_bytes  # noqa: E402

# Level 0's 2 km tiles hold one grid cell per two vertices at most
# (libprep/tile/tileset_build.cpp, tile_max_cells), so their blobs are
# mostly geometry; the CI case's level 5 uploads 16% of them (it was under
# 5% of level 0 when level 0's cell tables were three times larger). Most
# of what level 5 keeps is the 3 m lines, simplified to an eighth of their
# width (ARCHITECTURE.md "Overview levels").
MAX_BYTES_SHARE = 0.20
MAX_PIXELS_SHARE = 0.01
SUPERSAMPLE = 4
FILTERED_THRESHOLD = 1 / 8


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
    if len(sys.argv) < 8:
        print(__doc__)
        return 2
    tool, compare, root, work = sys.argv[1:5]
    vertices, tile = int(float(sys.argv[5])), sys.argv[6]
    W, H = (int(v) for v in sys.argv[7].split("x"))
    gl = "gl" in sys.argv[8:]
    spread = (float(sys.argv[sys.argv.index("--extent") + 1])
              if "--extent" in sys.argv[8:] else None)
    if not shutil.which("ogr2ogr"):
        print("SKIP: no ogr2ogr")
        return 77
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    sys.path.insert(0, os.path.join(root, "bench"))
    import gen_synthetic
    scene, _ = gen_synthetic.mix_scene(work, vertices, extent=spread)
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
    full_blob_bytes = sum(blob_bytes(os.path.join(ts, t["file"]))
                          for t in index["tiles"] if meets(t["square"]))
    level_bytes = {0: sum(t["bytes"] for t in index["tiles"])}
    for lv in levels:
        level_bytes[lv["level"]] = sum(t["bytes"] for t in lv["tiles"])

    def render(level, size, raw, extra=()):
        out, _, _ = run([tool, "render", ts, "--extent", extent_arg, "--size", size, "--cpu",
                         "--flat", "--level", level, "--stats", "--raw", raw, "-o",
                         os.path.join(work, "r.png")] + list(extra), "render --level " + level)
        return stats_of(out)

    def compare_raws(a, b, s):
        out, _, _ = run([compare, a, b, str(W), str(H), str(s), str(FILTERED_THRESHOLD)],
                        "raw_compare")
        m = re.match(r"point (\d+) filtered (\d+) pixels (\d+) covered (\d+)", out)
        return [int(g) for g in m.groups()]

    size = "%dx%d" % (W, H)
    auto = render("auto", size, os.path.join(work, "auto.raw"))
    full = render("0", size, os.path.join(work, "full.raw"))
    drawn = sorted(l for l, k in auto["per_level"].items() if k)
    if auto["per_level"].get(0, 0) != 0 or len(drawn) != 1:
        fail("the whole-extent view draws %s (tiles per level): not one overview level"
             % auto["per_level"])
    level = drawn[0]
    if full["full_bytes"] != full_bytes or auto["full_bytes"] != full_bytes:
        fail("--stats says the full-detail view holds %d / %d bytes; tileset.json's level-0 tiles "
             "meeting the view hold %d" % (full["full_bytes"], auto["full_bytes"], full_bytes))
    if full["bytes"] != full_bytes:
        fail("--level 0 loaded %d bytes, not the level-0 tiles' %d" % (full["bytes"], full_bytes))
    if full["blob_bytes"] != full_blob_bytes:
        fail("--level 0 uploaded %d blob bytes; the blob tables of the level-0 tiles meeting the "
             "view say %d" % (full["blob_bytes"], full_blob_bytes))
    share = auto["blob_bytes"] / full_blob_bytes
    package_share = auto["bytes"] / full_bytes
    point, _, n, _ = compare_raws(os.path.join(work, "auto.raw"), os.path.join(work, "full.raw"), 1)
    # The same two levels at 4x4 samples a pixel.
    big = "%dx%d" % (W * SUPERSAMPLE, H * SUPERSAMPLE)
    render(str(level), big, os.path.join(work, "auto4.raw"))
    render("0", big, os.path.join(work, "full4.raw"))
    _, differ, n, covered = compare_raws(os.path.join(work, "auto4.raw"),
                                         os.path.join(work, "full4.raw"), SUPERSAMPLE)
    if not os.environ.get("KEEP_WORK"):
        for r in ("auto", "full", "auto4", "full4"):
            os.remove(os.path.join(work, r + ".raw"))
    print("%d vertices, %s m tiles, levels 1..%d (build %.1f s); view %.0f x %.0f m at %dx%d "
          "(%.2f m pixels)" % (vertices, tile, len(levels), build_s, 2 * half_w, 2 * half_h, W, H,
                               pixel))
    print("package bytes per level: " + ", ".join("L%d %d" % kv for kv in sorted(level_bytes.items())))
    print("auto: level %d, %d tiles, %d blob bytes uploaded (%.3f%% of full detail's %d); %d "
          "package bytes loaded (%.3f%% of %d), CPU frame %.1f ms"
          % (level, auto["tiles"], auto["blob_bytes"], 100 * share, full_blob_bytes, auto["bytes"],
             100 * package_share, full_bytes, auto["frame_ms"]))
    print("full: %d level-0 tiles, %d bytes (%d blob bytes), CPU frame %.1f ms"
          % (full["tiles"], full["bytes"], full["blob_bytes"], full["frame_ms"]))
    print("pixels differing, box-filtered 4x4 (> 1/8): %d of %d (%.3f%%); point-sampled (> 1/255): "
          "%d (%.3f%%); pixels with a decal at full detail: %d (%.1f%%)"
          % (differ, n, 100.0 * differ / n, point, 100.0 * point / n, covered, 100.0 * covered / n))
    if gl:
        for name, lv in (("auto", "auto"), ("full", "0")):
            p = subprocess.run([tool, "render", ts, "--extent", extent_arg, "--size", size,
                                "--flat", "--level", lv, "--stats", "-o",
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
        fail("the whole-extent view uploads %.2f%% of the full-detail blob bytes (limit %.0f%%)"
             % (100 * share, 100 * MAX_BYTES_SHARE))
    if differ >= MAX_PIXELS_SHARE * n:
        fail("%d box-filtered pixels (%.2f%%) differ from full detail (limit %.0f%%)"
             % (differ, 100.0 * differ / n, 100 * MAX_PIXELS_SHARE))
    if point >= MAX_PIXELS_SHARE * n:
        fail("%d point-sampled pixels (%.2f%%) differ from full detail (limit %.0f%%)"
             % (point, 100.0 * point / n, 100 * MAX_PIXELS_SHARE))
    if not os.environ.get("KEEP_WORK"):
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
