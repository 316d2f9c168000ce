"""render (and the build's DEM and --extent checks) against hostile input:
a DEM that is a FIFO (given with --dem or named by a package), a package
naming a network DEM, cameras and sizes that draw a blank image, a DEM that
does not cover the view or the data, an --extent in degrees read as metres,
and a PNG target that is a FIFO, the package or the DEM.

Every render here uses --cpu (the CPU evaluator), so no EGL display is
needed and nothing is skipped for want of one.

python3 render_test.py DECALPREP WORK_DIR [SOURCE_DIR]
"""
import hashlib
import http.server
import os
import socketserver
import sys
import threading

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from safety import Failure, Skip, Suite, write_polygons_geojson  # noqa: E402

suite = Suite(sys.argv)

WGS84_PRJ = ('GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137,'
             '298.257223563]],PRIMEM["Greenwich",0],UNIT["Degree",0.0174532925199433]]')


def write_dem(path, lon0, lat0, n=40, cell=0.001, slope=2.0):
    """An n x n ESRI ASCII grid in WGS84 (a .prj beside it), lower-left
    corner at (lon0, lat0), heights rising eastwards: a real raster GDAL
    reads (AAIGrid), written without GDAL."""
    with open(path, "w") as f:
        f.write(f"ncols {n}\nnrows {n}\nxllcorner {lon0}\nyllcorner {lat0}\n"
                f"cellsize {cell}\nNODATA_value -9999\n")
        for _ in range(n):
            f.write(" ".join(f"{10 + slope * i:.1f}" for i in range(n)) + "\n")
    with open(os.path.splitext(path)[0] + ".prj", "w") as f:
        f.write(WGS84_PRJ)
    return path


def polygons(d):
    """Three small squares near Monaco (7.42..7.426 E, 43.73..43.731 N)."""
    return write_polygons_geojson(os.path.join(d, "squares.geojson"))


def build(d, *extra, name="squares.decals"):
    out = os.path.join(d, name)
    r = suite.run(["build", polygons(d), "-o", out, "--kind", "polygon", "-q", *extra])
    suite.expect(r, 0)
    return out


