#!/usr/bin/env python3
"""Dynamic lines keep their LOCALIS LOD on every level of a tileset
(formats/SPEC.md "Overview levels": "dynamic lines with `lod` get their LOD
structures from the level's geometry"; the blobs and the visibility rule:
SPEC "LodPoint", "LodSegment").

The scene, in EPSG:32632 and built with --crs EPSG:32632 --tile-size 500
--levels 3 (no DEM, no lmax: flat terrain, dynamic lines not subdivided):
- `walks`: dynamic lines (3 px) with `lod = true`, WALKS random walks
  along x (x steps of 1.5-3.5 m, y a bounded random walk plus a +-0.3 m zigzag,
  every vertex on the 1 mm grid), each in its own 60 m band whose edges stay
  clear of every tile's window edge (multiples of 250 m from the grid's
  origin), so that each tile holds one run of each line;
- `plain`: a few dynamic lines without `lod`.

Every package of every level (level 0 and the overview levels) is read with
the independent reader python/decalprep/spec_reader.py, never with decalprep's
own code, and checked against oracles computed here from the SPEC:
- LOD presence: one `lod_line_range` entry per `walks` dynamic line, none
  for `plain`; every range non-empty, all its points belonging to one
  `walks` line (LodPoint `line`), each line exactly once;
- the points: the original segments (splitter kLodNone) form one chain
  from the line's first to its last point, the chain's points are exactly
  the LOD points whose `line` is that line, and their positions are the
  line's `dyn_vertices` (x, y), in order;
- the hierarchy, by the SPEC's visibility rule evaluated here (a point is
  included iff bit 0 of its flags or e_star > eps(d - d_star); a segment is
  visible iff its generator is kLodNone or included and its splitter is
  kLodNone or not included): for constant thresholds eps (-1, 0, 0.2, 0.6
  and 3 m) the visible segments form one polyline whose vertices are this
  test's own Douglas-Peucker simplification of the line's dyn_vertices at
  tolerance eps (recursive; a sub-line's farthest vertex from the segment
  between its ends, the first on ties, is kept iff its distance exceeds
  eps). At eps = -1 m and at 0 (no vertex of this data lies on its chord)
  that is every vertex: the finest threshold gives back the
  consecutive-vertex segments. The SPEC promises exactly Douglas-Peucker
  only in a package built without dependees (LOCALIS §3.4: points whose
  presence keeps a simplification from crossing them); this scene has none
  by construction, which the test checks per tile: every line is strictly
  increasing in x and every pair of walks lines of a tile has disjoint x
  ranges or disjoint y ranges, so no point of a line lies in the box of
  another line's sub-line, nor between the x of its own line's sub-line
  ends unless it is one of the sub-line's vertices. Thresholds are moved to
  at least 0.2 mm from every chord distance so that the float32 e_star
  cannot decide a tie. The SPEC does not say whether Douglas-Peucker
  measures to the chord's segment or to its line; on this data the two
  agree;
- a distance-dependent threshold (eps(d) = 0.002 d, camera 300 m above the
  tile's origin): the visible segments still form one polyline from the
  line's first to its last point (the SPEC's guarantee for every camera and
  every non-decreasing eps);
- the level geometry: each walks line of a tile is a run of its input line
  (found by its band): its vertices are input vertices, in order. On level
  0 the run holds every input vertex between its ends; on each overview
  level at least one run holds fewer (the level's simplification), every
  input vertex between its ends lies within r_L / 8 + 1 mm of it (SPEC
  "Overview levels"), and the LOD checks above hold for those simplified
  lines too.

Usage: tileset_levels_lod_test.py DECALPREP WORK_DIR
Exit 0 pass, 1 fail, 77 skip (the reader's python3-numpy, python3-xxhash or
python3-zstandard missing).
"""
import bisect
import json
import math
import os
import random
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
# The independent reader, python/decalprep, from the source tree.
sys.path.insert(0, os.path.join(HERE, "..", "..", "python"))
sys.path.insert(0, HERE)
from tileset_util import write_scene  # noqa: E402
try:
    from decalprep import spec_reader as sr  # noqa: E402
