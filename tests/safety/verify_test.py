#!/usr/bin/env python3
"""Readers never hang and the writer never writes what `verify` refuses.

- A FIFO given as a package to `info`, `verify` and `dump` is refused (no
  writer ever opens it: a reader that opened it blocking would hang) within
  the time limit, naming it a FIFO; so is a tile of a tileset that is a
  FIFO or a link to /dev/zero (`verify`, `dump --tile`).
- `build --kind line --width 1e300` (and 2e7, the first width whose half
  width a package cannot hold) is refused with exit 2 naming --width, for a
  package and for a tileset, and writes nothing; a width just below builds
  a package that `verify` accepts only where its strokes fit the package:
  1.99e7 m reaches 9,950 km from the origin, past the 2,147 km of int32
  millimetres, and is refused (exit 6, naming the limit) before a byte is
  written, where it once wrote a package that no renderer could draw; a
  width of 4e6 m fits, builds and verifies. A scene file's width of 1e300 is
  refused as the scene is read (exit 3); a line 1.9999e7 m wide, cut in
  500 m tiles, is refused by the tile plan (exit 6) instead of hanging.

Usage: verify_test.py DECALPREP WORK_DIR SOURCE_DIR
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import safety  # noqa: E402

suite = safety.Suite(sys.argv)
LIMIT_S = 10


def fifo_package():
    d = suite.dir("fifo_package")
    fifo = os.path.join(d, "pipe.decals")
    os.mkfifo(fifo)
    for cmd, code in (("info", 3), ("verify", 5), ("dump", 5)):
        r = suite.run([cmd, fifo], timeout=LIMIT_S)
        try:
            suite.expect(r, code, "FIFO")
        except safety.Failure as e:
            raise safety.Failure(f"decalprep {cmd} {fifo}: {e}")


def special_tiles():
    d = suite.dir("special_tiles")
    src = safety.write_lines_geojson(os.path.join(d, "lines.geojson"), n=4)
    out = os.path.join(d, "ts")
    suite.expect(suite.run(["build", src, "-o", out, "--kind", "line", "--width", "3",
                            "--tile-size", "500", "-q"], timeout=120), 0)
    tiles = sorted(os.listdir(os.path.join(out, "tiles")))
    if not tiles:
        raise safety.Failure("the tileset has no tile")
    name = tiles[0]  # "x<X>_y<Y>.decals"
    key = name[1:-len(".decals")].replace("_y", ",")
    tile = os.path.join(out, "tiles", name)
    os.remove(tile)
    os.mkfifo(tile)
    for args in (["verify", out], ["dump", out, "--tile", key]):
        r = suite.run(args, timeout=LIMIT_S)
        try:
            suite.expect(r, 5, "FIFO")
        except safety.Failure as e:
            raise safety.Failure(f"decalprep {' '.join(args)}: {e}")
    os.remove(tile)
    os.symlink("/dev/zero", tile)
    suite.expect(suite.run(["verify", out], timeout=LIMIT_S), 5, "character device")


def too_wide():
    d = suite.dir("too_wide")
    src = safety.write_lines_geojson(os.path.join(d, "lines.geojson"), n=80)
    for width in ("1e300", "2e7"):
        pkg = os.path.join(d, "w.decals")
        r = suite.run(["build", src, "-o", pkg, "--kind", "line", "--width", width, "-q"],
                      timeout=60)
        suite.expect(r, 2, "--width")
        if os.path.exists(pkg):
            raise safety.Failure(f"--width {width}: {pkg} was written")
        ts = os.path.join(d, "ts")
        r = suite.run(["build", src, "-o", ts, "--kind", "line", "--width", width,
                       "--tile-size", "500", "-q"], timeout=60)
        suite.expect(r, 2, "--width")
        if os.path.exists(ts):
            raise safety.Failure(f"--width {width} --tile-size 500: {ts} was made: "
                                 f"{sorted(os.listdir(ts))}")
    # A scene file's width is refused as it is read: exit 3 naming the
    # file, the line and the width; nothing written, package or tileset.
    scene = os.path.join(d, "wide.toml")
    with open(scene, "w") as f:
        f.write(f'source = "{src}"\n\n[[layer]]\nname = "wide"\nkind = "line"\nwidth = 1e300\n')
    pkg = os.path.join(d, "scene.decals")
    r = suite.run(["build", scene, "-o", pkg, "-q"], timeout=60)
    suite.expect(r, 3, "wide.toml", "width 1e+300", "too wide")
    if os.path.exists(pkg):
        raise safety.Failure(f"scene width 1e300: {pkg} was written")
    ts = os.path.join(d, "scene_ts")
    r = suite.run(["build", scene, "-o", ts, "--tile-size", "500", "-q"], timeout=60)
    suite.expect(r, 3, "too wide")
    if os.path.exists(ts):
        raise safety.Failure(f"scene width 1e300 --tile-size 500: {ts} was made")
    # The widest line a package holds, with tiles far smaller than its
    # stroke: its margin would reach ~10^11 tiles, which the plan refuses
    # (exit 6) instead of listing them for ever.
    ts = os.path.join(d, "wide_small_tiles")
    r = suite.run(["build", src, "-o", ts, "--kind", "line", "--width", "1.9999e7", "--tile-size", "500",
                   "-q"], timeout=60)
    suite.expect(r, 6, "more than")
    if os.path.exists(ts):
        raise safety.Failure(f"--width 1.9999e7 --tile-size 500: {ts} was left: {sorted(os.listdir(ts))}")
    # Below the width limit but past what a package's grid can address:
    # refused before a byte is written.
    pkg = os.path.join(d, "widest.decals")
    suite.expect(suite.run(["build", src, "-o", pkg, "--kind", "line", "--width", "1.99e7", "-q"],
                           timeout=60), 6, "2147 km")
    if os.path.exists(pkg):
        raise safety.Failure(f"--width 1.99e7: {pkg} was written")
    # Strokes that fit: built, and its own verify accepts it.
    suite.expect(suite.run(["build", src, "-o", pkg, "--kind", "line", "--width", "4e6", "-q"],
                           timeout=60), 0)
    suite.expect(suite.run(["verify", pkg], timeout=LIMIT_S), 0, "ok")


suite.case("a FIFO package is refused by info, verify and dump without hanging", fifo_package)
suite.case("a FIFO tile and a tile linked to /dev/zero are refused without hanging", special_tiles)
suite.case("a static line 2e7 m wide or wider is refused before anything is written", too_wide)
sys.exit(suite.finish())
