#!/usr/bin/env python3
"""Minimum widths on a tileset's overview (formats/SPEC.md "Minimum widths").

Liechtenstein's OSM waterways (the shared extract), drawn 3 m wide with
min_width_px = 2, built as a tileset of 4 km tiles with overview levels;
the whole extent rendered top-down at 88 m pixels (--level auto draws the
coarsest level there), with --cpu and, where there is headless GL, GL.

The oracle is the source geometry read by GDAL (OGR) and transformed into
the tileset's frame by PROJ, not the package: at every pixel column that
crosses a waterway's centre line, the covered run of the --decals image
(alpha > 1/2) in that column that holds the crossing must be at least 2
pixels long. Parts shorter than the coarsest level's min_length are left
out (the level drops them, "Overview levels"). Prints the columns checked
and the shortest run. Without the minimum (the same build without the key)
the runs are at most 1 pixel: the check can fail.

Usage: min_width_overview_test.py DECALPREP SHARED_DATA WORKDIR
Exit 77 (skip) without /usr/bin/python3's GDAL bindings and numpy or the
shared data.
"""
import json
import math
import os
import shutil
import subprocess
import sys

try:
    import numpy as np
    from osgeo import gdal, ogr, osr
except ImportError:
    print("skip: needs numpy and GDAL's Python bindings (python3-gdal)")
    sys.exit(77)

TOOL, DATA, WORK = sys.argv[1], sys.argv[2], sys.argv[3]
PBF = os.path.join(DATA, "liechtenstein", "liechtenstein-2013-08-03.osm.pbf")
WHERE = "waterway IN ('river', 'stream', 'canal')"
PX, N = 88.0, 2
if not os.path.exists(PBF):
    print("skip: no shared data at " + PBF)
    sys.exit(77)
gdal.UseExceptions()