except ImportError as e:
    print("SKIP: python/decalprep needs python3-numpy, python3-xxhash and python3-zstandard (%s)" % e)
    sys.exit(77)

TILE = 500
LEVELS = 3
X0, Y0 = 372_000, 4_840_000  # on the grid of every level (4000 m at level 3)
WALKS = 8
BAND = 60  # m between walk centres; a walk stays within +-WANDER + ZIG of it
WANDER = 15.0
ZIG = 0.3
PLAIN = 3
NONE = sr.LOD_NONE
NUDGE = 2e-4  # m: no constant threshold lies closer than this to a chord distance


def band_centre(k):
    return Y0 + 50 + BAND * k


def walk(rng, k):
    """Walk k as vertices in whole millimetres (ints), x strictly increasing."""
    x = (X0 + 20 + 37 * k) * 1000
    end = x + (900 + 45 * k) * 1000
    yc = band_centre(k) * 1000
    y = 0.0
    pts = []
    i = 0
    while x <= end:
        y = max(-WANDER, min(WANDER, y + rng.gauss(0.0, 0.4)))
        zig = ZIG if i % 2 else -ZIG
        pts.append((x, yc + int(round((y + zig) * 1000))))
        x += rng.randint(1500, 3500)
        i += 1
    return pts


def write_inputs(work):
    rng = random.Random(20261124)
    walks = [walk(rng, k) for k in range(WALKS)]
    feats = [{"type": "Feature", "properties": {"id": k},
              "geometry": {"type": "LineString",
                           "coordinates": [[x / 1000.0, y / 1000.0] for x, y in pts]}}
             for k, pts in enumerate(walks)]
    plain = []
    for k in range(PLAIN):
        y = band_centre(WALKS + 1 + k)
        plain.append({"type": "Feature", "properties": {"id": k},
                      "geometry": {"type": "LineString",
                                   "coordinates": [[X0 + 30.0 + 10 * j, y + (j % 2)]
                                                   for j in range(60)]}})
    write_scene(work, [("walks", "line", feats,
                        'dynamic = true\nlod = true\nwidth = 3\ncolor = "#e4572e"\n'),
                       ("plain", "line", plain, 'dynamic = true\nwidth = 2\ncolor = "#3366aa"\n')])
    return walks


# ------------------------------------------------------------------ oracles --

def seg_dist(p, a, b):
    """Distance in metres from p to the segment ab (points in quanta)."""
    ax, ay = a[0] * 1e-3, a[1] * 1e-3
    vx, vy = b[0] * 1e-3 - ax, b[1] * 1e-3 - ay
    wx, wy = p[0] * 1e-3 - ax, p[1] * 1e-3 - ay
    vv = vx * vx + vy * vy
    t = 0.0 if vv == 0 else max(0.0, min(1.0, (wx * vx + wy * vy) / vv))
    return math.hypot(wx - t * vx, wy - t * vy)


def dp_tree(pts):
    """The Douglas-Peucker recursion over the whole line, once: per sub-line
    (lo, hi) with a vertex between its ends, the farthest vertex from the
    chord's segment (the first on ties) and its distance, as
    {(lo, hi): (split, distance)}. The split does not depend on the
    tolerance, so every tolerance's result is a walk of this tree."""
    out, stack = {}, [(0, len(pts) - 1)]
    while stack:
        lo, hi = stack.pop()
        if hi - lo < 2:
            continue
        a, b = pts[lo], pts[hi]
        best, best_d = lo + 1, -1.0
        for i in range(lo + 1, hi):
            d = seg_dist(pts[i], a, b)
            if d > best_d:
                best, best_d = i, d
        out[(lo, hi)] = (best, best_d)
        stack += [(lo, best), (best, hi)]
    return out


def douglas_peucker(tree, n, eps):
    """Indices of the vertices Douglas-Peucker keeps at tolerance eps: a
    sub-line's farthest vertex is kept, and both halves simplified in turn,
    iff its distance exceeds eps."""
    keep = {0, n - 1}
    stack = [(0, n - 1)]
    while stack:
        lo, hi = stack.pop()
        if (lo, hi) not in tree:
            continue
        best, best_d = tree[(lo, hi)]
        if best_d > eps:
            keep.add(best)
            stack += [(lo, best), (best, hi)]
    return sorted(keep)


