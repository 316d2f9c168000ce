#!/usr/bin/env python3
"""A package's bytes do not depend on where the checkout is: one scene (a
GeoJSON source of polygons and dynamic lines, a DEM inside a zip, read
through /vsizip/) copied into two checkout folders at different depths,
built once with an absolute scene path and once with a relative one from
another working folder, gives cmp-identical packages; `render` still
finds the recorded DEM from a third working folder, and the file-less form
is location-independent too.

  determinism_test.py DECALPREP WORK_DIR SOURCE_DIR
"""
import filecmp
import os
import shutil
import sys
import zipfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import safety  # noqa: E402
from safety import Failure  # noqa: E402

suite = safety.Suite(sys.argv)


def write_dem(path, lon0=7.41, lat0=43.72, n=40, cell=0.001):
    """An ESRI ASCII grid over the data, a ramp (no CRS: assume_crs)."""
    with open(path, "w") as f:
        f.write(f"ncols {n}\nnrows {n}\nxllcorner {lon0}\nyllcorner {lat0}\ncellsize {cell}\n")
        for j in range(n):
            f.write(" ".join(str(50 + 2 * i + j) for i in range(n)) + "\n")


def make_scene(folder):
    """data/ with the sources and the zipped DEM, scenes/scene.toml naming
    them by relative paths, as a checkout holds them."""
    data, scenes = os.path.join(folder, "data"), os.path.join(folder, "scenes")
    os.makedirs(data)
    os.makedirs(scenes)
    safety.write_polygons_geojson(os.path.join(data, "p.geojson"))
    safety.write_lines_geojson(os.path.join(data, "l.geojson"))
    write_dem(os.path.join(data, "dem.asc"))
    # The zip member gets a fixed date: zip headers hold the file's time
    # (2 s steps), and the sources' hashes are recorded, so two checkouts
    # made on either side of a 2 s step would hold different DEM bytes.
    with open(os.path.join(data, "dem.asc"), "rb") as f:
        member = zipfile.ZipInfo("dem.asc", date_time=(2020, 1, 1, 0, 0, 0))
        with zipfile.ZipFile(os.path.join(data, "dem.zip"), "w") as z:
            z.writestr(member, f.read())
    os.remove(os.path.join(data, "dem.asc"))
    with open(os.path.join(scenes, "scene.toml"), "w") as f:
        f.write('dem = "/vsizip/../data/dem.zip/dem.asc"\nassume_crs = "EPSG:4326"\n'
                '[[layer]]\nname = "parcels"\nsource = "../data/p.geojson"\nkind = "polygon"\n'
                '[[layer]]\nname = "trails"\nsource = "../data/l.geojson"\nkind = "line"\n'
                'dynamic = true\nwidth = 3\n')
    return folder


def two_checkouts():
    root = suite.dir("checkouts")
    a = make_scene(os.path.join(root, "ci-runner-1", "decalprep"))
    b = make_scene(os.path.join(root, "x", "y", "z", "other-checkout"))
    os.makedirs(os.path.join(b, "build"))
    pkg_a = os.path.join(a, "scenes", "out.decals")
    # A: absolute scene path and output, from the work folder.
    r = suite.run(["build", os.path.join(a, "scenes", "scene.toml"), "-o", pkg_a, "-q"], cwd=suite.work)
    suite.expect(r, 0)
    # B: relative paths, from a folder beside the scenes.
    r = suite.run(["build", "../scenes/scene.toml", "-o", "../scenes/out.decals", "-q"],
                  cwd=os.path.join(b, "build"))
    suite.expect(r, 0)
    pkg_b = os.path.join(b, "scenes", "out.decals")
    if not filecmp.cmp(pkg_a, pkg_b, shallow=False):
        da = suite.run(["dump", pkg_a, "--summary"]).out.splitlines()
        db = suite.run(["dump", pkg_b, "--summary"]).out.splitlines()
        diff = [f"- {x}\n+ {y}" for x, y in zip(da, db) if x != y][:8]
        raise Failure("the two checkouts' packages differ:\n" + "\n".join(diff))
    # The recorded paths say nothing of either checkout.
    with open(pkg_a, "rb") as f:
        blob = f.read()
    for folder in ("ci-runner-1", suite.work):
        if folder.encode() in blob:
            raise Failure(f"the package records {folder!r}")
    return pkg_a


