#!/usr/bin/env python3
"""A world-spanning polygon layer (spData's world.gpkg, from the Debian
package r-cran-spdata; scripts/fetch-data) builds as a tileset with no option
but --tile-size, and its CPU top-down render covers what gdal_rasterize
burns from the same layer reprojected (ogr2ogr) into the tileset's frame CRS:
the mismatch outside a one-pixel band around the rasterised boundaries stays
below 1e-3. The GL render of the same view, at full detail and from the
overview level 1 (tiles of 4,000 km), keeps the same bound: tiles up to
17,000 km from the eye, and tiles wider than the 2,147 km an int32 of
millimetres spans from their origin, are drawn where they lie.

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
    run([tool, "build", world, "-o", tiles, "--tile-size", "2000000", "--levels", "1", "-q"])
    run([tool, "verify", tiles])
    ix = json.load(open(os.path.join(tiles, "tileset.json")))
    xmin, ymin, xmax, ymax = ix["extent"]
    # The view: the data's box, grown to the image's aspect.
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    half_w = max((xmax - xmin) / 2, (ymax - ymin) / 2 * W / H) * 1.02
    half_h = half_w * H / W
    view = (cx - half_w, cy - half_h, cx + half_w, cy + half_h)
    ext = "%.6f,%.6f,%.6f,%.6f" % view

    def drawn_by(name, args):
        """Which pixels a render of the view covers (its --raw alpha)."""
        raw = os.path.join(work, name + ".raw")
        run([tool, "render", tiles, "--flat", "--extent", ext, "--size", "%dx%d" % (W, H),
             "-o", os.path.join(work, name + ".png"), "--raw", raw] + args)
        data = open(raw, "rb").read()
        return [1 if a > 0 else 0 for a in struct.unpack("<%df" % (4 * W * H), data)[3::4]]

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

    outside = [k for k in range(W * H) if not band(k)]
    burnt = sum(burn[k] for k in outside)
    if burnt < W * H // 10:
        print("FAIL: gdal_rasterize burnt too little: the view misses the world")
        return 1
    failed = 0
    for name, args in (("cpu", ["--cpu", "--level", "0"]), ("gl", ["--level", "0"]),
                       ("gl_level1", ["--level", "1"])):
        drawn = drawn_by(name, args)
        mismatched = sum(1 for k in outside if drawn[k] != burn[k])
        frac = mismatched / len(outside)
        print("world.gpkg, %s: %d tiles, frame %s; %d of %d pixels outside the band differ "
              "(%.2e), %d burnt" % (name, len(ix["tiles"]), ix["frame"]["description"], mismatched,
                                    len(outside), frac, burnt))
        if frac >= 1e-3:
            print("FAIL: %s: mismatch %.2e >= 1e-3" % (name, frac))
            failed = 1
    return failed


if __name__ == "__main__":
    sys.exit(main())