def included(p, eps_of_d, cam):
    """SPEC "Visibility rule": is LOD point p included?"""
    if p["flags"] & 1:
        return True
    d = math.sqrt((p["eval_x"] * 1e-3 - cam[0]) ** 2 + (p["eval_y"] * 1e-3 - cam[1]) ** 2 +
                  cam[2] ** 2)
    return p["e_star"] > eps_of_d(d - p["d_star"])


def visible_chain(points, segs, first, last, eps_of_d, cam):
    """The visible segments (SPEC rule) as one chain from `first` to `last`
    (point indices), or a string saying why they are not one."""
    inc = {}

    def on(i):
        if i not in inc:
            inc[i] = included(points[i], eps_of_d, cam)
        return inc[i]

    nxt = {}
    for s in segs:
        if (s["generator"] == NONE or on(s["generator"])) and \
           (s["splitter"] == NONE or not on(s["splitter"])):
            if s["a"] in nxt:
                return "two visible segments start at point %d" % s["a"]
            nxt[s["a"]] = s["b"]
    chain = [first]
    while chain[-1] != last:
        if chain[-1] not in nxt or len(chain) > len(nxt):
            return "the visible segments break off at point %d" % chain[-1]
        chain.append(nxt[chain[-1]])
    if len(chain) - 1 != len(nxt):
        return "%d visible segments, %d on the chain" % (len(nxt), len(chain) - 1)
    return chain


# ------------------------------------------------------------------- checks --