def build(folder, min_width):
    os.makedirs(folder)
    with open(os.path.join(folder, "scene.toml"), "w") as f:
        f.write('[[layer]]\nname = "waterways"\nsource = "%s"\nlayer = "lines"\nwhere = "%s"\n'
                'kind = "line"\nwidth = 3\ncolor = "#2060ff"\n%s'
                % (PBF, WHERE, "min_width_px = %d\n" % N if min_width else ""))
    out = os.path.join(folder, "ts")
    r = subprocess.run([TOOL, "build", os.path.join(folder, "scene.toml"), "-o", out,
                        "--tile-size", "4000", "--levels", "auto", "-q"],
                       capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        sys.exit("build failed: " + r.stdout + r.stderr)
    return out


def render(ts, name, gl):
    index = json.load(open(os.path.join(ts, "tileset.json")))
    x0, y0, x1, y1 = index["extent"]
    w, h = math.ceil((x1 - x0) / PX) + 2, math.ceil((y1 - y0) / PX) + 2
    ext = (x0 - PX, y0 - PX, x0 - PX + w * PX, y0 - PX + h * PX)  # 88 m pixels exactly
    png = os.path.join(os.path.dirname(ts), name + ".png")
    decals = os.path.join(os.path.dirname(ts), name + "-decals.png")
    cmd = [TOOL, "render", ts, "--extent", ",".join("%.6f" % v for v in ext),
           "--size", "%dx%d" % (w, h), "--aa", "none", "-o", png, "--decals", decals]
    if not gl:
        cmd.append("--cpu")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        return None, r.stderr
    image = gdal.Open(decals)  # kept open while its band is read
    alpha = image.GetRasterBand(4).ReadAsArray().astype(np.float64) / 255.0
    image = None
    return (ext, alpha, index), ""


def centre_lines(index):
    """The waterways' parts in the tileset's frame, as point lists."""
    frame = osr.SpatialReference()
    frame.ImportFromWkt(index["frame"]["crs_wkt"])
    frame.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ox, oy = index["frame"].get("origin", [0.0, 0.0])
    ds = ogr.Open(PBF)
    layer = ds.GetLayerByName("lines")
    layer.SetAttributeFilter(WHERE)
    src = layer.GetSpatialRef()
    src.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ct = osr.CoordinateTransformation(src, frame)
    parts = []
    for feat in layer:
        g = feat.GetGeometryRef().Clone()
        g.Transform(ct)
        singles = [g.GetGeometryRef(i) for i in range(g.GetGeometryCount())] \
            if g.GetGeometryType() in (ogr.wkbMultiLineString, ogr.wkbMultiLineString25D) else [g]
        for s in singles:
            parts.append([(s.GetX(i) + ox, s.GetY(i) + oy) for i in range(s.GetPointCount())])
    return parts


def runs_at_crossings(ext, alpha, parts, min_length):
    """(columns checked, shortest run, runs below N) over every column
    crossing of every part at least min_length long."""
    h, w = alpha.shape
    covered = alpha > 0.5
    checked, shortest, short = 0, 1 << 30, []
    for pts in parts:
        length = sum(math.dist(pts[k], pts[k + 1]) for k in range(len(pts) - 1))
        if length < min_length:
            continue
        for (ax, ay), (bx, by) in zip(pts, pts[1:]):
            if ax == bx:
                continue
            lo, hi = min(ax, bx), max(ax, bx)
            i0 = math.ceil((lo - ext[0]) / PX - 0.5)
            i1 = math.floor((hi - ext[0]) / PX - 0.5)
            for i in range(max(i0, 0), min(i1, w - 1) + 1):
                xc = ext[0] + (i + 0.5) * PX
                if not lo <= xc <= hi:
                    continue
                y = ay + (xc - ax) / (bx - ax) * (by - ay)
                j = int((ext[3] - y) / PX)
                if not 0 <= j < h:
                    continue
                # The run holding the crossing's pixel (or its neighbour
                # when the centre line passes a pixel edge).
                start = j if covered[j, i] else (j - 1 if j > 0 and covered[j - 1, i] else
                                                 (j + 1 if j + 1 < h and covered[j + 1, i] else None))
                run = 0
                if start is not None:
                    a = b = start
                    while a > 0 and covered[a - 1, i]:
                        a -= 1
                    while b + 1 < h and covered[b + 1, i]:
                        b += 1
                    run = b - a + 1
                checked += 1
                shortest = min(shortest, run)
                if run < N:
                    short.append((i, j, run))
    return checked, shortest, short


def main():
    shutil.rmtree(WORK, ignore_errors=True)
    os.makedirs(WORK)
    ts = build(os.path.join(WORK, "min"), True)
    plain = build(os.path.join(WORK, "plain"), False)
    failed = False
    for gl in (False, True):
        what = "gl" if gl else "cpu"
        got, why = render(ts, what, gl)
        if got is None:
            if gl:
                print("gl: skipped (no headless GL: %s)" % why.strip().splitlines()[-1:])
                continue
            sys.exit("render --cpu failed: " + why)
        ext, alpha, index = got
        coarsest = max(index["levels"], key=lambda l: l["level"])
        parts = centre_lines(index)
        checked, shortest, short = runs_at_crossings(ext, alpha, parts, coarsest["min_length_m"])
        print("%s: %d x %d pixels of %g m; coarsest level %d (resolution %g m); %d waterway parts; "
              "%d column crossings checked, shortest run %d px, %d below %d px"
              % (what, alpha.shape[1], alpha.shape[0], PX, coarsest["level"],
                 coarsest["resolution_m"], len(parts), checked, shortest, len(short), N))
        if checked < 200 or short:
            print("  FAIL: %s" % short[:10])
            failed = True
    # The same without min_width_px: 3 m at 88 m pixels is mostly nothing.
    got, why = render(plain, "plain-cpu", False)
    if got is None:
        sys.exit("render --cpu failed: " + why)
    ext, alpha, index = got
    checked, shortest, short = runs_at_crossings(ext, alpha, centre_lines(index), 0)
    print("without min_width_px (cpu): %d of %d column crossings below %d px"
          % (len(short), checked, N))
    if len(short) < checked // 2:
        print("  FAIL: the control is not thin")
        failed = True
    sys.exit(1 if failed else 0)


main()