def same_bytes_across_checkouts():
    two_checkouts()


def render_finds_the_recorded_dem():
    pkg = two_checkouts()
    elsewhere = suite.dir("elsewhere")
    r = suite.run(["render", pkg, "--cpu", "--size", "32x24", "-o", os.path.join(elsewhere, "x.png")],
                  cwd=elsewhere, timeout=60)
    suite.expect(r, 0, "terrain from the package's build DEM")
    if "cannot be read here" in r.err:
        raise Failure(f"render did not find the recorded DEM:\n{r}")
    # The package moved with its DEM (a whole checkout copied) still finds it.
    moved = os.path.join(suite.dir("moved"), "copy")
    shutil.copytree(os.path.dirname(os.path.dirname(pkg)), moved)
    r = suite.run(["render", os.path.join(moved, "scenes", "out.decals"), "--cpu", "--size", "32x24",
                   "-o", os.path.join(elsewhere, "y.png")], cwd=elsewhere, timeout=60)
    suite.expect(r, 0, "terrain from the package's build DEM", moved)


def fileless_form():
    root = suite.dir("fileless")
    outs = []
    for name in ("one", os.path.join("two", "deeper")):
        d = os.path.join(root, name)
        os.makedirs(d)
        safety.write_polygons_geojson(os.path.join(d, "p.geojson"))
        outs.append(os.path.join(d, "out.decals"))
    r = suite.run(["build", "p.geojson", "-o", "out.decals", "-q"], cwd=os.path.dirname(outs[0]))
    suite.expect(r, 0)
    r = suite.run(["build", os.path.join(os.path.dirname(outs[1]), "p.geojson"), "-o", outs[1], "-q"],
                  cwd=os.path.dirname(outs[1]))
    suite.expect(r, 0)
    if not filecmp.cmp(outs[0], outs[1], shallow=False):
        raise Failure("the file-less builds of one source in two folders differ")


def tilesets_across_checkouts():
    """A tileset of the same scene from two checkouts: the same tile files,
    each cmp-identical, and the same tileset.json and manifest.json."""
    root = suite.dir("tile_checkouts")
    a = make_scene(os.path.join(root, "runner-a", "decalprep"))
    b = make_scene(os.path.join(root, "p", "q", "runner-b"))
    os.makedirs(os.path.join(b, "build"))
    out_a = os.path.join(a, "scenes", "tiles")
    r = suite.run(["build", os.path.join(a, "scenes", "scene.toml"), "-o", out_a, "--tile-size", "150",
                   "--levels", "1", "-q"], cwd=suite.work, timeout=120)
    suite.expect(r, 0)
    r = suite.run(["build", "../scenes/scene.toml", "-o", "../scenes/tiles", "--tile-size", "150",
                   "--levels", "1", "-q"], cwd=os.path.join(b, "build"), timeout=120)
    suite.expect(r, 0)
    out_b = os.path.join(b, "scenes", "tiles")
    files_a = sorted(os.path.relpath(os.path.join(d, f), out_a) for d, _, fs in os.walk(out_a) for f in fs)
    files_b = sorted(os.path.relpath(os.path.join(d, f), out_b) for d, _, fs in os.walk(out_b) for f in fs)
    if files_a != files_b:
        raise Failure(f"different files: {files_a} vs {files_b}")
    if not any(f.endswith(".decals") for f in files_a):
        raise Failure(f"no tile was written: {files_a}")
    differ = [f for f in files_a if not filecmp.cmp(os.path.join(out_a, f), os.path.join(out_b, f), shallow=False)]
    if differ:
        raise Failure(f"these differ between the checkouts: {differ}")


suite.case("two checkouts, absolute and relative scene paths: cmp-identical packages",
           same_bytes_across_checkouts)
suite.case("render finds the recorded DEM from another folder, and after the checkout moved",
           render_finds_the_recorded_dem)
suite.case("the file-less form: the same bytes from two folders", fileless_form)
suite.case("a tileset from two checkouts: every file cmp-identical", tilesets_across_checkouts)
sys.exit(suite.finish())
