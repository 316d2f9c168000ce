#!/usr/bin/env python3
"""Writes the seed corpus of fuzz_model (fuzz/corpus/model/) from the hostile
corpus (tests/hostile/generate.py), in fuzz_model's input layout:
  byte 0 style, byte 1 width (dm - 1), byte 2 'W' + WKT lines, or another
  byte + WKB records (uint16 little-endian length + WKB).
GeoJSON cases become WKT in local metres (as the clean stage sees them after
project); the NaN / Inf / 1e300 cases become WKB so that the doubles are exact.

Usage: make_model_seeds.py HOSTILE_CORPUS_DIR OUT_DIR
"""
import json
import math
import os
import struct
import sys

LON0, LAT0 = 7.42, 43.73
M = 1.0 / 111_320.0


def metres(c):
    lon, lat = c[0], c[1]
    if not (math.isfinite(lon) and math.isfinite(lat)) or abs(lon) > 1000:
        return (lon, lat)
    return ((lon - LON0) / (M / math.cos(math.radians(LAT0))), (lat - LAT0) / M)


def fmt(p):
    return "%.6f %.6f" % p


def wkt(g):
    t = g["type"]
    c = g.get("coordinates")
    if t == "Point":
        return "POINT (%s)" % fmt(metres(c))
    if t == "LineString":
        return "LINESTRING EMPTY" if not c else "LINESTRING (%s)" % ", ".join(fmt(metres(p)) for p in c)
    if t == "Polygon":
        if not c:
            return "POLYGON EMPTY"
        return "POLYGON (%s)" % ", ".join("(%s)" % ", ".join(fmt(metres(p)) for p in r) for r in c)
    if t == "MultiPolygon":
        return "MULTIPOLYGON (%s)" % ", ".join(
            "(%s)" % ", ".join("(%s)" % ", ".join(fmt(metres(p)) for p in r) for r in poly) for poly in c)
    if t == "GeometryCollection":
        return "GEOMETRYCOLLECTION (%s)" % ", ".join(wkt(x) for x in g["geometries"])
    return None


def wkb_line(points):
    return struct.pack("<BII", 1, 2, len(points)) + b"".join(struct.pack("<2d", *p) for p in points)


def wkb_polygon(rings):
    out = struct.pack("<BII", 1, 3, len(rings))
    for r in rings:
        out += struct.pack("<I", len(r)) + b"".join(struct.pack("<2d", *p) for p in r)
    return out


def records(*geoms):
    return b"".join(struct.pack("<H", len(g)) + g for g in geoms)


def style(kind, corner):
    k = {"polygon": 0, "line": 1, "outline": 2}[kind]
    c = {"round": 0, "miter": 1, "bevel": 2}[corner]
    return k | (c << 2)


def main():
    corpus, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    cases = json.load(open(os.path.join(corpus, "cases.json"), encoding="utf-8"))
    n = 0
    for c in cases:
        if c.get("big") or not c["path"].endswith(".geojson"):
            continue
        fc = json.load(open(c["path"], encoding="utf-8"))
        lines = [w for w in (wkt(f["geometry"]) for f in fc["features"] if f.get("geometry")) if w]
        if not lines:
            continue
        args = c["args"]
        corner = args[args.index("--corner") + 1] if "--corner" in args else "round"
        width = float(args[args.index("--width") + 1]) if "--width" in args else 2.0
        data = bytes([style(c["kind"], corner), max(0, min(255, round(width * 10) - 1)), ord("W")])
        data += "\n".join(lines).encode()
        if len(data) > 60_000:
            continue
        open(os.path.join(out, c["name"] + ".seed"), "wb").write(data)
        n += 1
        if c["kind"] == "polygon":  # the same shapes as outlines, miter, offset mode
            open(os.path.join(out, c["name"] + "_outline.seed"), "wb").write(
                bytes([2 | (1 << 2) | (2 << 4), 9]) + data[2:])
            n += 1
    nan, inf = float("nan"), float("inf")
    sq = [(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]
    extra = {
        "wkb_nan_polygon": (0, records(wkb_polygon([[(0, 0), (nan, 0), (0, 10), (0, 0)]]), wkb_polygon([sq]))),
        "wkb_inf_line": (1, records(wkb_line([(0, 0), (inf, 0)]), wkb_line([(0, 0), (10, 0)]))),
        "wkb_1e300_line": (1, records(wkb_line([(0, 0), (1e300, 0)]), wkb_line([(0, 0), (10, 0)]))),
        "wkb_utm_1mm": (1, records(wkb_line([(500000.0, 9999000.0), (500000.001, 9999000.001),
                                             (500010.0, 9999000.002)]))),
        "wkb_reversal_miter": (1 | (1 << 2), records(wkb_line([(0, 0), (10, 0), (0, 0)]))),
        "wkb_far_apart": (0, records(wkb_polygon([sq]), wkb_polygon([[(x + 3e6, y) for x, y in sq]]))),
    }
    for name, (st, body) in extra.items():
        open(os.path.join(out, name + ".seed"), "wb").write(bytes([st, 19, ord("B")]) + body)
        n += 1
    print(f"fuzz_model seeds: wrote {n} files to {out}")


if __name__ == "__main__":
    main()
