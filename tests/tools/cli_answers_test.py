#!/usr/bin/env python3
"""What `verify`, `dump` and `render` answer where a user can slip.

  cli_answers_test.py DECALPREP REPO_ROOT WORK_DIR

On the checked-in package tests/formats/legacy/golden_v1_2.decals:
- `dump --blob nope` exits 2 and lists the package's blob names, which
  `info --json` gives (the oracle);
- `verify` of a missing path exits 3 (input), not 5 (corrupt); of a copy
  with one blob byte flipped exits 5; of both, 5;
- `verify --json` prints one object whose entries say, per path, ok or the
  reason and whether the path could not be read;
- `render -o x.jpg` (and `--decals d.tif`) exits 2 before drawing, names
  the .png to use, and leaves no file under the given name;
- a top-down `--extent` whose aspect is not `--size`'s: the world file
  describes square pixels, the extent widened about its centre along the
  short axis (computed here from the given extent and size), the note on
  stderr states that extent, and the picture is the one `--extent` of the
  widened extent draws (same PNG bytes); `--size W` takes the height from
  the extent's aspect, with square pixels; `--stretch` keeps the extent as
  given (pixels dx/W by dy/H, no note); `--size W` without `--extent` is
  exit 2;
- `--dem /vsizip/ARCHIVE` without the file inside opens the archive's one
  raster (the same picture as naming it), and an archive of two rasters or
  of none is exit 3 listing what it holds;
- `--version` names the project version of CMakeLists.txt and the format
  versions it writes, which a package it builds (`info --json`) and a
  tileset with overview levels (its tileset.json) carry.
"""
import json
import os
import re
import shutil
import subprocess
import sys


def run(cmd):
    return subprocess.run(cmd, capture_output=True, text=True)


def png_size(path):
    head = open(path, "rb").read(24)
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def world_file(png):
    return [float(v) for v in open(os.path.splitext(png)[0] + ".pgw").read().split()]


def square_pixels(tool, pkg, work, info, expect):
    """--extent of another aspect than --size, --size W, --stretch."""
    x0, y0, x1, y1 = info["metadata"]["extent"]  # the origin is 0,0
    # Wider than 640x360's aspect at the package's own height: padded in y.
    given = (x0, y0, x1, y0 + (x1 - x0) * 0.25)
    arg = ",".join("%.6f" % v for v in given)
    given = tuple(float(v) for v in arg.split(","))
    w, h = 640, 360
    base = [tool, "render", pkg, "--cpu", "--flat"]
    out = os.path.join(work, "square.png")
    r = run(base + ["--extent", arg, "--size", "%dx%d" % (w, h), "-o", out])
    expect("render --extent of another aspect exits 0", r.returncode == 0, r.stderr)
    px = (given[2] - given[0]) / w
    cy = (given[1] + given[3]) / 2
    want = (given[0], cy - px * h / 2, given[2], cy + px * h / 2)
    a, _, _, e, c, f = world_file(out)
    expect("the world file's pixels are square", abs(a + e) <= 1e-9 * a, "A %r E %r" % (a, e))
    expect("the pixel is the given width over W", abs(a - px) <= 1e-9 * px, "%r vs %r" % (a, px))
    got = (c - a / 2, f + e * (h - 0.5), c + a * (w - 0.5), f - e / 2)
    expect("the world file's extent is the given one widened about its centre in y",
           all(abs(g - v) <= 1e-6 for g, v in zip(got, want)), "%r vs %r" % (got, want))
    stated = "%.3f,%.3f,%.3f,%.3f" % want
    expect("the note states the widened extent", ("widened to " + stated) in r.stderr, r.stderr)
    again = os.path.join(work, "square_again.png")
    r2 = run(base + ["--extent", ",".join("%.9f" % v for v in want), "--size", "%dx%d" % (w, h),
                     "-o", again])
    expect("the widened extent given as such draws the same picture",
           r2.returncode == 0 and open(out, "rb").read() == open(again, "rb").read(), r2.stderr)

    auto = os.path.join(work, "auto.png")
    r = run(base + ["--extent", arg, "--size", "500", "-o", auto])
    want_h = round(500 * (given[3] - given[1]) / (given[2] - given[0]))
    ok = r.returncode == 0 and png_size(auto) == (500, want_h)
    expect("--size 500 takes the height from the extent (500x%d)" % want_h, ok,
           r.stderr + (" %r" % (png_size(auto),) if r.returncode == 0 else ""))
    if ok:
        a, _, _, e, _, _ = world_file(auto)
        expect("--size 500: square pixels", abs(a + e) <= 1e-9 * a, "A %r E %r" % (a, e))
        expect("--size 500: no note (the rounding pads under half a pixel)",
               "widened" not in r.stderr, r.stderr)

    stretched = os.path.join(work, "stretch.png")
    r = run(base + ["--extent", arg, "--size", "%dx%d" % (w, h), "--stretch", "-o", stretched])
    a, _, _, e, _, _ = world_file(stretched) if r.returncode == 0 else (0, 0, 0, 0, 0, 0)
    expect("--stretch keeps the extent: pixels dx/W by dy/H, no note",
           r.returncode == 0 and abs(a - px) <= 1e-9 * px and
           abs(-e - (given[3] - given[1]) / h) <= 1e-9 * px and "widened" not in r.stderr,
           "exit %d, A %r E %r: %s" % (r.returncode, a, e, r.stderr))

    r = run(base + ["--size", "500", "-o", os.path.join(work, "noextent.png")])
    expect("--size W without --extent exits 2 naming it",
           r.returncode == 2 and "--size '500'" in r.stderr, "exit %d: %s" % (r.returncode,
                                                                             r.stderr))


