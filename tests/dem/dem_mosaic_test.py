#!/usr/bin/python3
"""A DEM mosaic (scene file dem = [...], --dem repeated) end to end, on the
real SRTM tile of the shared data cut into two tiles that share one column,
as adjacent SRTM tiles share their edge column:

- the heights decalprep uses (the terrain file's mesh, `decalprep terrain`,
  read back by terrain_dump) equal, within 1 mm, GDAL's bilinear kernel
  computed here from the raw cells of the VRT that the gdalbuildvrt CLI
  makes of the two tiles, at every mesh vertex, those along and across the
  shared column included; that VRT's cells equal the unsplit tile's;
- the package records the list, and `terrain` finds the DEM from it;
- --dem repeated gives the same surface as the scene's list;
- a tile whose no-data cells lie over its neighbour's data leaves that data
  in place (per-source no-data);
- a tile in another CRS is refused, naming both tiles and both CRSs;
- a single-string dem is recorded as a string, as before mosaics.

Usage: dem_mosaic_test.py DECALPREP TERRAIN_DUMP SHARED_DATA WORKDIR
Exit 77 (skip) without the shared data, numpy or GDAL's Python bindings."""
import json
import os
import shutil
import subprocess
import sys

try:
    import numpy as np
    from osgeo import gdal, osr
except ImportError as e:
    print(f"SKIP: {sys.executable} lacks numpy or osgeo ({e})")
    sys.exit(77)

tool, dump, shared, work = (os.path.abspath(a) for a in sys.argv[1:5])
zip_path = os.path.join(shared, "monaco", "N43E007.hgt.zip")
pbf = os.path.join(shared, "monaco", "monaco.osm.pbf")
for f in (zip_path, pbf):
    if not os.path.exists(f):
        print(f"SKIP: {f} missing (shared data)")
        sys.exit(77)
if not shutil.which("gdalbuildvrt"):
    print("SKIP: the gdalbuildvrt CLI is missing")
    sys.exit(77)
gdal.UseExceptions()
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
failures = []


def expect(what, ok, detail=""):
    print(("ok   " if ok else "FAIL ") + what + ("" if ok else ": " + detail))
    if not ok:
        failures.append(what)


def run(args, ok=True):
    r = subprocess.run(args, cwd=work, capture_output=True, text=True)
    if ok and r.returncode != 0:
        sys.exit(f"{' '.join(args)} exited {r.returncode}:\n{r.stderr}")
    return r


# Two tiles of the 3" tile (1201 x 1201): columns 0..504 and 504..1200 of
# rows 200..499; column 504 (longitude 7.42) in both. GeoTIFF keeps the
# tile's CRS and no-data.
tile = "/vsizip/" + zip_path + "/N43E007.hgt"
border_col, rows = 504, (200, 300)
gdal.Translate(os.path.join(work, "left.tif"), tile,
               srcWin=[0, rows[0], border_col + 1, rows[1]])
gdal.Translate(os.path.join(work, "right.tif"), tile,
               srcWin=[border_col, rows[0], 1201 - border_col, rows[1]])
border_lon = 7.0 + border_col / 1200.0

scene = """source = "{pbf}"
dem = {dem}
extent = [7.405, 43.728, 7.435, 43.742]
extent_crs = "EPSG:4326"
crs = "EPSG:32632"

[[layer]]
name = "roads"
layer = "lines"
where = "highway IS NOT NULL"
kind = "line"
width = 4
dynamic = true
"""


def build(name, dem, extra=()):
    with open(os.path.join(work, name + ".toml"), "w") as f:
        f.write(scene.format(pbf=pbf, dem=dem))
    return run([tool, "build", name + ".toml", "-o", name + ".decals", *extra], ok=False)


def metadata(package):
    r = run([tool, "info", package, "--json"])
    return json.loads(r.stdout)["metadata"]


def mesh(package, extra=()):
    out = package + ".terrain"
    run([tool, "terrain", package, "-o", out, "-q", *extra])
    return json.loads(run([dump, out]).stdout)


r = build("mosaic", '["left.tif", "right.tif"]')
expect("dem = [left, right] builds", r.returncode == 0, r.stderr)
if r.returncode != 0:
    sys.exit(1)
recorded = metadata("mosaic.decals")["build_options"]["dem"]
expect("the package records the list", recorded == ["left.tif", "right.tif"], str(recorded))
m = mesh("mosaic.decals")

# The oracle: gdalbuildvrt's VRT of the two tiles, GDAL's bilinear kernel
# (cell centres at i + 0.5, the edge cell beyond the outermost centres).
subprocess.run(["gdalbuildvrt", "-q", "oracle.vrt", "left.tif", "right.tif"], cwd=work, check=True)
vrt = gdal.Open(os.path.join(work, "oracle.vrt"))
band = vrt.GetRasterBand(1)
cells = band.ReadAsArray().astype(np.float64)
nodata = band.GetNoDataValue()
src = gdal.Open(tile)  # kept: a band outlives no dataset in GDAL's Python
whole = src.GetRasterBand(1).ReadAsArray(0, rows[0], 1201, rows[1]).astype(np.float64)
expect("the VRT of the two tiles holds the unsplit tile's cells", np.array_equal(cells, whole))
gt = vrt.GetGeoTransform()
frame = osr.SpatialReference()
frame.ImportFromEPSG(32632)
dem_srs = vrt.GetSpatialRef()
for s in (frame, dem_srs):
    s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
