#!/usr/bin/env python3
"""A world-spanning polygon layer (spData's world.gpkg, from the Debian
package r-cran-spdata; scripts/fetch-data) builds as a tileset with no option
but --tile-size, and its CPU top-down render covers what gdal_rasterize
burns from the same layer reprojected (ogr2ogr) into the tileset's frame CRS:
the mismatch outside a one-pixel band around the rasterised boundaries stays
below 1e-3.

Usage: tileset_world_test.py DECALPREP WORLD_GPKG WORK_DIR
Exit 0 on success, 1 on failure, 77 (ctest SKIP_RETURN_CODE) when the
world layer is missing (scripts/fetch-data makes it).
"""
import json
import os
import shutil
import struct
import subprocess
import sys

W, H = 900, 450


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit("FAIL: %s: exit %d\n%s%s" % (" ".join(cmd), r.returncode, r.stdout, r.stderr))
    return r


def main():
    tool, world, work = sys.argv[1:4]
    if not os.path.exists(world):
        print("SKIP: %s is missing (scripts/fetch-data makes it)" % world)
        return 77
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    tiles = os.path.join(work, "world")
    run([tool, "build", world, "-o", tiles, "--tile-size", "2000000", "-q"])
    run([tool, "verify", tiles])
    ix = json.load(open(os.path.join(tiles, "tileset.json")))
    xmin, ymin, xmax, ymax = ix["extent"]
    # The view: the data's box, grown to the image's aspect.
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    half_w = max((xmax - xmin) / 2, (ymax - ymin) / 2 * W / H) * 1.02
    half_h = half_w * H / W
    view = (cx - half_w, cy - half_h, cx + half_w, cy + half_h)
    ext = "%.6f,%.6f,%.6f,%.6f" % view
    raw = os.path.join(work, "world.raw")
    run([tool, "render", tiles, "--cpu", "--flat", "--extent", ext, "--size", "%dx%d" % (W, H),
         "-o", os.path.join(work, "world.png"), "--raw", raw])
    data = open(raw, "rb").read()
    alpha = struct.unpack("<%df" % (4 * W * H), data)[3::4]
    drawn = [1 if a > 0 else 0 for a in alpha]

    wkt = os.path.join(work, "frame.wkt")
    open(wkt, "w").write(ix["frame"]["crs_wkt"])
    proj = os.path.join(work, "world_frame.gpkg")
    run(["ogr2ogr", "-f", "GPKG", proj, world, "-t_srs", wkt, "-nln", "world"])
    burn_path = os.path.join(work, "burn.bin")
    run(["gdal_rasterize", "-q", "-burn", "1", "-init", "0", "-ot", "Byte", "-of", "ENVI",
         "-te", "%.6f" % view[0], "%.6f" % view[1], "%.6f" % view[2], "%.6f" % view[3],
         "-ts", str(W), str(H), "-l", "world", proj, burn_path])
    burn = open(burn_path, "rb").read()
    if len(burn) != W * H:
        print("FAIL: gdal_rasterize wrote %d bytes, expected %d" % (len(burn), W * H))
        return 1

    def band(k):
        i, j = k % W, k // W
        v = burn[k]
        for dj in (-1, 0, 1):
            for di in (-1, 0, 1):
                ii, jj = i + di, j + dj
                if 0 <= ii < W and 0 <= jj < H and burn[ii + W * jj] != v:
                    return True
        return False

    considered = mismatched = burnt = 0
    for k in range(W * H):
        if band(k):
            continue
        considered += 1
        burnt += burn[k]
        if drawn[k] != burn[k]:
            mismatched += 1
    frac = mismatched / considered
    print("world.gpkg: %d tiles, frame %s; %d of %d pixels outside the band differ (%.2e), "
          "%d burnt" % (len(ix["tiles"]), ix["frame"]["description"], mismatched, considered, frac,
                        burnt))
    if burnt < W * H // 10:
        print("FAIL: gdal_rasterize burnt too little: the view misses the world")
        return 1
    if frac >= 1e-3:
        print("FAIL: mismatch %.2e >= 1e-3" % frac)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