def dem_archives(tool, root, pkg, work, expect):
    """--dem /vsizip/ARCHIVE without the file inside."""
    import zipfile
    archive = os.path.join(root, "samples", "monaco", "N43E007.hgt.zip")
    base = [tool, "render", pkg, "--cpu", "--size", "64x36"]
    named = os.path.join(work, "dem_named.png")
    whole = os.path.join(work, "dem_archive.png")
    r1 = run(base + ["--dem", "/vsizip/" + archive + "/N43E007.hgt", "-o", named])
    r2 = run(base + ["--dem", "/vsizip/" + archive, "-o", whole])
    expect("--dem /vsizip/ARCHIVE with one raster opens it: the picture of the named file",
           r1.returncode == 0 and r2.returncode == 0 and
           open(named, "rb").read() == open(whole, "rb").read(), r1.stderr + r2.stderr)
    two = os.path.join(work, "two.zip")
    data = zipfile.ZipFile(archive).read("N43E007.hgt")
    with zipfile.ZipFile(two, "w") as z:
        z.writestr("a/N43E007.hgt", data)
        z.writestr("b/N43E007.hgt", data)
    r = run(base + ["--dem", "/vsizip/" + two, "-o", os.path.join(work, "two.png")])
    expect("an archive of two rasters: exit 3 naming both and asking for one",
           r.returncode == 3 and "holds 2 rasters; name one" in r.stderr and
           "a/N43E007.hgt" in r.stderr and "b/N43E007.hgt" in r.stderr,
           "exit %d: %s" % (r.returncode, r.stderr))
    none = os.path.join(work, "none.zip")
    with zipfile.ZipFile(none, "w") as z:
        z.writestr("readme.txt", "no raster here")
    r = run(base + ["--dem", "/vsizip/" + none, "-o", os.path.join(work, "none.png")])
    expect("an archive without a raster: exit 3 listing its entries",
           r.returncode == 3 and "holds no raster GDAL can open (entries: readme.txt)" in r.stderr,
           "exit %d: %s" % (r.returncode, r.stderr))


def versions(tool, root, work, expect):
    r = run([tool, "--version"])
    text = r.stdout
    project = re.search(r"project\(decalprep VERSION ([0-9.]+)",
                        open(os.path.join(root, "CMakeLists.txt")).read()).group(1)
    expect("--version exits 0 naming the project version",
           r.returncode == 0 and text.startswith("decalprep " + project + "\n"), text + r.stderr)
    pkg_writes = re.search(r"decal packages.*writes ([0-9]+)\.([0-9]+)", text)
    ts_writes = re.search(r"tilesets.*\(([0-9]+)\.([0-9]+) with overview levels\)", text)
    expect("--version names the package and tileset versions it writes",
           pkg_writes is not None and ts_writes is not None, text)
    if pkg_writes is None or ts_writes is None:
        return
    src = os.path.join(work, "line.geojson")
    with open(src, "w") as f:
        f.write('{"type":"FeatureCollection","crs":{"type":"name","properties":{"name":'
                '"EPSG:32632"}},"features":[{"type":"Feature","properties":{},"geometry":'
                '{"type":"LineString","coordinates":[[500000,4800000],[504000,4803000]]}}]}')
    out = os.path.join(work, "version.decals")
    b = run([tool, "build", src, "-o", out, "--kind", "line", "--width", "4", "-q"])
    v = json.loads(run([tool, "info", out, "--json"]).stdout)["version"] if b.returncode == 0 else {}
    expect("a package it builds has the version --version says it writes",
           [v.get("major"), v.get("minor")] == [int(pkg_writes.group(1)), int(pkg_writes.group(2))],
           "%r vs %r" % (v, pkg_writes.groups()))
    ts = os.path.join(work, "version_ts")
    b = run([tool, "build", src, "-o", ts, "--kind", "line", "--width", "4", "--tile-size", "1000",
             "--levels", "2", "-q"])
    got = json.load(open(os.path.join(ts, "tileset.json"))).get("tileset_version") \
        if b.returncode == 0 else None
    expect("a tileset with levels has the version --version says it writes",
           got == "%s.%s" % ts_writes.groups(), "%r vs %r (%s)" % (got, ts_writes.groups(), b.stderr))