to_dem = osr.CoordinateTransformation(frame, dem_srs)

h, w = cells.shape
checked = near_border = across = 0
worst = 0.0
for j in range(m["ny"]):
    for i in range(m["nx"]):
        x = m["origin_x"] + m["x0"] + i * m["dx"]
        y = m["origin_y"] + m["y0"] + j * m["dy"]
        lon, lat, _ = to_dem.TransformPoint(x, y)
        px = (lon - gt[0]) / gt[1] - 0.5
        py = (lat - gt[3]) / gt[5] - 0.5
        fx, fy = np.floor(px), np.floor(py)
        tx, ty = px - fx, py - fy
        i0, i1 = int(np.clip(fx, 0, w - 1)), int(np.clip(fx + 1, 0, w - 1))
        j0, j1 = int(np.clip(fy, 0, h - 1)), int(np.clip(fy + 1, 0, h - 1))
        stencil = [cells[j0, i0], cells[j0, i1], cells[j1, i0], cells[j1, i1]]
        if nodata is not None and nodata in stencil:
            continue  # decalprep fills voids; the oracle has no such rule
        a, b, c, d = stencil
        want = (1 - ty) * ((1 - tx) * a + tx * b) + ty * ((1 - tx) * c + tx * d)
        got = m["z"][i + m["nx"] * j]
        worst = max(worst, abs(got - want))
        checked += 1
        if abs(px + 0.5 - (border_col + 0.5)) < 2:
            near_border += 1
            across += i0 != i1 and border_col in (i0, i1)  # one cell on each side
expect(f"mesh heights equal the gdalbuildvrt VRT's bilinear within 1 mm ({checked} vertices, "
       f"{near_border} within 2 cells of the shared column, {across} with a stencil across it; "
       f"worst {worst:.2e} m)",
       checked > 400 and near_border >= 20 and across >= 10 and worst <= 1e-3,
       f"checked {checked}, near {near_border}, across {across}, worst {worst}")

# --dem repeated on the command line: the surface of the scene's list.
r = build("cli", '"left.tif"', ["--dem", "left.tif", "--dem", "right.tif"])
expect("build --dem A --dem B builds", r.returncode == 0, r.stderr)
recorded = metadata("cli.decals")["build_options"]["dem"]
expect("build --dem A --dem B records both", recorded == ["left.tif", "right.tif"], str(recorded))
expect("build --dem A --dem B drapes like dem = [A, B]", mesh("cli.decals")["z"] == m["z"])
z = mesh("mosaic.decals", ["--dem", "left.tif", "--dem", "right.tif"])["z"]
expect("terrain --dem A --dem B gives the recorded mosaic's heights", z == m["z"])

# Per-source no-data: the right tile's shared column made void; the left
# tile's cells there stay, so the surface is unchanged.
drv = gdal.GetDriverByName("GTiff")
right = gdal.Open(os.path.join(work, "right.tif"))
hole = drv.CreateCopy(os.path.join(work, "right_void.tif"), right)
col = hole.GetRasterBand(1).ReadAsArray()
col[:, 0] = -32768
hole.GetRasterBand(1).WriteArray(col)
hole = None
r = build("void", '["left.tif", "right_void.tif"]')
expect("dem = [left, right with a void column] builds", r.returncode == 0, r.stderr)
expect("a tile's no-data over its neighbour's data leaves that data (per-source no-data)",
       r.returncode == 0 and mesh("void.decals")["z"] == m["z"])

# A tile in another CRS: refused, naming both tiles and both CRSs.
gdal.Translate(os.path.join(work, "right_utm.tif"), os.path.join(work, "right.tif"),
               outputSRS="EPSG:32632")
r = build("crs", '["left.tif", "right_utm.tif"]')
msg = r.stderr
expect("a tile in another CRS is refused (exit 3, no package)",
       r.returncode == 3 and not os.path.exists(os.path.join(work, "crs.decals")),
       f"exit {r.returncode}: {msg}")
expect("the refusal names both tiles and both CRSs",
       "right_utm.tif: CRS EPSG:32632 differs from" in msg and "left.tif's EPSG:4326" in msg, msg)

# One raster as a string: recorded as a string, as before mosaics.
r = build("single", '"left.tif"')
recorded = metadata("single.decals")["build_options"]["dem"]
expect("a single-string dem builds and is recorded as a string",
       r.returncode == 0 and recorded == "left.tif", f"{r.stderr} {recorded!r}")

if failures:
    sys.exit(f"{len(failures)} failed: " + "; ".join(failures))
print("all passed")
