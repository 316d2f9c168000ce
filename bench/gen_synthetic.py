#!/usr/bin/env python3
"""Generates synthetic benchmark inputs of a given vertex count.

  gen_synthetic.py KIND VERTICES OUT.geojsonl [--seed S] [--extent M]

KIND: polygons  - star-shaped polygons with 0-3 holes each (~200 vertices each)
      lines     - a jittered street-like network of polylines (~50 vertices each)
      mix       - half of each
      fine      - smooth polygons drawn with a vertex every 0.2 m (90% of the
                  vertices) and smooth lines with a vertex every metre: detail
                  far below what a whole-extent view can show, which overview
                  levels simplify away (a tileset's coarse levels are a few
                  percent of its bytes)
Output is GeoJSON sequence (one feature per line) in EPSG:32632 (UTM 32N, around
Monaco), so that no reprojection distortion hides in the timings; convert with
`ogr2ogr -f FlatGeobuf out.fgb OUT.geojsonl -a_srs EPSG:32632` for fast reads.
The features lie in a square of side 2 km * sqrt(VERTICES / 10^4) (constant
density), or of side M metres with --extent (the same features, sparser or
denser). Deterministic for a given seed. Standard library only.

The benches and tests import mix_scene(): "mix" as FlatGeobuf (ogr2ogr)
beside a scene file of two layers over it, polygons and 3 m lines.
"""
import json
import math
import os
import random
import subprocess
import sys

X0, Y0 = 370_000.0, 4_840_000.0  # UTM 32N near Monaco


def star(rng, cx, cy, r, n, cw=False):
    pts = []
    for i in range(n):
        a = 2 * math.pi * i / n
        rr = r * (0.75 + 0.25 * rng.random())
        pts.append([round(cx + rr * math.cos(a), 3), round(cy + rr * math.sin(a), 3)])
    if cw:
        pts.reverse()
    pts.append(pts[0])
    return pts


def polygons(rng, budget, out, fid, extent):
    while budget > 0:
        n = min(budget, rng.randint(100, 300))
        cx, cy = X0 + rng.random() * extent, Y0 + rng.random() * extent
        r = 20 + rng.random() * 200
        rings = [star(rng, cx, cy, r, max(n - 40, 8))]
        left = n - len(rings[0])
        for h in range(rng.randint(0, 3)):
            if left < 8:
                break
            k = min(left, 10)
            a = 2 * math.pi * h / 3
            rings.append(star(rng, cx + 0.4 * r * math.cos(a), cy + 0.4 * r * math.sin(a), 0.15 * r, k, cw=True))
            left -= k + 1
        budget -= sum(len(x) for x in rings)
        out.write(json.dumps({"type": "Feature", "id": fid, "properties": {"id": fid, "class": fid % 7},
                              "geometry": {"type": "Polygon", "coordinates": rings}}) + "\n")
        fid += 1
    return fid


def lines(rng, budget, out, fid, extent):
    while budget > 0:
        n = min(max(budget, 2), rng.randint(20, 80))
        x, y = X0 + rng.random() * extent, Y0 + rng.random() * extent
        heading = rng.random() * 2 * math.pi
        pts = []
        for _ in range(n):
            pts.append([round(x, 3), round(y, 3)])
            heading += rng.gauss(0, 0.3)
            step = 5 + rng.random() * 30
            x += step * math.cos(heading)
            y += step * math.sin(heading)
        budget -= n
        out.write(json.dumps({"type": "Feature", "id": fid, "properties": {"id": fid, "class": fid % 5},
                              "geometry": {"type": "LineString", "coordinates": pts}}) + "\n")
        fid += 1
    return fid


def smooth_star(rng, cx, cy, r, n):
    """A closed ring of n vertices around (cx, cy): radius r varied by four
    sine waves of 2-9 turns (at most 15% each), smooth at every scale
    below a few metres."""
    waves = [(rng.randint(2, 9), rng.random() * 0.15, rng.random() * 2 * math.pi) for _ in range(4)]
    pts = []
    for i in range(n):
        a = 2 * math.pi * i / n
        rr = r * (1 + sum(amp * math.sin(f * a + ph) for f, amp, ph in waves))
        pts.append([round(cx + rr * math.cos(a), 3), round(cy + rr * math.sin(a), 3)])
    pts.append(pts[0])
    return pts