def main(tool, root, work):
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    pkg = os.path.join(work, "golden.decals")
    shutil.copy(os.path.join(root, "tests", "formats", "legacy", "golden_v1_2.decals"), pkg)
    failures = []

    def expect(what, ok, detail=""):
        print(("ok   " if ok else "FAIL ") + what + ("" if ok else ": " + detail))
        if not ok:
            failures.append(what)

    info = json.loads(run([tool, "info", pkg, "--json"]).stdout)
    names = [b["name"] for b in info["blobs"]]

    r = run([tool, "dump", pkg, "--blob", "nope"])
    expect("dump --blob nope exits 2", r.returncode == 2, "exit %d" % r.returncode)
    expect("dump --blob nope lists the blob names",
           all(n in r.stderr for n in names) and "its blobs:" in r.stderr, r.stderr)

    missing = os.path.join(work, "missing.decals")
    r = run([tool, "verify", missing])
    expect("verify of a missing file exits 3 (input)", r.returncode == 3,
           "exit %d: %s" % (r.returncode, r.stderr))
    expect("verify of a missing file names it", missing in r.stderr, r.stderr)

    bad = os.path.join(work, "flipped.decals")
    data = bytearray(open(pkg, "rb").read())
    last = info["blobs"][-1]
    data[last["offset"] + last["stored_size"] // 2] ^= 0x01
    open(bad, "wb").write(data)
    r = run([tool, "verify", bad])
    expect("verify of a flipped byte exits 5", r.returncode == 5, "exit %d" % r.returncode)
    r = run([tool, "verify", bad, missing])
    expect("verify of a corrupt and a missing file exits 5", r.returncode == 5,
           "exit %d" % r.returncode)

    r = run([tool, "verify", pkg, bad, missing, "--json"])
    try:
        j = json.loads(r.stdout)
        by = {e["path"]: e for e in j["packages"]}
        expect("verify --json: one entry per path", set(by) == {pkg, bad, missing}, r.stdout)
        expect("verify --json: the good package ok with a summary",
               by[pkg]["ok"] and "blobs" in by[pkg]["summary"], r.stdout)
        expect("verify --json: the flipped one not ok, readable, with a reason",
               not by[bad]["ok"] and not by[bad]["unreadable"] and by[bad]["reason"], r.stdout)
        expect("verify --json: the missing one unreadable",
               not by[missing]["ok"] and by[missing]["unreadable"], r.stdout)
        expect("verify --json: ok false overall, exit 5", not j["ok"] and r.returncode == 5,
               "exit %d" % r.returncode)
    except (ValueError, KeyError) as e:
        expect("verify --json prints one JSON object", False, "%s: %r" % (e, r.stdout[:500]))
    r = run([tool, "verify", pkg, "--json"])
    expect("verify --json of a good package: ok true, exit 0",
           r.returncode == 0 and json.loads(r.stdout)["ok"], r.stdout + r.stderr)

    for opts, name in ((["-o", os.path.join(work, "x.jpg")], "x.jpg"),
                       (["-o", os.path.join(work, "y.png"), "--decals",
                         os.path.join(work, "d.TIF")], "d.TIF")):
        r = run([tool, "render", pkg, "--cpu", "--flat", "--size", "64x36"] + opts)
        expect("render %s exits 2" % name, r.returncode == 2, "exit %d: %s" % (r.returncode, r.stderr))
        expect("render %s names the .png to use" % name,
               os.path.splitext(name)[0] + ".png" in r.stderr, r.stderr)
        expect("render %s writes nothing" % name,
               not os.path.exists(os.path.join(work, name)) and
               not os.path.exists(os.path.join(work, "y.png")), str(os.listdir(work)))

    square_pixels(tool, pkg, work, info, expect)
    dem_archives(tool, root, pkg, work, expect)
    versions(tool, root, work, expect)

    if failures:
        print("FAIL: %d checks" % len(failures))
        return 1
    print("PASS")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    sys.exit(main(*sys.argv[1:4]))