def check_tile(out, file, level, walks, stats, failures):
    where = "level %d %s" % (level, file)
    p = sr.read_file(os.path.join(out, file))
    bad = sr.check_indices(p)
    if bad:
        failures.append("%s: index constraints: %s" % (where, bad[:3]))
        return
    meta = p.metadata
    layer_names = [l["layer"] for l in meta["manifest"]["layers"]]
    ox, oy = int(round(meta["origin"]["x"] * 1000)), int(round(meta["origin"]["y"] * 1000))

    def el(name):
        b = p.blob(name)
        return sr.elements(b) if b is not None else []

    verts, starts, props = el("dyn_vertices"), el("dyn_line_start"), el("dyn_line_props")
    points, segments, ranges = el("lod_points"), el("lod_segments"), el("lod_line_range")
    walk_lines = [j for j, pr in enumerate(props) if layer_names[pr["layer"]] == "walks"]
    if not walk_lines:
        if ranges:
            failures.append("%s: %d LOD lines but no walks line" % (where, len(ranges)))
        return
    ends = list(starts[1:]) + [len(verts)]
    line_pts = {j: [(v[0], v[1]) for v in verts[starts[j]:ends[j]]] for j in walk_lines}
    stats["tiles"][level] += 1

    # No dependees by construction (docstring): x increasing, boxes apart.
    boxes = {}
    for j, pts in line_pts.items():
        if any(pts[i + 1][0] <= pts[i][0] for i in range(len(pts) - 1)):
            failures.append("%s: walks line %d is not increasing in x (test data)" % (where, j))
            return
        ys = [q[1] for q in pts]
        boxes[j] = (pts[0][0], pts[-1][0], min(ys), max(ys))
    for i in walk_lines:
        for j in walk_lines:
            if i < j:
                a, b = boxes[i], boxes[j]
                if a[0] <= b[1] and b[0] <= a[1] and a[2] <= b[3] and b[2] <= a[3]:
                    failures.append("%s: walks lines %d and %d have overlapping boxes (test data)"
                                    % (where, i, j))
                    return

    # Presence: one range per walks line, none for plain lines.
    if len(ranges) != len(walk_lines):
        failures.append("%s: %d lod_line_range entries for %d walks dynamic lines" % (
            where, len(ranges), len(walk_lines)))
    points_of = {}
    for i, q in enumerate(points):
        points_of.setdefault(q["line"], set()).add(i)
    seen = set()
    for k, (first, count) in enumerate(ranges):
        if count == 0:
            failures.append("%s: LOD line %d has an empty range" % (where, k))
            continue
        segs = segments[first:first + count]
        refs = set()
        for s in segs:
            refs.update(v for v in (s["a"], s["b"], s["generator"], s["splitter"]) if v != NONE)
        owners = {points[i]["line"] for i in refs}
        if len(owners) != 1:
            failures.append("%s: LOD line %d has points of dynamic lines %s" % (
                where, k, sorted(owners)))
            continue
        j = owners.pop()
        if j not in line_pts or j in seen:
            failures.append("%s: LOD line %d is dynamic line %d (%s)" % (
                where, k, j, "again" if j in seen else "not a walks line"))
            continue
        seen.add(j)
        pts = line_pts[j]

        # The points: the original segments chain the line's vertices.
        orig = [s for s in segs if s["splitter"] == NONE]
        nxt = {s["a"]: s["b"] for s in orig}
        starts_ = set(nxt) - set(nxt.values())
        if len(nxt) != len(orig) or len(starts_) != 1:
            failures.append("%s: LOD line %d: the original segments are no chain" % (where, k))
            continue
        chain = [starts_.pop()]
        while chain[-1] in nxt and len(chain) <= len(orig):
            chain.append(nxt[chain[-1]])
        mine = points_of.get(j, set())
        got = [(points[i]["x"], points[i]["y"]) for i in chain]
        if len(chain) != len(orig) + 1 or set(chain) != mine or refs - mine:
            failures.append("%s: LOD line %d: %d original segments chain %d points; the line "
                            "has %d LOD points" % (where, k, len(orig), len(chain), len(mine)))
            continue
        if got != pts:
            diff = next((i for i in range(min(len(got), len(pts))) if got[i] != pts[i]),
                        min(len(got), len(pts)))
            failures.append("%s: LOD line %d: its %d points are not dynamic line %d's %d "
                            "vertices (first difference at %d)" % (where, k, len(got), j,
                                                                   len(pts), diff))
            continue

        # The hierarchy: constant thresholds select Douglas-Peucker.
        tree = dp_tree(pts)
        dists = sorted(d for _, d in tree.values())
        index_of = {pt: i for i, pt in enumerate(chain)}
        for target in (-1.0, 0.0, 0.2, 0.6, 3.0):
            eps = target
            while True:  # nudge eps off every chord distance
                at = bisect.bisect_left(dists, eps - NUDGE)
                if at == len(dists) or dists[at] > eps + NUDGE:
                    break
                eps = dists[at] + 2 * NUDGE
            vis = visible_chain(points, segs, chain[0], chain[-1], lambda d, e=eps: e,
                                (0.0, 0.0, 0.0))
            if isinstance(vis, str):
                failures.append("%s: LOD line %d at eps %.4f m: %s" % (where, k, eps, vis))
                continue
            want = douglas_peucker(tree, len(pts), eps)
            if eps <= 0 and want != list(range(len(pts))):
                failures.append("%s: line %d has a collinear vertex (test data)" % (where, j))
            have = [index_of[i] for i in vis]
            if have != want:
                failures.append("%s: LOD line %d at eps %.4f m: %d visible vertices, Douglas-"
                                "Peucker keeps %d (first difference at vertex %s)" % (
                                    where, k, eps, len(have), len(want),
                                    next((a for a, b in zip(have, want) if a != b), "end")))
            stats["dp_checks"] += 1
            if target == 0.6:
                stats["kept_06"][level] += len(want)
                stats["verts"][level] += len(pts)

        # A distance-dependent threshold: still one polyline end to end.
        cam = (0.0, 0.0, 300.0)
        vis = visible_chain(points, segs, chain[0], chain[-1], lambda d: 0.002 * max(d, 0.0), cam)
        if isinstance(vis, str):
            failures.append("%s: LOD line %d, eps(d) = 0.002 d: %s" % (where, k, vis))
        stats["lod_lines"][level] += 1

    if seen != set(walk_lines):
        failures.append("%s: walks lines without LOD: %s" % (where, sorted(set(walk_lines) - seen)))

    # The level geometry: each line is a run of its input walk.
    for j, pts in line_pts.items():
        absolute = [(ox + x, oy + y) for x, y in pts]
        k = int(round((absolute[0][1] / 1000.0 - Y0 - 50) / BAND))
        src = walks[k] if 0 <= k < len(walks) else []
        inside = [q for q in src if absolute[0][0] <= q[0] <= absolute[-1][0]]
        pos = {q: i for i, q in enumerate(inside)}
        idx = [pos.get(q) for q in absolute]
        if None in idx or idx != sorted(idx) or idx[0] != 0 or idx[-1] != len(inside) - 1:
            failures.append("%s: dynamic line %d is not a run of input walk %d" % (where, j, k))
            continue
        stats["runs"][level] += 1
        # Every input vertex of the run within r_L / 8 (SPEC "Overview
        # levels"; 0 on level 0) of the level line's segment over its x: a
        # vertex the simplification removed lies between its chord's ends.
        tol = TILE * 2 ** level / 1024 / 8 if level else 0.0
        xs = [q[0] for q in absolute]
        worst = 0.0
        for q in inside:
            i = min(max(bisect.bisect_right(xs, q[0]) - 1, 0), len(xs) - 2)
            worst = max(worst, seg_dist(q, absolute[i], absolute[i + 1]))
        stats["worst"][level] = max(stats["worst"][level], worst / tol if tol else worst)
        if worst > tol + 0.001:
            failures.append("%s: an input vertex of walk %d is %.4f m from dynamic line %d "
                            "(r/8 = %.4f m)" % (where, k, worst, j, tol))
        if len(pts) < len(inside):
            stats["simplified"][level] += 1
            if level == 0:
                failures.append("%s: dynamic line %d has %d vertices, its run of walk %d has %d"
                                % (where, j, len(pts), k, len(inside)))