def fine(rng, budget, out, fid, extent):
    polygon_budget = int(budget * 0.9)
    while polygon_budget > 0:
        r = 40 + rng.random() * 160
        n = min(max(16, int(2 * math.pi * r / 0.2)), polygon_budget + 16)
        ring = smooth_star(rng, X0 + rng.random() * extent, Y0 + rng.random() * extent, r, n)
        polygon_budget -= len(ring)
        out.write(json.dumps({"type": "Feature", "id": fid, "properties": {"id": fid, "class": fid % 7},
                              "geometry": {"type": "Polygon", "coordinates": [ring]}}) + "\n")
        fid += 1
    line_budget = budget - int(budget * 0.9)
    while line_budget > 0:
        n = min(max(line_budget, 2), rng.randint(200, 600))
        x, y = X0 + rng.random() * extent, Y0 + rng.random() * extent
        heading, turn, pts = rng.random() * 2 * math.pi, rng.gauss(0, 0.01), []
        for _ in range(n):
            pts.append([round(x, 3), round(y, 3)])
            turn += rng.gauss(0, 0.002)
            heading += turn
            x += math.cos(heading)
            y += math.sin(heading)
        line_budget -= n
        out.write(json.dumps({"type": "Feature", "id": fid, "properties": {"id": fid, "class": fid % 5},
                              "geometry": {"type": "LineString", "coordinates": pts}}) + "\n")
        fid += 1
    return fid


def write(kind, vertices, path, seed=1, extent=None):
    """Writes KIND with about VERTICES vertices to PATH (GeoJSON sequence)."""
    rng = random.Random(seed)
    # Keep density roughly constant: extent grows with sqrt(vertices).
    if extent is None:
        extent = 2_000.0 * math.sqrt(max(vertices, 10_000) / 10_000)
    with open(path, "w") as out:
        if kind == "polygons":
            polygons(rng, vertices, out, 1, extent)
        elif kind == "lines":
            lines(rng, vertices, out, 1, extent)
        elif kind == "mix":
            fid = polygons(rng, vertices // 2, out, 1, extent)
            lines(rng, vertices - vertices // 2, out, fid, extent)
        elif kind == "fine":
            fine(rng, vertices, out, 1, extent)
        else:
            sys.exit(f"gen_synthetic: unknown kind '{kind}' (polygons|lines|mix|fine)")


def mix_scene(work, vertices, name="mix", extent=None, seed=1, kind="mix"):
    """Writes WORK/NAME.fgb (KIND, "mix" by default; layer NAME, EPSG:32632)
    and WORK/NAME.toml, a scene of two layers over it: "polygons" and
    "lines" (3 m wide). Returns (scene path, FlatGeobuf path). Needs
    ogr2ogr."""
    gj = os.path.join(work, name + ".geojsonl")
    fgb = os.path.join(work, name + ".fgb")
    write(kind, vertices, gj, seed, extent)
    subprocess.run(["ogr2ogr", "-f", "FlatGeobuf", fgb, gj, "-a_srs", "EPSG:32632", "-nln", name],
                   check=True)
    os.remove(gj)
    scene = os.path.join(work, name + ".toml")
    with open(scene, "w") as f:
        f.write('source = "%s"\ncrs = "EPSG:32632"\n' % fgb)
        for layer, kind, extra, geom in (("polygons", "polygon", "", "POLYGON"),
                                         ("lines", "line", "width = 3\n", "LINESTRING")):
            f.write('[[layer]]\nname = "%s"\nkind = "%s"\n%ssql = "SELECT * FROM %s '
                    'WHERE OGR_GEOMETRY = \'%s\'"\n' % (layer, kind, extra, name, geom))
    return scene, fgb


def main():
    kind, vertices, path = sys.argv[1], int(float(sys.argv[2])), sys.argv[3]
    seed = int(sys.argv[sys.argv.index("--seed") + 1]) if "--seed" in sys.argv else 1
    extent = float(sys.argv[sys.argv.index("--extent") + 1]) if "--extent" in sys.argv else None
    write(kind, vertices, path, seed, extent)


if __name__ == "__main__":
    main()
