#!/usr/bin/env python3
"""Exit 0 means something was built: a build that keeps no feature from any
layer exits 9 and writes no package (its report says why) unless
--allow-empty (or allow_empty = true in the scene file); a layer that reads
no feature is a warning naming the layer, its source and its filter, and
dynamic-line heights taken outside the DEM a warning with their count; both
are errors (exit 10) under --strict, which batch mode passes to its scenes.
Widths no map means (a static line under 1 mm or over 100 km, a dynamic one
under 0.1 or over 1000 pixels) are a warning naming the layer, its scene
line and the value; sensible widths give none.

  empty_test.py DECALPREP WORK_DIR SOURCE_DIR
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import safety  # noqa: E402
from safety import Failure  # noqa: E402

suite = safety.Suite(sys.argv)

# An extent (local frame metres) 100 km from the data: everything is clipped away.
FAR = "100000,100000,100010,100010"


def two_layer_scene(d, where="k > 10", extra=""):
    """Polygons that build, and a line layer whose `where` matches nothing."""
    safety.write_polygons_geojson(os.path.join(d, "p.geojson"))
    safety.write_lines_geojson(os.path.join(d, "l.geojson"))
    path = os.path.join(d, "scene.toml")
    with open(path, "w") as f:
        f.write(extra + '[[layer]]\nname = "polys"\nsource = "p.geojson"\nkind = "polygon"\n'
                f'[[layer]]\nname = "roads"\nsource = "l.geojson"\nwhere = "{where}"\nkind = "line"\n')
    return path


def everything_clipped():
    d = suite.dir("clipped")
    src = safety.write_polygons_geojson(os.path.join(d, "p.geojson"))
    pkg, report = os.path.join(d, "out.decals"), os.path.join(d, "out.json")
    r = suite.run(["build", src, "-o", pkg, "--report", report, "--extent", FAR])
    suite.expect(r, 9, "no layer kept a feature", "clipped away 3", "--allow-empty")
    if os.path.exists(pkg):
        raise Failure("an empty build wrote a package")
    rep = json.load(open(report))
    if rep.get("exit_code") != 9 or rep.get("package_written") is not False:
        raise Failure(f"the report does not say the build failed with exit 9: {rep}")
    if rep.get("manifest", {}).get("totals", {}).get("clipped_away") != 3:
        raise Failure(f"the report lacks the layer counts that say why: {rep}")


def allow_empty_flag():
    d = suite.dir("allow_flag")
    src = safety.write_polygons_geojson(os.path.join(d, "p.geojson"))
    pkg = os.path.join(d, "out.decals")
    r = suite.run(["build", src, "-o", pkg, "--extent", FAR, "--allow-empty", "-q"])
    suite.expect(r, 0)
    if not os.path.exists(pkg):
        raise Failure("--allow-empty wrote no package")
    suite.expect(suite.run(["verify", pkg]), 0)


def allow_empty_scene_key():
    d = suite.dir("allow_key")
    safety.write_polygons_geojson(os.path.join(d, "p.geojson"))
    scene = os.path.join(d, "scene.toml")
    with open(scene, "w") as f:
        f.write('allow_empty = true\n[[layer]]\nname = "polys"\nsource = "p.geojson"\nkind = "polygon"\n')
    pkg = os.path.join(d, "out.decals")
    suite.expect(suite.run(["build", scene, "-o", pkg, "--extent", FAR, "-q"]), 0)
    if not os.path.exists(pkg):
        raise Failure("allow_empty = true wrote no package")


def where_matches_nothing_warns():
    d = suite.dir("where_warns")
    scene = two_layer_scene(d)
    pkg, report = os.path.join(d, "out.decals"), os.path.join(d, "out.json")
    r = suite.run(["build", scene, "-o", pkg, "--report", report, "-q"])
    suite.expect(r, 0, "warning", "layer 'roads'", "l.geojson", 'where "k > 10"')
    if "polys" in r.err:
        raise Failure(f"a layer that read features is named in a warning:\n{r}")
    warnings = json.load(open(report)).get("warnings", [])
    if len(warnings) != 1 or "roads" not in warnings[0]:
        raise Failure(f"the report's warnings are not the one layer: {warnings}")


def where_warning_json():
    d = suite.dir("where_json")
    scene = two_layer_scene(d)
    r = suite.run(["build", scene, "-o", os.path.join(d, "out.decals"), "--progress", "json"])
    suite.expect(r, 0)
    events = [json.loads(line) for line in r.err.splitlines() if line.strip()]  # all JSON
    if not any(e.get("event") == "warning" and "roads" in e.get("text", "") for e in events):
        raise Failure(f"no warning object on stderr with --progress json:\n{r}")


def where_matches_nothing_strict():
    d = suite.dir("where_strict")
    scene = two_layer_scene(d)
    pkg = os.path.join(d, "out.decals")
    r = suite.run(["build", scene, "-o", pkg, "--strict", "-q"])
    suite.expect(r, 10, "--strict", "layer 'roads'", 'where "k > 10"')
    if os.path.exists(pkg):
        raise Failure("--strict stopped the build but a package was written")


def batch_passes_strict_and_allow_empty():
    d = suite.dir("batch")
    scenes = os.path.join(d, "scenes")
    os.makedirs(scenes)
    two_layer_scene(scenes)  # scenes/scene.toml
    out = os.path.join(d, "out")
    r = suite.run(["build", scenes, "-o", out, "--strict", "-q"])
    suite.expect(r, 10)
    summary = json.load(open(os.path.join(out, "summary.json")))
    if [p["exit_code"] for p in summary["packages"]] != [10]:
        raise Failure(f"the scene did not fail with exit 10: {summary}")
    out2 = os.path.join(d, "out2")
    r = suite.run(["build", scenes, "-o", out2, "--extent", FAR, "-q"])
    suite.expect(r, 9)
    out3 = os.path.join(d, "out3")
    r = suite.run(["build", scenes, "-o", out3, "--extent", FAR, "--allow-empty", "-q"])
    suite.expect(r, 0)
    if not os.path.exists(os.path.join(out3, "scene.decals")):
        raise Failure("batch --allow-empty wrote no package")


def write_dem(path, lon0, lat0, lon1, lat1, n=20):
    """An ESRI ASCII grid (no CRS: the scene gives assume_crs), a gentle ramp."""
    cx, cy = (lon1 - lon0) / n, (lat1 - lat0) / n
    assert abs(cx - cy) < 1e-12
    with open(path, "w") as f:
        f.write(f"ncols {n}\nnrows {n}\nxllcorner {lon0}\nyllcorner {lat0}\ncellsize {cx}\n")
        for j in range(n):
            f.write(" ".join(str(100 + i + j) for i in range(n)) + "\n")


def dem_scene(d, lon1):
    """Three dynamic lines from lon 7.42 to 7.421 (lat 43.730..43.732), a
    DEM over lon 7.400..lon1, and an extent holding all of the lines."""
    safety.write_lines_geojson(os.path.join(d, "l.geojson"))
    write_dem(os.path.join(d, "dem.asc"), 7.40, 43.72, lon1, 43.72 + (lon1 - 7.40))
    scene = os.path.join(d, "scene.toml")
    with open(scene, "w") as f:
        f.write('dem = "dem.asc"\nassume_crs = "EPSG:4326"\n'
                'extent = [7.41, 43.725, 7.43, 43.74]\nextent_crs = "EPSG:4326"\n'
                '[[layer]]\nname = "trails"\nsource = "l.geojson"\nkind = "line"\n'
                'dynamic = true\nwidth = 3\n')
    return scene


def heights_outside_dem():
    d = suite.dir("dem_outside")
    # The DEM ends at lon 7.4205, halfway along every line: all 3 lines have
    # vertices beyond it.
    scene = dem_scene(d, 7.4205)
    pkg, report = os.path.join(d, "out.decals"), os.path.join(d, "out.json")
    r = suite.run(["build", scene, "-o", pkg, "--report", report, "-q"])
    suite.expect(r, 0, "warning", "outside the DEM", "on 3 of 3 lines")
    if not any("outside the DEM" in w for w in json.load(open(report)).get("warnings", [])):
        raise Failure("the report's warnings do not have the DEM's")
    r = suite.run(["build", scene, "-o", os.path.join(d, "strict.decals"), "--strict", "-q"])
    suite.expect(r, 10, "outside the DEM")
    if os.path.exists(os.path.join(d, "strict.decals")):
        raise Failure("--strict stopped the build but a package was written")


def heights_inside_dem_no_warning():
    d = suite.dir("dem_inside")
    scene = dem_scene(d, 7.45)  # covers every line
    r = suite.run(["build", scene, "-o", os.path.join(d, "out.decals"), "--strict"])
    suite.expect(r, 0)
    if "outside the DEM" in r.err:
        raise Failure(f"a DEM covering the lines gave the warning:\n{r}")


def implausible_widths_warn():
    d = suite.dir("widths")
    safety.write_lines_geojson(os.path.join(d, "l.geojson"))
    scene = os.path.join(d, "scene.toml")
    with open(scene, "w") as f:
        f.write('[[layer]]\nname = "hair"\nsource = "l.geojson"\nkind = "line"\nwidth = 0.0001\n'
                '[[layer]]\nname = "wide"\nsource = "l.geojson"\nkind = "line"\nwidth = 3000\n'
                'dynamic = true\n'
                '[[layer]]\nname = "fine"\nsource = "l.geojson"\nkind = "line"\nwidth = 6\n')
    pkg, report = os.path.join(d, "out.decals"), os.path.join(d, "out.json")
    r = suite.run(["build", scene, "-o", pkg, "--report", report, "-q"])
    suite.expect(r, 0, "layer 'hair' (" + scene + ":1): width 0.0001 m is outside the plausible "
                 "0.001..100000 m of a static line",
                 "layer 'wide' (" + scene + ":6): width 3000 pixels is outside the plausible "
                 "0.1..1000 pixels of a dynamic line")
    if "'fine'" in r.err:
        raise Failure(f"a 6 m line is named in a warning:\n{r}")
    warnings = json.load(open(report)).get("warnings", [])
    if len(warnings) != 2:
        raise Failure(f"the report's warnings are not the two layers: {warnings}")
    r = suite.run(["build", scene, "-o", os.path.join(d, "strict.decals"), "--strict", "-q"])
    suite.expect(r, 10, "--strict", "layer 'hair'", "layer 'wide'")
    if os.path.exists(os.path.join(d, "strict.decals")):
        raise Failure("--strict stopped the build but a package was written")


suite.case("everything clipped away: exit 9, no package, the report says why", everything_clipped)
suite.case("--allow-empty writes the empty package, exit 0", allow_empty_flag)
suite.case("allow_empty = true in the scene file", allow_empty_scene_key)
suite.case("a where matching nothing warns, naming layer, source and filter", where_matches_nothing_warns)
suite.case("the warning is a JSON object under --progress json", where_warning_json)
suite.case("--strict: a where matching nothing is exit 10", where_matches_nothing_strict)
suite.case("batch mode passes --strict and --allow-empty to its scenes", batch_passes_strict_and_allow_empty)
suite.case("dynamic-line heights outside the DEM: warning with counts, exit 10 under --strict",
           heights_outside_dem)
suite.case("a DEM that covers the lines gives no warning", heights_inside_dem_no_warning)
suite.case("implausible widths warn, naming layer, line and value; exit 10 under --strict",
           implausible_widths_warn)
sys.exit(suite.finish())