def sha(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def render(pkg, out, *extra, timeout=20):
    # An address-space cap: a size that is not refused must fail to
    # allocate, not take the shared machine's memory.
    return suite.run(["render", pkg, "--cpu", "--size", "64x48", "-o", out, *extra],
                     timeout=timeout, mem_mb=4096)


# 1. A FIFO given as --dem: refused before GDAL opens it, by build and render.
def dem_fifo_build():
    d = suite.dir("dem_fifo_build")
    fifo = os.path.join(d, "dem.asc")
    os.mkfifo(fifo)
    r = suite.run(["build", polygons(d), "-o", os.path.join(d, "o.decals"), "--kind", "polygon",
                   "--dem", fifo], timeout=15)
    suite.expect(r, 3, "FIFO", fifo)


def dem_fifo_render():
    d = suite.dir("dem_fifo_render")
    pkg = build(d)
    fifo = os.path.join(d, "dem.asc")
    os.mkfifo(fifo)
    r = render(pkg, os.path.join(d, "o.png"), "--dem", fifo, timeout=15)
    suite.expect(r, 3, "FIFO", fifo)


# 2. A package naming a DEM that is now a FIFO: not opened, flat terrain
# and a warning (exit 0), or exit 10 with --strict; never a hang.
def package_dem_fifo():
    d = suite.dir("package_dem_fifo")
    link = os.path.join(d, "dem-link.asc")
    os.symlink(write_dem(os.path.join(d, "dem.asc"), 7.41, 43.72), link)
    with open(os.path.join(d, "dem-link.prj"), "w") as f:  # GDAL looks beside the name given
        f.write(WGS84_PRJ)
    pkg = build(d, "--dem", link)
    os.remove(link)
    os.mkfifo(link)
    r = render(pkg, os.path.join(d, "o.png"), timeout=15)
    suite.expect(r, 0, "warning", link, "FIFO", "flat")
    r = render(pkg, os.path.join(d, "strict.png"), "--strict", timeout=15)
    suite.expect(r, 10, link, "FIFO")


class Recorder(http.server.SimpleHTTPRequestHandler):
    """Serves the case folder and records every request path."""
    requests = []

    def do_GET(self):
        Recorder.requests.append(self.path)
        return super().do_GET()

    def do_HEAD(self):
        Recorder.requests.append(self.path)
        return super().do_HEAD()

    def log_message(self, *args):
        pass


# 2. A package naming a /vsicurl/ DEM: render fetches nothing unless the
# user passes that path with --dem. The package is built from a local HTTP
# server, so it records the network path as a real build would.
def package_dem_network():
    d = suite.dir("package_dem_network")
    write_dem(os.path.join(d, "dem.asc"), 7.41, 43.72)
    handler = lambda *a, **k: Recorder(*a, directory=d, **k)  # noqa: E731
    with socketserver.TCPServer(("127.0.0.1", 0), handler) as server:
        threading.Thread(target=server.serve_forever, daemon=True).start()
        try:
            url = f"/vsicurl/http://127.0.0.1:{server.server_address[1]}/dem.asc"
            out = os.path.join(d, "net.decals")
            r = suite.run(["build", polygons(d), "-o", out, "--kind", "polygon", "-q",
                           "--dem", url], timeout=60)
            if r.code != 0 or not Recorder.requests:
                raise Skip(f"this GDAL cannot build from a /vsicurl/ DEM on 127.0.0.1 ({r.code}): "
                           f"{r.err.strip()[-300:]}")
            Recorder.requests.clear()
            r = render(out, os.path.join(d, "o.png"), timeout=30)
            suite.expect(r, 0, "warning", "network", "flat")
            if Recorder.requests:
                raise Failure(f"render fetched the package's DEM: {Recorder.requests}\n{r}")
            r = render(out, os.path.join(d, "strict.png"), "--strict", timeout=30)
            suite.expect(r, 10, "network")
            if Recorder.requests:
                raise Failure(f"render --strict fetched the package's DEM: {Recorder.requests}")
            # The user's own --dem may name the network.
            r = render(out, os.path.join(d, "user.png"), "--dem", url, timeout=30)
            suite.expect(r, 0)
            if not Recorder.requests:
                raise Failure(f"render --dem URL did not read the DEM\n{r}")
        finally:
            server.shutdown()


# 3. Cameras and sizes that give no image: exit 2 naming the option.
def bad_cameras():
    d = suite.dir("bad_cameras")
    pkg = build(d)
    out = os.path.join(d, "o.png")
    cases = [
        (["--pitch", "nan"], "--pitch"),
        (["--pitch", "inf"], "--pitch"),
        (["--fov", "nan", "--eye", "0,-500,300", "--target", "0,0,0"], "--fov"),
        (["--eye", "nan,0,100", "--target", "0,0,0"], "--eye"),
        (["--eye", "0,0,100", "--target", "0,0,inf"], "--target"),
        (["--eye", "10,20,100", "--target", "10,20,100"], "--eye"),
        (["--size", "4294967396x4294967396"], "--size"),
        (["--size", "100x4294967396"], "--size"),
        (["--size", "16384x16384"], "--size"),
        (["--size", "-5x10"], "--size"),
    ]
    for args, needle in cases:
        if os.path.exists(out):
            os.remove(out)
        r = render(pkg, out, *args, timeout=20)
        try:
            suite.expect(r, 2, needle)
        except Failure as f:
            raise Failure(f"render {' '.join(args)}: {f}")
        if os.path.exists(out):
            raise Failure(f"render {' '.join(args)} wrote {out}")
    # A camera looking straight down (--eye above --target) is no longer
    # degenerate: it draws the squares.
    r = render(pkg, out, "--eye", "0,0,2000", "--target", "0,0,0")
    suite.expect(r, 0)


# 4. A --dem at render time that does not cover the package: a warning
# naming the DEM, exit 10 with --strict.
def dem_not_covering_render():
    d = suite.dir("dem_not_covering_render")
    pkg = build(d)
    far = write_dem(os.path.join(d, "far.asc"), 10.0, 45.0)
    r = render(pkg, os.path.join(d, "o.png"), "--dem", far)
    suite.expect(r, 0, "warning", far, "misses")
    r = render(pkg, os.path.join(d, "s.png"), "--dem", far, "--strict")
    suite.expect(r, 10, far, "--strict")
    # A DEM over the data: no warning, and --strict passes.
    near = write_dem(os.path.join(d, "near.asc"), 7.41, 43.72)
    r = render(pkg, os.path.join(d, "n.png"), "--dem", near, "--strict")
    suite.expect(r, 0)
    if "warning" in r.err:
        raise Failure(f"a covering DEM was warned about\n{r}")
    # A top-down view beyond the package: a warning, exit 10 with --strict.
    r = render(pkg, os.path.join(d, "v.png"), "--extent", "50000,50000,51000,51000", "--strict")
    suite.expect(r, 10, "misses the package extent")


# 5. A lon/lat --extent without --extent-crs in a metre frame: exit 2
# suggesting --extent-crs EPSG:4326, in build and in render; the same
# extent with --extent-crs works.
def extent_in_degrees():
    d = suite.dir("extent_in_degrees")
    pkg = build(d)
    deg = "7.41,43.72,7.44,43.75"
    r = suite.run(["build", polygons(d), "-o", os.path.join(d, "b.decals"), "--kind", "polygon",
                   "--extent", deg])
    suite.expect(r, 2, "--extent-crs EPSG:4326")
    if os.path.exists(os.path.join(d, "b.decals")):
        raise Failure("build wrote a package for a degree extent")
    r = suite.run(["build", polygons(d), "-o", os.path.join(d, "t"), "--kind", "polygon",
                   "--extent", deg, "--tile-size", "500"])
    suite.expect(r, 2, "--extent-crs EPSG:4326")
    r = render(pkg, os.path.join(d, "r.png"), "--extent", deg)
    suite.expect(r, 2, "--extent-crs EPSG:4326")
    r = suite.run(["build", polygons(d), "-o", os.path.join(d, "ok.decals"), "--kind", "polygon",
                   "-q", "--extent", deg, "--extent-crs", "EPSG:4326"])
    suite.expect(r, 0)
    r = render(pkg, os.path.join(d, "ok.png"), "--extent", deg, "--extent-crs", "EPSG:4326")
    suite.expect(r, 0)
    # Frame metres within +-90 around the origin, the size of the data: fine.
    r = render(pkg, os.path.join(d, "m.png"), "--extent", "-80,-60,80,60")
    suite.expect(r, 0)


# 6. build: a DEM that does not overlap the data (or the --extent) is an
# input error naming the DEM, not an empty or clipped-away package.
def dem_not_overlapping_build():
    d = suite.dir("dem_not_overlapping_build")
    far = write_dem(os.path.join(d, "far.asc"), 10.0, 45.0)
    out = os.path.join(d, "o.decals")
    r = suite.run(["build", polygons(d), "-o", out, "--kind", "polygon", "--dem", far])
    suite.expect(r, 3, far, "does not overlap", "the data's extent")
    if os.path.exists(out):
        raise Failure("a package was written")
    r = suite.run(["build", polygons(d), "-o", out, "--kind", "polygon", "--dem", far,
                   "--extent", "-300,-300,300,300"])
    suite.expect(r, 3, far, "does not overlap", "--extent")
    near = write_dem(os.path.join(d, "near.asc"), 7.41, 43.72)
    r = suite.run(["build", polygons(d), "-o", out, "--kind", "polygon", "-q", "--dem", near])
    suite.expect(r, 0)


# 7. The PNG target: not a FIFO, not the package, not the DEM.
def png_target():
    d = suite.dir("png_target")
    dem = write_dem(os.path.join(d, "dem.asc"), 7.41, 43.72)
    pkg = build(d, "--dem", dem)
    before, dem_before = sha(pkg), sha(dem)
    fifo = os.path.join(d, "out.png")
    os.mkfifo(fifo)
    r = render(pkg, fifo, timeout=15)
    suite.expect(r, 7, "FIFO")
    r = render(pkg, pkg)
    suite.expect(r, 7, "input")
    r = render(pkg, dem)
    suite.expect(r, 7, "input")
    r = render(pkg, os.path.join(d, "ok.png"), "--decals", pkg)
    suite.expect(r, 7, "input")
    if sha(pkg) != before or sha(dem) != dem_before:
        raise Failure("the package or the DEM changed")


suite.case("dem_fifo_build", dem_fifo_build)
suite.case("dem_fifo_render", dem_fifo_render)
suite.case("package_dem_fifo", package_dem_fifo)
suite.case("package_dem_network", package_dem_network)
suite.case("bad_cameras", bad_cameras)
suite.case("dem_not_covering_render", dem_not_covering_render)
suite.case("extent_in_degrees", extent_in_degrees)
suite.case("dem_not_overlapping_build", dem_not_overlapping_build)
suite.case("png_target", png_target)
sys.exit(suite.finish())