def main():
    tool, work = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    walks = write_inputs(work)
    out = os.path.join(work, "tiles")
    t0 = time.time()
    r = subprocess.run([tool, "build", os.path.join(work, "scene.toml"), "-o", out, "--tile-size",
                        str(TILE), "--levels", str(LEVELS), "--jobs", "2", "-q"],
                       capture_output=True, text=True)
    built = time.time() - t0
    if r.returncode != 0:
        print("FAIL: build exited %d: %s" % (r.returncode, r.stderr.strip()))
        return 1
    ix = json.load(open(os.path.join(out, "tileset.json")))
    failures = []
    stats = {key: [0] * (LEVELS + 1) for key in
             ("tiles", "lod_lines", "runs", "simplified", "verts", "kept_06", "worst")}
    stats["dp_checks"] = 0
    levels = [(0, ix["tiles"])] + [(lv["level"], lv["tiles"]) for lv in ix.get("levels", [])]
    if len(levels) != LEVELS + 1:
        failures.append("tileset.json has %d levels, not %d" % (len(levels) - 1, LEVELS))
    for level, tiles in levels:
        for t in tiles:
            check_tile(out, t["file"], level, walks, stats, failures)
    for level in range(LEVELS + 1):
        print("level %d: %d tiles with walks, %d LOD lines, %d runs (%d simplified, input at most "
              "%.3f r/8 away), %d vertices, %d kept by Douglas-Peucker at 0.6 m" % (
                  level, stats["tiles"][level], stats["lod_lines"][level], stats["runs"][level],
                  stats["simplified"][level], stats["worst"][level], stats["verts"][level],
                  stats["kept_06"][level]))
        if stats["lod_lines"][level] == 0:
            failures.append("level %d: no tile with LOD lines" % level)
        if level > 0 and stats["simplified"][level] == 0:
            failures.append("level %d: no walk is simplified" % level)
    print("%d Douglas-Peucker comparisons; build %.1f s, checks %.1f s" % (
        stats["dp_checks"], built, time.time() - t0 - built))
    for f in failures[:20]:
        print("FAIL:", f)
    if len(failures) > 20:
        print("... and %d more" % (len(failures) - 20))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
