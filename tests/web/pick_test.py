#!/usr/bin/env python3
"""Picking in the browser viewer (tests/web/CMakeLists.txt, Web.Picking):
`decalprep view --screenshot --pick X,Y` names the layer and the source
feature id of the decal on top at a pixel, from the WebGPU query itself.

The oracle is the source, not the package: OGR reads the Monaco sample's
OpenStreetMap extract with each scene layer's own `where` or `sql`, PROJ
moves it into the package's frame (its crs_wkt), and GEOS decides which
features cover the pixel's centre:
  - a polygon layer covers the inside of its polygons;
  - a line layer covers the points within half its width of a line
    (plus the casing width for its casing), a point layer the points within
    half its width plus its casing of a point;
  - an outline layer covers a band of its width along the rings.
The drawing order is the scene's layer order (formats/SPEC.md "Drawing
order": a later layer is above every feature of an earlier one).

The top-down view is 640x360 pixels of 1 m. A candidate pixel qualifies when
the top layer that comes within MARGIN of its centre covers it by at least
MARGIN, through exactly one feature, and no feature of that layer or a
layer above comes within MARGIN of it otherwise (so neither the 1 mm
quantisation nor the pixel grid can change the answer). Five such pixels on
different features (polygons and lines), plus one pixel that nothing comes
near, are picked in one screenshot run; each answer must name the expected
layer and fid (formats/SPEC.md LineProps `feature`: the source FID, or
0xffffffff for one a u32 cannot hold).

--backend webgpu|webgl2 (default webgpu) is passed to `view`, whose --stats
device line must name it (Web.PickingWebGL2 picks with the WebGL2 renderer).

Usage: pick_test.py DECALPREP REPO_ROOT WORK_DIR [--backend webgpu|webgl2]   (exit 77: skip)
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pixel_agreement import SKIP, chromium  # noqa: E402
MARGIN = 1.5       # metres, 1.5 pixels
SIZE = (640, 360)  # pixels of 1 m
WANTED = ["buildings", "streets", "main_roads", "buildings", "landuse", "green", "water"]


def main():
    if len(sys.argv) not in (4, 6) or (len(sys.argv) == 6 and sys.argv[4] != "--backend"):
        print(__doc__)
        return 2
    decalprep, root, work = sys.argv[1:4]
    backend = sys.argv[5] if len(sys.argv) == 6 else "webgpu"
    try:
        from osgeo import gdal, ogr, osr
    except ImportError as e:
        print("SKIP: GDAL's Python bindings are missing (python3-gdal):", e)
        return SKIP
    if not chromium():
        print("SKIP: no Chromium (scripts/deps installs it)")
        return SKIP
    ogr.UseExceptions()
    osr.UseExceptions()
    gdal.PushErrorHandler("CPLQuietErrorHandler")  # the OSM driver's unclosed-ring warnings
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    sample = os.path.join(root, "samples", "monaco")
    pkg = os.path.join(work, "monaco.decals")
    b = subprocess.run([decalprep, "build", os.path.join(sample, "scene.toml"), "-o", pkg],
                       capture_output=True, text=True)
    if b.returncode != 0:
        print("FAIL: building the Monaco sample:", b.stderr[-2000:])
        return 1
    info = json.loads(subprocess.run([decalprep, "info", "--json", pkg], capture_output=True,
                                     text=True, check=True).stdout)
    meta = info["metadata"]
    ox, oy = meta["origin"]["x"], meta["origin"]["y"]

    with open(os.path.join(sample, "scene.toml"), "rb") as f:
        scene = tomllib.load(f)
    wgs = osr.SpatialReference()
    wgs.ImportFromEPSG(4326)
    frame = osr.SpatialReference()
    frame.ImportFromWkt(meta["crs_wkt"])
    for s in (wgs, frame):
        s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    to_frame = osr.CoordinateTransformation(wgs, frame)
    src = ogr.Open(os.path.join(sample, scene["source"]))

    # Every static layer's features in package coordinates. Dynamic lines
    # are never picked (the pick is the frame's static query); they are
    # left out.
    sources = []
    for spec in scene["layer"]:
        if spec.get("dynamic"):
            continue
        if "sql" in spec:
            lyr = src.ExecuteSQL(spec["sql"])
        else:
            lyr = src.GetLayerByName(spec["layer"])
            lyr.SetAttributeFilter(spec.get("where"))
        feats = []
        for ft in lyr:
            g = ft.GetGeometryRef()
            if g is not None:
                g = g.Clone()
                g.Transform(to_frame)
                shift(g, ox, oy)
                feats.append((g, ft.GetFID()))
        if "sql" in spec:
            src.ReleaseResultSet(lyr)
        sources.append((spec, feats))

    # The window: SIZE pixels of 1 m about a point of the largest land-use
    # polygon, where buildings (translucent) stand on land use.
    landuse = max((g for spec, feats in sources if spec["name"] == "landuse" for g, _ in feats),
                  key=lambda g: g.GetArea())
    c = landuse.PointOnSurface()
    xmin, ymax = round(c.GetX()) - SIZE[0] / 2, round(c.GetY()) + SIZE[1] / 2
    window = ogr.CreateGeometryFromWkt(
        "POLYGON((%f %f,%f %f,%f %f,%f %f,%f %f))" % (
            xmin - 20, ymax + 20, xmin + SIZE[0] + 20, ymax + 20, xmin + SIZE[0] + 20,
            ymax - SIZE[1] - 20, xmin - 20, ymax - SIZE[1] - 20, xmin - 20, ymax + 20))

    # Every drawn feature near the window, by layer from the bottom:
    # (layer name, [(what it covers as a GEOS geometry, fid)], dashed).
    layers = []
    for spec, source_feats in sources:
        kind, width = spec["kind"], float(spec.get("width", 0))
        casing = float(spec.get("casing_width", 0))
        feats, casings = [], []
        for g, fid in source_feats:
            if not g.Intersects(window):
                continue
            if kind == "polygon":
                feats.append((g, fid))
            elif kind == "outline":
                feats.append((g.Boundary().Buffer(width, 8), fid))
            else:
                feats.append((g.Buffer(width / 2, 8), fid))
            if casing > 0:
                casings.append((g.Buffer(width / 2 + casing, 8), fid))
        # A casing is a layer of its own, just below its layer (the package's
        # layer table names it LAYER.casing).
        if casings:
            layers.append((spec["name"] + ".casing", casings, False))
        layers.append((spec["name"], feats, bool(spec.get("dash"))))
    print("oracle: %d layers, %d features near the window" % (
        len(layers), sum(len(f) for _, f, _ in layers)))

    picks = choose_picks(layers, xmin, ymax, ogr)
    if len(picks) < 6:
        print("FAIL: the oracle found only %d unambiguous pixels" % len(picks))
        return 1
    extent = "%f,%f,%f,%f" % (xmin + ox, ymax - SIZE[1] + oy, xmin + SIZE[0] + ox, ymax + oy)
    cmd = [decalprep, "view", pkg, "--screenshot", os.path.join(work, "pick.png"),
           "--extent", extent, "--size", "%dx%d" % SIZE, "--backend", backend, "--stats"]
    for (px, py), _ in picks:
        cmd += ["--pick", "%d,%d" % (px, py)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    print(r.stdout[-3000:], r.stderr[-3000:])
    if r.returncode != 0 and ("Chromium" in r.stderr or "WebGPU" in r.stderr):
        print("SKIP: the browser cannot draw here (exit %d)" % r.returncode)
        return SKIP
    if r.returncode != 0:
        print("FAIL: view --screenshot --pick exited %d" % r.returncode)
        return 1
    device = {"webgpu": "WebGPU", "webgl2": "WebGL2"}.get(backend, backend)
    if not re.search(r"^device: %s " % device, r.stdout, re.M):
        print("FAIL: --backend %s, but the page drew with another device" % backend)
        return 1
    got = {}
    for line in r.stdout.splitlines():
        m = re.match(r"pick (\d+),(\d+): (?:(line|polygon), layer \d+ '([^']*)', fid (\d+)|no decal)$", line)
        if m:
            got[(int(m.group(1)), int(m.group(2)))] = (m.group(4), int(m.group(5))) if m.group(3) else None
    failures = 0
    for (px, py), want in picks:
        have = got.get((px, py), "missing")
        ok = have == want
        failures += not ok
        print("%s pixel %d,%d: expected %s, the viewer says %s" % (
            "ok  " if ok else "FAIL", px, py, describe(want), describe(have)))
    print("%d of %d picks agree with the source" % (len(picks) - failures, len(picks)))
    return 1 if failures else 0


def shift(g, ox, oy):
    """Moves g by -origin: frame CRS to package coordinates."""
    if not (ox or oy):
        return
    for i in range(g.GetGeometryCount()):
        shift(g.GetGeometryRef(i), ox, oy)
    for i in range(g.GetPointCount()):
        g.SetPoint_2D(i, g.GetX(i) - ox, g.GetY(i) - oy)


def stored_id(fid):
    """The id a package stores for a source FID (formats/SPEC.md LineProps)."""
    return fid if 0 <= fid <= 0xFFFFFFFE else 0xFFFFFFFF


def describe(v):
    if v is None:
        return "no decal"
    if v == "missing":
        return "no answer"
    return "layer '%s' fid %d" % v


def verdict(layers, x, y, ogr):
    """The expected answer at (x, y): ("name", fid), None (no decal), or
    "ambiguous" when the pixel grid or the quantisation could change it."""
    return stacked_verdict(layers, x, y, ogr)[0]


def stacked_verdict(layers, x, y, ogr):
    """verdict(), and whether a feature of a lower layer covers (x, y) too."""
    p = ogr.Geometry(ogr.wkbPoint)
    p.AddPoint_2D(x, y)
    for top, (name, feats, dashed) in reversed(list(enumerate(layers))):
        near, inside = [], []
        for cover, fid in feats:
            d = cover.Distance(p)
            if d >= MARGIN:
                continue
            near.append(fid)
            if d == 0 and cover.Boundary().Distance(p) >= MARGIN:
                inside.append(fid)
        if not near:
            continue
        # The top layer near the pixel decides: one feature, deep inside, and
        # not dashed (a gap could fall on the pixel).
        if len(near) == 1 and len(inside) == 1 and not dashed:
            below = any(cover.Distance(p) == 0 for _, fs, _ in layers[:top] for cover, _ in fs)
            return (name, stored_id(inside[0])), below
        return "ambiguous", False
    return None, False


def choose_picks(layers, xmin, ymax, ogr):
    """Six pixels: five features of the WANTED layers (each at most once;
    where one can be found, one that lies over a feature of a lower layer,
    so that a pick of the bottom decal instead of the top one shows) and
    one pixel with no decal, in a fixed scan order."""
    by_name = {name: feats for name, feats, _ in layers}
    picks, used, stacked = [], set(), []
    for name in WANTED:
        if len(picks) == 5:
            break
        best = None
        for cover, fid in by_name.get(name, []):
            if (name, fid) in used:
                continue
            c = cover.PointOnSurface()
            px, py = int(c.GetX() - xmin), int(ymax - c.GetY())
            if not (8 <= px < SIZE[0] - 8 and 8 <= py < SIZE[1] - 8):
                continue
            want, below = stacked_verdict(layers, xmin + px + 0.5, ymax - py - 0.5, ogr)
            if want == (name, stored_id(fid)):
                if best is None or below:
                    best = ((px, py), want, fid, below)
                if below:
                    break
        if best:
            picks.append(best[:2])
            used.add((name, best[2]))
            if best[3]:
                stacked.append(name)
    print("oracle: %d of %d picks lie over a lower layer's feature (%s)" % (
        len(stacked), len(picks), ", ".join(stacked)))
    # A translucent building over land use is what tells the top decal from
    # the last one composited.
    if "buildings" not in stacked:
        print("FAIL: no building over a lower layer's feature in the window")
        return []
    for py in range(20, SIZE[1] - 20, 17):
        for px in range(20, SIZE[0] - 20, 23):
            if verdict(layers, xmin + px + 0.5, ymax - py - 0.5, ogr) is None:
                picks.append(((px, py), None))
                return picks
    return picks


if __name__ == "__main__":
    sys.exit(main())
