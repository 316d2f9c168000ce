#!/usr/bin/env python3
"""Overview levels of a tileset (formats/SPEC.md "Overview levels") on a
synthetic scene whose oracle is clean: single-part polygons (regular
n-gons) and lines in EPSG:32632, built with --crs EPSG:32632 (the frame is
the source CRS, so areas and lengths are the source's), no clip, no
--resolution.

Checks:
- the build as separate steps (--plan 3, every step run twice) gives the
  bytes of the one-process build (--jobs 2); finalize with a tile job
  missing names the missing tiles, level tiles among them, and exits
  non-zero;
- each level's dropped_small per layer equals the count of input features
  below the level's min_area / min_length, by ogrinfo's SQLite dialect
  (ST_Area, ST_Length) on the input files;
- each level's vertices_out is at most the level below's (level 0: the
  manifest's);
- every vertex of a line of a level tile lies within 1 mm of the input
  (the simplified line keeps input vertices), and every input vertex of a
  line kept on the level and inside the tile's square lies within
  min(r_L, 2 m width) / 8 + 1 mm of the tile's lines (the level's line
  tolerance);
- info lists the levels, verify checks their tiles, dump --level opens one;
- info's tiles line and a build's closing line give the level tiles and
  bytes and the totals with them, as tileset.json lists them, and the
  closing line the candidate tiles the progress counted;
- read_tileset_index refuses a bad level file path, a wrong level tile
  size and non-consecutive levels, naming the field; a 1.0 index reads;
- --levels auto stops at a level of at most 4 tiles; --levels without
  --tile-size is a usage error naming --levels.

Usage: tileset_levels_test.py DECALPREP WORK_DIR
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tileset_util import StepRunner, plan_steps, tree, write_scene  # noqa: E402

N = 3
TILE = 500.0
LEVELS = 3
X0, Y0 = 370_000.0, 4_840_000.0
AREAS = [0.5, 2.0, 8.0, 30.0, 500.0, 5000.0]   # m², away from r_L² for L = 1..3
LENGTHS = [0.5, 1.5, 3.0, 10.0, 100.0, 400.0]  # m, away from r_L
LINE_WIDTH = 2.0  # m, the lines layer's width
GRID = 14  # GRID x GRID polygons and as many lines, 145 m apart


def ngon(cx, cy, area, n):
    r = math.sqrt(2 * area / (n * math.sin(2 * math.pi / n)))
    pts = [[cx + r * math.cos(2 * math.pi * i / n), cy + r * math.sin(2 * math.pi * i / n)]
           for i in range(n)]
    return pts + [pts[0]]


def zigzag(x, y, length, amp, steps):
    """A line along x of about `length` with a zig-zag of amplitude amp."""
    pts = []
    for i in range(steps + 1):
        t = length * i / steps
        pts.append([x + t, y + (amp if i % 2 else 0.0)])
    return pts


def write_inputs(work):
    polys, lines = [], []
    k = 0
    for gy in range(GRID):
        for gx in range(GRID):
            cx, cy = X0 + 60 + gx * 145.0, Y0 + 60 + gy * 145.0
            a = AREAS[k % len(AREAS)]
            n = 6 + (k * 7) % 35
            polys.append({"type": "Feature", "properties": {"id": k},
                          "geometry": {"type": "Polygon", "coordinates": [ngon(cx, cy, a, n)]}})
            length = LENGTHS[k % len(LENGTHS)]
            steps = 1 if length < 5 else int(length / 2)
            amp = 0.0 if steps == 1 else 0.2 + (k % 5) * 0.6
            lines.append({"type": "Feature", "properties": {"id": k},
                          "geometry": {"type": "LineString",
                                       "coordinates": zigzag(cx - 70, cy + 50, length, amp,
                                                             steps)}})
            k += 1
    write_scene(work, [("polys", "polygon", polys, 'color = "#336699"\n'),
                       ("lines", "line", lines, 'width = %g\ncolor = "#aa3311"\n' % LINE_WIDTH)])


def ogr_count(path, layer, expr):
    r = subprocess.run(["ogrinfo", "-q", "-dialect", "SQLite", "-sql",
                        "SELECT count(*) AS n FROM %s WHERE %s" % (layer, expr), path],
                       capture_output=True, text=True, check=True)
    m = re.search(r"n \(Integer\) = (\d+)", r.stdout)
    if not m:
        raise RuntimeError("ogrinfo: " + r.stdout + r.stderr)
    return int(m.group(1))


def seg_dist(p, a, b):
    ax, ay = a
    bx, by = b
    dx, dy = bx - ax, by - ay
    L = dx * dx + dy * dy
    t = 0.0 if L == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / L))
    return math.hypot(p[0] - (ax + t * dx), p[1] - (ay + t * dy))


class Segments:
    """The segments of a set of lines in cells of CELL metres: the distance
    from a point to the nearest one within `reach` (inf when none is)."""
    CELL = 8.0

    def __init__(self, lines):
        self.cells = {}
        for pts in lines:
            for i in range(len(pts) - 1):
                a, b = pts[i], pts[i + 1]
                for cx in range(int(math.floor(min(a[0], b[0]) / self.CELL)),
                                int(math.floor(max(a[0], b[0]) / self.CELL)) + 1):
                    for cy in range(int(math.floor(min(a[1], b[1]) / self.CELL)),
                                    int(math.floor(max(a[1], b[1]) / self.CELL)) + 1):
                        self.cells.setdefault((cx, cy), []).append((a, b))

    def distance(self, p, reach):
        best = float("inf")
        c0x, c1x = int(math.floor((p[0] - reach) / self.CELL)), int(math.floor((p[0] + reach) / self.CELL))
        c0y, c1y = int(math.floor((p[1] - reach) / self.CELL)), int(math.floor((p[1] + reach) / self.CELL))
        for cx in range(c0x, c1x + 1):
            for cy in range(c0y, c1y + 1):
                for a, b in self.cells.get((cx, cy), ()):
                    best = min(best, seg_dist(p, a, b))
        return best if best <= reach else float("inf")


def tile_lines(tool, ts, level, tile):
    """The static lines of a level tile in absolute frame coordinates (from
    dump --json: line_vertices in quanta from the tile's origin, grouped by
    line_vertex_line)."""
    r = subprocess.run([tool, "dump", ts, "--tile", "%d,%d" % (tile["x"], tile["y"]),
                        "--level", str(level), "--json"], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError("dump: " + r.stderr)
    j = json.loads(r.stdout)
    q = j["quantum_m"]
    blobs = {b["name"]: b for b in j["blobs"]}
    verts = blobs["line_vertices"]["elements"]
    owner = blobs["line_vertex_line"]["elements"]
    ox, oy = tile["origin"]
    out = []
    for i, v in enumerate(verts):
        if i == 0 or owner[i] != owner[i - 1]:
            out.append([])
        out[-1].append((ox + v[0] * q, oy + v[1] * q))
    return out


def main():
    tool, work = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    write_inputs(work)
    scene = os.path.join(work, "scene.toml")
    failures = []
    base = [tool, "build", scene, "--tile-size", str(int(TILE)), "--levels", str(LEVELS)]

    ref = os.path.join(work, "ref")
    r = subprocess.run(base + ["--jobs", "2", "-o", ref, "-q"], capture_output=True, text=True)
    if r.returncode != 0:
        print("FAIL: the one-process build failed:", r.stderr)
        return 1
    want = tree(ref, skip=("plan.json",))
    ix = json.load(open(os.path.join(ref, "tileset.json")))
    if ix["tileset_version"] != "1.1" or len(ix["levels"]) != LEVELS:
        failures.append("tileset.json: version %s, %d levels" % (ix["tileset_version"],
                                                                  len(ix["levels"])))

    # --- steps: the same bytes; each step twice; finalize names a missing level tile.
    out = os.path.join(work, "stepped")
    plan = plan_steps(base, out, N, work)
    runner = StepRunner(plan, out, failures)
    run_twice = runner.run_twice
    early = runner.run_all_but_last_tile_job(N)
    named = re.findall(r"(?:L\d+/)?x-?\d+_y-?\d+", early.stderr)
    if early.returncode == 0:
        failures.append("finalize with a tile job missing exited 0")
    if not any(n.startswith("L") for n in named):
        failures.append("finalize named no level tile: " + early.stderr.strip()[:300])
    for n in named:
        m = re.match(r"L(\d+)/(.*)", n)
        path = os.path.join(out, "tiles", "L" + m.group(1), m.group(2) + ".decals") if m else \
            os.path.join(out, "tiles", n + ".decals")
        if os.path.exists(path):
            failures.append("finalize named %s, which was built" % n)
    run_twice("tiles", N - 1)
    run_twice("finalize")
    got = tree(out, skip=("plan.json",))
    if got != want:
        failures.append("stepped tileset differs: missing %s, extra %s, different %s" % (
            sorted(set(want) - set(got))[:5], sorted(set(got) - set(want))[:5],
            sorted(k for k in set(want) & set(got) if want[k] != got[k])[:5]))

    # --- drops against ogrinfo on the input features (one part each).
    for lv in ix["levels"]:
        counts = {c["layer"]: c for c in lv["layers"]}
        want_polys = ogr_count(os.path.join(work, "polys.geojson"), "polys",
                               "ST_Area(geometry) < %.17g" % lv["min_area_m2"])
        want_lines = ogr_count(os.path.join(work, "lines.geojson"), "lines",
                               "ST_Length(geometry) < %.17g" % lv["min_length_m"])
        for layer, n in (("polys", want_polys), ("lines", want_lines)):
            c = counts[layer]
            if c["dropped_small"] != n or c["parts_in"] != GRID * GRID or c["parts"] != GRID * GRID - n:
                failures.append("level %d layer %s: dropped_small %d, parts %d of %d; ogrinfo: "
                                "%d below the threshold" % (lv["level"], layer, c["dropped_small"],
                                                            c["parts"], c["parts_in"], n))
        print("level %d (r = %g m): dropped %d polygons, %d lines (ogrinfo: %d, %d)" % (
            lv["level"], lv["resolution_m"], counts["polys"]["dropped_small"],
            counts["lines"]["dropped_small"], want_polys, want_lines))

    # --- vertices per level never grow.
    below = {c["layer"]: c["vertices_out"] for c in ix["manifest"]["layers"]}
    for lv in ix["levels"]:
        for c in lv["layers"]:
            if c["vertices_in"] != below_0(ix, c["layer"]):
                failures.append("level %d layer %s: vertices_in %d, level 0 has %d" % (
                    lv["level"], c["layer"], c["vertices_in"], below_0(ix, c["layer"])))
            if c["vertices_out"] > below[c["layer"]]:
                failures.append("level %d layer %s: %d vertices, more than the level below (%d)" %
                                (lv["level"], c["layer"], c["vertices_out"], below[c["layer"]]))
        below = {c["layer"]: c["vertices_out"] for c in lv["layers"]}

    # --- the tolerance bound (min(r_L, width) / 8) on a few tiles of each level (lines layer).
    src = json.load(open(os.path.join(work, "lines.geojson")))["features"]
    originals = [[tuple(p) for p in f["geometry"]["coordinates"]] for f in src]
    original_segments = Segments(originals)
    checked = 0
    for lv in ix["levels"]:
        r_l = lv["resolution_m"]
        tiles = sorted(lv["tiles"], key=lambda t: -t["counts"]["lines"])[:2]
        for t in tiles:
            got_lines = tile_lines(tool, ref, lv["level"], t)
            got_segments = Segments(got_lines)
            x0, y0, x1, y1 = t["square"]
            worst_in = max((original_segments.distance(p, 0.01) for pts in got_lines for p in pts),
                           default=0.0)
            worst_out = 0.0
            for pts in originals:
                length = sum(math.dist(pts[i], pts[i + 1]) for i in range(len(pts) - 1))
                if length < lv["min_length_m"]:
                    continue
                for p in pts:
                    if x0 <= p[0] < x1 and y0 <= p[1] < y1:
                        worst_out = max(worst_out, got_segments.distance(p, r_l))
                        checked += 1
            # The level's line tolerance (formats/SPEC.md "Overview levels").
            bound = min(r_l, LINE_WIDTH) / 8
            if worst_in > 0.001 or worst_out > bound + 0.001:
                failures.append("level %d tile %d,%d: a tile vertex %.4f m from the input, an "
                                "input vertex %.4f m from the tile (bound %.4f)" % (
                                    lv["level"], t["x"], t["y"], worst_in, worst_out, bound))
            print("level %d tile %d,%d: input within %.4f m of the tile (bound min(r, w)/8 = %.4f)" % (
                lv["level"], t["x"], t["y"], worst_out, bound))
    if checked == 0:
        failures.append("the tolerance check saw no input vertex")

    # --- tools.
    info = subprocess.run([tool, "info", ref], capture_output=True, text=True)
    if info.returncode != 0 or "level 3:" not in info.stdout or "dropped small" not in info.stdout:
        failures.append("info does not list the levels: " + info.stdout[-400:] + info.stderr)
    # The level tiles counted where a user reads totals: info's tiles line
    # and the build's closing line, against tileset.json's sizes.
    n0 = len(ix["tiles"])
    b0 = sum(t["bytes"] for t in ix["tiles"])
    nl = sum(len(lv["tiles"]) for lv in ix["levels"])
    bl = sum(t["bytes"] for lv in ix["levels"] for t in lv["tiles"])
    line = ("tiles     %d packages, %d bytes at full detail (level 0); %d packages, %d bytes with "
            "the %d overview levels" % (n0, b0, n0 + nl, b0 + bl, len(ix["levels"])))
    if line not in info.stdout:
        failures.append("info's tiles line leaves out the levels: wanted %r in %s" % (
            line, info.stdout[:400]))
    again = subprocess.run(base + ["--jobs", "2", "-o", os.path.join(work, "summary"), "--progress",
                                   "plain"], capture_output=True, text=True)
    # The progress counts candidate tiles; the closing line gives the same
    # count and how many of them held no part (the rest are the packages).
    cand = re.findall(r"^tiles: (\d+)/(\d+) candidate tiles", again.stderr, re.M)
    total = int(cand[-1][1]) if cand else -1
    said = ("tileset: %d tiles (%d built, 0 kept from an earlier run), %d bytes at full detail; "
            "overview levels 1..%d: %d tiles (%d built, 0 kept), %d bytes; %d tiles, %d bytes in "
            "all; %d candidate tiles, %d of them with no part; in %s" % (
                n0, n0, b0, len(ix["levels"]), nl, nl, bl, n0 + nl, b0 + bl, total,
                total - n0 - nl, os.path.join(work, "summary")))
    if again.returncode != 0 or total < n0 + nl or said not in again.stderr:
        failures.append("the build's closing line: wanted %r in %s" % (said, again.stderr[-600:]))
    ver = subprocess.run([tool, "verify", ref], capture_output=True, text=True)
    if ver.returncode != 0 or "overview levels" not in ver.stdout:
        failures.append("verify: exit %d %s %s" % (ver.returncode, ver.stdout, ver.stderr))
    broken = os.path.join(work, "broken")
    shutil.copytree(ref, broken)
    victim = ix["levels"][1]["tiles"][0]["file"]
    with open(os.path.join(broken, victim), "r+b") as f:
        f.seek(300)
        b = f.read(1)
        f.seek(300)
        f.write(bytes([b[0] ^ 0xff]))
    ver = subprocess.run([tool, "verify", broken], capture_output=True, text=True)
    if ver.returncode == 0 or victim not in ver.stderr:
        failures.append("verify of a damaged level tile: exit %d, %s" % (ver.returncode,
                                                                         ver.stderr.strip()))
    t0 = ix["levels"][0]["tiles"][0]
    d = subprocess.run([tool, "dump", ref, "--tile", "%d,%d" % (t0["x"], t0["y"]), "--level", "1",
                        "--summary"], capture_output=True, text=True)
    if d.returncode != 0 or "tile.level 1\n" not in d.stdout:
        failures.append("dump --level 1: exit %d, %s" % (d.returncode, d.stderr.strip()))

    # --- hostile indexes.
    def hostile(name, change, field):
        dst = os.path.join(work, "hostile_" + name)
        shutil.rmtree(dst, ignore_errors=True)
        shutil.copytree(ref, dst)
        j = json.load(open(os.path.join(dst, "tileset.json")))
        change(j)
        with open(os.path.join(dst, "tileset.json"), "w") as f:
            json.dump(j, f)
        r = subprocess.run([tool, "info", dst], capture_output=True, text=True)
        if field is None:
            if r.returncode != 0:
                failures.append("%s: refused: %s" % (name, r.stderr.strip()))
        elif r.returncode == 0 or field not in r.stderr or "tileset.json" not in r.stderr:
            failures.append("%s: exit %d, %s (wanted the field %s named)" % (
                name, r.returncode, r.stderr.strip(), field))

    def set_path(j):
        j["levels"][0]["tiles"][0]["file"] = "tiles/L1/../x0_y0.decals"

    def set_size(j):
        j["levels"][1]["tile_size_m"] = j["levels"][1]["tile_size_m"] * 2

    def skip_level(j):
        j["levels"][1]["level"] = 3

    def wrong_level_dir(j):
        t = j["levels"][1]["tiles"][0]
        t["file"] = "tiles/L1/x%d_y%d.decals" % (t["x"], t["y"])

    def as_1_0(j):
        j["tileset_version"] = "1.0"
        del j["levels"]
        del j["resolution_m"]

    def no_levels_1_1(j):
        del j["levels"]

    hostile("dotdot", set_path, "levels[0].tiles[0].file")
    hostile("size", set_size, "levels[1].tile_size_m")
    hostile("gap", skip_level, "levels[1].level")
    hostile("dir", wrong_level_dir, "levels[1].tiles[0].file")
    hostile("missing", no_levels_1_1, "levels")
    hostile("v1_0", as_1_0, None)

    # --- auto and usage.
    auto = os.path.join(work, "auto")
    r = subprocess.run([tool, "build", scene, "--tile-size", str(int(TILE)), "--levels", "auto",
                        "-o", auto, "--step", "prepare", "-q"], capture_output=True, text=True)
    if r.returncode != 0:
        failures.append("--levels auto --step prepare: " + r.stderr.strip())
    else:
        p = json.load(open(os.path.join(auto, ".work", "plan.json")))
        sizes = [len(p["tiles"])] + [len(l["tiles"]) for l in p["levels"]]
        # Tiles the data's box (no margin) meets on the top level.
        print("--levels auto: tiles per level %s" % sizes)
        if not p["levels"] or len(p["levels"]) > 16:
            failures.append("--levels auto made %d levels" % len(p["levels"]))
        else:
            top = TILE * 2 ** len(p["levels"])
            e = ix["extent"]
            nx = math.floor(e[2] / top) - math.floor(e[0] / top) + 1
            ny = math.floor(e[3] / top) - math.floor(e[1] / top) + 1
            below_top = TILE * 2 ** (len(p["levels"]) - 1)
            bx = math.floor(e[2] / below_top) - math.floor(e[0] / below_top) + 1
            by = math.floor(e[3] / below_top) - math.floor(e[1] / below_top) + 1
            if nx * ny > 4 or bx * by <= 4:
                failures.append("--levels auto: %d levels, the top covers the data with %d tiles, "
                                "the one below with %d" % (len(p["levels"]), nx * ny, bx * by))
    r = subprocess.run([tool, "build", scene, "--levels", "2", "-o", os.path.join(work, "x.decals"),
                        "-q"], capture_output=True, text=True)
    if r.returncode != 2 or "--levels" not in r.stderr or "--tile-size" not in r.stderr:
        failures.append("--levels without --tile-size: exit %d, %s" % (r.returncode,
                                                                       r.stderr.strip()))

    # --- the scene file's [tiling] levels: as --levels; without a tile size, named.
    with open(scene) as f:
        text = f.read()
    tiled = os.path.join(work, "tiled.toml")
    with open(tiled, "w") as f:
        f.write(text.replace('crs = "EPSG:32632"\n',
                             'crs = "EPSG:32632"\n\n[tiling]\ntile_size = 500\nlevels = "auto"\n'))
    r = subprocess.run([tool, "build", tiled, "-o", os.path.join(work, "auto_file"), "--step",
                        "prepare", "-q"], capture_output=True, text=True)
    if r.returncode != 0:
        failures.append("[tiling] levels = \"auto\": " + r.stderr.strip())
    elif os.path.exists(os.path.join(auto, ".work", "plan.json")):
        a = json.load(open(os.path.join(auto, ".work", "plan.json")))["levels"]
        b = json.load(open(os.path.join(work, "auto_file", ".work", "plan.json")))["levels"]
        if a != b:
            failures.append("[tiling] levels = \"auto\" planned other levels than --levels auto")
    untiled = os.path.join(work, "untiled.toml")
    with open(untiled, "w") as f:
        f.write(text.replace('crs = "EPSG:32632"\n',
                             'crs = "EPSG:32632"\n\n[tiling]\nlevels = 2\n'))
    r = subprocess.run([tool, "build", untiled, "-o", os.path.join(work, "y.decals"), "-q"],
                       capture_output=True, text=True)
    if r.returncode != 2 or "[tiling] levels" not in r.stderr:
        failures.append("[tiling] levels without a tile size: exit %d, %s" % (r.returncode,
                                                                              r.stderr.strip()))

    # --- fewer levels over the same folder: the stale level files go.
    fewer = os.path.join(work, "fewer")
    shutil.copytree(ref, fewer)
    r = subprocess.run([tool, "build", scene, "--tile-size", str(int(TILE)), "--levels", "1",
                        "--jobs", "2", "-o", fewer, "-q"], capture_output=True, text=True)
    left = sorted(d for d in os.listdir(os.path.join(fewer, "tiles")) if d.startswith("L"))
    if r.returncode != 0 or left != ["L1"]:
        failures.append("--levels 1 over a 3-level tileset: exit %d, level folders %s" % (
            r.returncode, left))
    elif tree(fewer, skip=("plan.json",)) != {k: v for k, v in want.items() if not k.startswith(("tiles/L2/",
                                                                              "tiles/L3/",
                                                                              "tileset.json"))} | \
            {"tileset.json": tree(fewer, skip=("plan.json",))["tileset.json"]}:
        failures.append("--levels 1 over a 3-level tileset changed level 0 or level 1's tiles")

    for f in failures:
        print("FAIL:", f)
    if not failures:
        print("levels: steps equal the one-process build (%d files), drops equal ogrinfo's "
              "counts, vertices never grow, %d input vertices within r/2 of their level tile" %
              (len(want), checked))
    return 1 if failures else 0


def below_0(ix, layer):
    return next(c["vertices_out"] for c in ix["manifest"]["layers"] if c["layer"] == layer)


if __name__ == "__main__":
    sys.exit(main())
