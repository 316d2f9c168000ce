#!/usr/bin/env python3
"""Writes the hostile-input corpus (tests/hostile/README.md) into OUTDIR.

Every case is a small file that decalprep reads through GDAL, plus a row in
OUTDIR/cases.json naming the file, the build arguments and the expected
behaviour. Expectations live in tests/hostile/expected.json (checked in), keyed
by case name, so that the generator only makes inputs.

Usage: generate.py OUTDIR [--big]   (--big adds the 10^6-vertex, 10^5-hole and
                                      10^4-teeth cases; they take seconds to write)
Needs only the Python standard library; shapefiles are written byte by byte so
that NaN/Inf coordinates and broken files can be made exactly.
"""
import json
import math
import os
import struct
import sys

LON0, LAT0 = 7.42, 43.73          # Monaco-ish, so the default local frame is sane
M = 1.0 / 111_320.0               # ~1 metre in degrees of latitude


def ll(x, y):
    """Metres east/north of the reference point -> [lon, lat]."""
    return [LON0 + x * M / math.cos(math.radians(LAT0)), LAT0 + y * M]


def ring(points, close=True):
    pts = [ll(x, y) for x, y in points]
    if close:
        pts.append(pts[0])
    return pts


def square(cx, cy, r):
    return [(cx - r, cy - r), (cx + r, cy - r), (cx + r, cy + r), (cx - r, cy + r)]


def square_cw(cx, cy, r):
    return list(reversed(square(cx, cy, r)))


def feature(geom, fid, props=None):
    return {"type": "Feature", "id": fid, "properties": props or {"name": f"f{fid}"}, "geometry": geom}


def write_geojson(path, features, crs=None):
    fc = {"type": "FeatureCollection", "features": features}
    if crs:
        fc["crs"] = {"type": "name", "properties": {"name": crs}}
    with open(path, "w", encoding="utf-8") as f:
        json.dump(fc, f, allow_nan=False)


def poly(*rings):
    return {"type": "Polygon", "coordinates": list(rings)}


def line(points):
    return {"type": "LineString", "coordinates": [ll(x, y) for x, y in points]}


# ----------------------------------------------------------- shapefile writer
def write_shapefile(base, shape_type, records, prj=True, attrs=None):
    """Minimal ESRI shapefile writer. records: list of parts lists, each part a
    list of (x, y) in lon/lat. shape_type 3 = PolyLine, 5 = Polygon."""
    contents = []
    for parts in records:
        pts = [p for part in parts for p in part]
        xs = [p[0] for p in pts] or [0.0]
        ys = [p[1] for p in pts] or [0.0]
        finite = lambda v: [a for a in v if math.isfinite(a)] or [0.0]
        bbox = (min(finite(xs)), min(finite(ys)), max(finite(xs)), max(finite(ys)))
        body = struct.pack("<i4dii", shape_type, *bbox, len(parts), len(pts))
        idx = 0
        for part in parts:
            body += struct.pack("<i", idx)
            idx += len(part)
        for x, y in pts:
            body += struct.pack("<2d", x, y)
        contents.append(body)
    all_pts = [p for parts in records for part in parts for p in part if all(map(math.isfinite, p))]
    bx = (min(p[0] for p in all_pts), min(p[1] for p in all_pts), max(p[0] for p in all_pts),
          max(p[1] for p in all_pts)) if all_pts else (0, 0, 0, 0)

    def header(file_len_words):
        return (struct.pack(">7i", 9994, 0, 0, 0, 0, 0, file_len_words) +
                struct.pack("<2i", 1000, shape_type) + struct.pack("<4d", *bx) + struct.pack("<4d", 0, 0, 0, 0))

    shp, shx = b"", b""
    offset = 50
    for i, body in enumerate(contents):
        rec = struct.pack(">2i", i + 1, len(body) // 2) + body
        shx += struct.pack(">2i", offset, len(body) // 2)
        offset += len(rec) // 2
        shp += rec
    with open(base + ".shp", "wb") as f:
        f.write(header(50 + len(shp) // 2) + shp)
    with open(base + ".shx", "wb") as f:
        f.write(header(50 + len(shx) // 2) + shx)
    # dBASE III with one character field NAME(20)
    attrs = attrs or [f"f{i}".encode() for i in range(len(records))]
    n = len(records)
    dbf = struct.pack("<B3BIHH20x", 3, 124, 1, 1, n, 32 + 32 + 1, 1 + 20)
    dbf += b"NAME".ljust(11, b"\0") + b"C" + b"\0" * 4 + bytes([20, 0]) + b"\0" * 14
    dbf += b"\r"
    for a in attrs:
        dbf += b" " + a[:20].ljust(20, b" ")
    dbf += b"\x1a"
    with open(base + ".dbf", "wb") as f:
        f.write(dbf)
    if prj:
        with open(base + ".prj", "w") as f:
            f.write('GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],'
                    'PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]')


def main():
    out = sys.argv[1]
    big = "--big" in sys.argv
    os.makedirs(out, exist_ok=True)
    cases = []

    def case(name, filename, kind, features=None, extra_args=None, crs=None, big_case=False):
        path = os.path.join(out, filename)
        if features is not None:
            write_geojson(path, features, crs)
        cases.append({"name": name, "path": path, "kind": kind, "args": extra_args or [], "big": big_case})

    # ---------------------------------------------------------------- polygons
    case("poly_bowtie", "poly_bowtie.geojson", "polygon",
         [feature(poly(ring([(0, 0), (10, 10), (10, 0), (0, 10)])), 1)])
    case("poly_spike", "poly_spike.geojson", "polygon",
         [feature(poly(ring([(0, 0), (10, 0), (10, 5), (30, 5), (10, 5.000001), (10, 10), (0, 10)])), 1)])
    case("poly_duplicate_points", "poly_duplicate_points.geojson", "polygon",
         [feature(poly(ring([(0, 0), (0, 0), (10, 0), (10, 0), (10, 10), (0, 10), (0, 10)])), 1)])
    case("poly_unclosed_ring", "poly_unclosed_ring.geojson", "polygon",
         [feature(poly(ring([(0, 0), (10, 0), (10, 10), (0, 10)], close=False)), 1)])
    # Its only feature is dropped: nothing is kept, which is exit 9 without
    # --allow-empty (tests/safety/empty_test.py); here the drop is the point.
    case("poly_two_distinct_points", "poly_two_distinct_points.geojson", "polygon",
         [feature(poly(ring([(0, 0), (10, 0), (0, 0), (10, 0)])), 1)], ["--allow-empty"])
    case("poly_hole_touches_shell_point", "poly_hole_touches_shell_point.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5)), ring([(0, 5), (3, 3), (3, 7)][::-1])), 1)])
    case("poly_hole_touches_shell_edge", "poly_hole_touches_shell_edge.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5)), ring([(0, 3), (3, 3), (3, 7), (0, 7)][::-1])), 1)])
    case("poly_hole_outside_shell", "poly_hole_outside_shell.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5)), ring(square_cw(30, 30, 2))), 1)])
    case("poly_hole_crosses_shell", "poly_hole_crosses_shell.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5)), ring(square_cw(10, 5, 2))), 1)])
    case("poly_overlapping_holes", "poly_overlapping_holes.geojson", "polygon",
         [feature(poly(ring(square(10, 10, 10)), ring(square_cw(8, 10, 3)), ring(square_cw(12, 10, 3))), 1)])
    case("poly_three_level_nesting", "poly_three_level_nesting.geojson", "polygon",
         [feature({"type": "MultiPolygon", "coordinates": [
             [ring(square(10, 10, 10)), ring(square_cw(10, 10, 6))],
             [ring(square(10, 10, 3)), ring(square_cw(10, 10, 1))]]}, 1)])
    case("poly_identical_duplicates", "poly_identical_duplicates.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5))), 1), feature(poly(ring(square(5, 5, 5))), 2)])
    case("poly_zero_area_sliver", "poly_zero_area_sliver.geojson", "polygon",
         [feature(poly(ring([(0, 0), (10, 0), (20, 0)])), 1), feature(poly(ring(square(5, 5, 5))), 2)])
    if big:
        n = 1_000_000
        pts = [(5000 * math.cos(2 * math.pi * i / n) * (1 + 0.01 * math.sin(97 * 2 * math.pi * i / n)),
                5000 * math.sin(2 * math.pi * i / n) * (1 + 0.01 * math.sin(97 * 2 * math.pi * i / n)))
               for i in range(n)]
        case("poly_million_vertices", "poly_million_vertices.geojson", "polygon",
             [feature(poly(ring(pts)), 1)], big_case=True)
        # 316 columns x 317 rows of 20 m holes, 11.4 m apart, clear of the
        # shell (-4960 - 10 > -5000, -4960 + 316 * 31.4 + 10 < 5000): valid.
        holes = [ring(square_cw(-4960 + 31.4 * (k % 316), -4960 + 31.4 * (k // 316), 10)) for k in range(100_000)]
        case("poly_100k_holes", "poly_100k_holes.geojson", "polygon",
             [feature(poly(ring(square(0, 0, 5000)), *holes), 1)], big_case=True)
        # The same, but the first row and column of holes reach the shell and
        # share an edge with it (invalid): repaired with --repair structure,
        # and with the default linework method (clean repairs it by parts:
        # GEOS MakeValid of the whole polygon takes minutes here).
        def touching(k):
            cx, cy = -4960 + 31.4 * (k % 316), -4960 + 31.4 * (k // 316)
            x0, y0 = (-5000 if k % 316 == 0 else cx - 10), (-5000 if k // 316 == 0 else cy - 10)
            return ring([(x0, y0), (x0, cy + 10), (cx + 10, cy + 10), (cx + 10, y0), (x0, y0)])
        case("poly_100k_holes_touching_shell", "poly_100k_holes_touching_shell.geojson", "polygon",
             [feature(poly(ring(square(0, 0, 5000)), *[touching(k) for k in range(100_000)]), 1)],
             ["--repair", "structure"], big_case=True)
        case("poly_100k_holes_touching_shell_linework", "poly_100k_holes_touching_shell.geojson",
             "polygon", None, big_case=True)
        teeth = [(0, 0)]
        for t in range(10_000):
            teeth += [(t * 2 + 0.5, 0), (t * 2 + 0.5, 100), (t * 2 + 1.5, 100), (t * 2 + 1.5, 0)]
        teeth += [(20_000, 0), (20_000, -10), (0, -10)]
        case("poly_comb_10k_teeth", "poly_comb_10k_teeth.geojson", "polygon",
             [feature(poly(ring(teeth)), 1)], big_case=True)

    # ------------------------------------------------------------------- lines
    args_w = ["--width", "2"]
    case("line_zero_length_segment", "line_zero_length_segment.geojson", "line",
         [feature(line([(0, 0), (5, 0), (5, 0), (10, 0)]), 1)], args_w)
    case("line_single_point", "line_single_point.geojson", "line",
         [feature(line([(0, 0)]), 1), feature(line([(0, 0), (10, 0)]), 2)], args_w)
    case("line_180_reversal", "line_180_reversal.geojson", "line",
         [feature(line([(0, 0), (10, 0), (0, 0)]), 1)], args_w + ["--corner", "miter"])
    turn = lambda deg: [(0, 0), (10, 0), (10 + 10 * math.cos(math.radians(180 - deg)), 10 * math.sin(math.radians(180 - deg)))]
    case("line_179_9_turn", "line_179_9_turn.geojson", "line", [feature(line(turn(179.9)), 1)], args_w + ["--corner", "miter"])
    case("line_0_01_turn", "line_0_01_turn.geojson", "line", [feature(line(turn(0.01)), 1)], args_w + ["--corner", "miter"])
    case("line_collinear_100k", "line_collinear_100k.geojson", "line",
         [feature(line([(i * 0.01, 1e-9 * (i % 3)) for i in range(100_000)]), 1)], args_w + ["--corner", "bevel"])
    case("line_longer_than_grid", "line_longer_than_grid.geojson", "line",
         [feature(line([(-50_000, 0), (50_000, 1)]), 1)] + [feature(line([(i, 0), (i, 1)]), 2 + i) for i in range(200)], args_w)
    case("line_self_overlapping", "line_self_overlapping.geojson", "line",
         [feature(line([(0, 0), (10, 0), (10, 10), (5, 0), (20, 0)]), 1)], args_w + ["--corner", "miter"])
    case("line_wider_than_extent", "line_wider_than_extent.geojson", "line",
         [feature(line([(0, 0), (10, 0)]), 1)], ["--width", "1000"])

    # ------------------------------------------------------------- coordinates
    write_shapefile(os.path.join(out, "coord_nan"), 5,
                    [[ring(square(5, 5, 5))], [[(LON0, LAT0), (float("nan"), LAT0), (LON0, LAT0 + 1e-4), (LON0, LAT0)]]])
    case("coord_nan", "coord_nan.shp", "polygon")
    write_shapefile(os.path.join(out, "coord_inf"), 3,
                    [[[ll(0, 0), ll(10, 0)]], [[(LON0, LAT0), (float("inf"), LAT0)]]])
    case("coord_inf", "coord_inf.shp", "line", extra_args=args_w)
    # The same files with --skip-failures: the failing feature is dropped and
    # recorded, the rest builds, exit code 4 (partial).
    cases.append({"name": "coord_nan_skip_failures", "path": os.path.join(out, "coord_nan.shp"), "kind": "polygon",
                  "args": ["--skip-failures"], "big": False})
    cases.append({"name": "coord_inf_skip_failures", "path": os.path.join(out, "coord_inf.shp"), "kind": "line",
                  "args": args_w + ["--skip-failures"], "big": False})
    case("coord_1e300", "coord_1e300.geojson", "line",
         [feature({"type": "LineString", "coordinates": [[LON0, LAT0], [1e300, LAT0]]}, 1),
          feature(line([(0, 0), (10, 0)]), 2)], args_w)
    # The same magnitude in a projected source whose CRS is the frame (no
    # transformation to fail): clean must refuse it before GEOS, whose
    # simplifier's quad-tree loops forever on envelopes near DBL_MAX.
    case("coord_1e307_in_frame_crs", "coord_1e307_in_frame_crs.geojson", "line",
         [feature({"type": "LineString", "coordinates": [[500000.0, 4800000.0], [1e307, 4800000.0]]}, 1),
          feature({"type": "LineString", "coordinates": [[500000.0, 4800000.0], [500010.0, 4800000.0]]}, 2)],
         args_w + ["--crs", "EPSG:32632", "--resolution", "0.5"], crs="urn:ogc:def:crs:EPSG::32632")
    utm = {"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::32632"}},
           "features": [feature({"type": "LineString", "coordinates": [[500000.0, 9999000.0], [500000.001, 9999000.001],
                                                                         [500010.0, 9999000.002]]}, 1),
                        feature({"type": "Polygon", "coordinates": [[[500000.0, 9999900.0], [500000.003, 9999900.0],
                                                                      [500000.003, 9999900.003], [500000.0, 9999900.003],
                                                                      [500000.0, 9999900.0]]]}, 2)]}
    with open(os.path.join(out, "coord_utm_north_1mm.geojson"), "w") as f:
        json.dump(utm, f)
    case("coord_utm_north_1mm", "coord_utm_north_1mm.geojson", "line", extra_args=["--width", "0.001"])
    case("coord_antimeridian", "coord_antimeridian.geojson", "line",
         [feature({"type": "LineString", "coordinates": [[179.9, 10.0], [-179.9, 10.1]]}, 1)], args_w)
    # The same line in a CRS that holds it (PDC Mercator, centred on 150 E).
    case("coord_antimeridian_crs", "coord_antimeridian_crs.geojson", "line",
         [feature({"type": "LineString", "coordinates": [[179.9, 10.0], [-179.9, 10.1]]}, 1)],
         args_w + ["--crs", "EPSG:3832"])
    # Around the north pole only: the local TM frame holds it.
    case("coord_north_pole", "coord_north_pole.geojson", "polygon",
         [feature({"type": "Polygon", "coordinates": [[[0, 89.99], [120, 89.99], [-120, 89.99], [0, 89.99]]]}, 1)])
    case("coord_poles", "coord_poles.geojson", "polygon",
         [feature({"type": "Polygon", "coordinates": [[[0, 89.9], [120, 89.9], [-120, 89.9], [0, 89.9]]]}, 1),
          feature({"type": "Polygon", "coordinates": [[[-180, -90], [180, -90], [180, -89.9], [-180, -89.9], [-180, -90]]]}, 2)])
    case("coord_empty_geometries", "coord_empty_geometries.geojson", "polygon",
         [feature({"type": "Polygon", "coordinates": []}, 1), feature(None, 2), feature(poly(ring(square(5, 5, 5))), 3)])
    case("coord_geometry_collection", "coord_geometry_collection.geojson", "polygon",
         [feature({"type": "GeometryCollection", "geometries": [poly(ring(square(5, 5, 5))), line([(0, 0), (20, 20)]),
                                                                 {"type": "Point", "coordinates": ll(1, 1)}]}, 1)])
    case("coord_3d_measured", "coord_3d_measured.geojson", "line",
         [feature({"type": "LineString", "coordinates": [ll(0, 0) + [100.0], ll(10, 0) + [120.0]]}, 1)], args_w)
    case("coord_mixed_types", "coord_mixed_types.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5))), 1), feature(line([(0, 0), (20, 0)]), 2),
          feature({"type": "Point", "coordinates": ll(3, 3)}, 3)])

    # ------------------------------------------- per-feature failures (--skip-failures)
    # Each failure category once without the flag (the first failing feature
    # stops the build, exit 3, the message names it) and once with it (the
    # feature is dropped with "failed in <stage>", exit 4 partial).
    def with_skip(name):
        c = dict(cases[-1])
        c["name"] = name
        c["args"] = c["args"] + ["--skip-failures"]
        cases.append(c)

    # read: OGR cannot decode record 1 of a shapefile (nParts > nPoints).
    base = os.path.join(out, "fail_read_corrupt_record")
    write_shapefile(base, 5, [[ring(square(5, 5, 5))], [ring(square(20, 5, 5))], [ring(square(40, 5, 5))]])
    with open(base + ".shx", "rb") as f:
        rec1 = struct.unpack(">i", f.read()[108:112])[0] * 2
    with open(base + ".shp", "r+b") as f:
        f.seek(rec1 + 8 + 36)   # record header, shape type, bbox -> nParts
        f.write(struct.pack("<i", 7))
    case("fail_read_corrupt_record", "fail_read_corrupt_record.shp", "polygon")
    with_skip("fail_read_corrupt_record_skip_failures")
    # project: a vertex out of the frame projection's domain (the antipode of
    # an orthographic frame centred on the data).
    ortho = "+proj=ortho +lat_0=43.73 +lon_0=7.42 +datum=WGS84 +units=m +no_defs +type=crs"
    case("fail_project_out_of_domain", "fail_project_out_of_domain.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5))), 1),
          feature(poly([ll(20, 0), ll(30, 0), [LON0 - 180, -LAT0], ll(20, 0)]), 2),
          feature(poly(ring(square(50, 5, 5))), 3)], ["--crs", ortho])
    with_skip("fail_project_out_of_domain_skip_failures")
    # clean: a GEOS error. GEOS 3.11 fails on no known geometry, so that case
    # runs in process with an injected failure (test_clean_failure.cpp).
    # build: vertices 3000 km east and west of the data centre, beyond the
    # int32 millimetre positions of the package (EPSG:3857 in and out, so the
    # projection itself is the identity).
    mx, my = 826_000.0, 5_423_000.0
    sq_m = lambda cx, cy, r: [[cx - r, cy - r], [cx + r, cy - r], [cx + r, cy + r], [cx - r, cy + r], [cx - r, cy - r]]
    case("fail_build_out_of_range", "fail_build_out_of_range.geojson", "polygon",
         [feature(poly(sq_m(mx, my, 5)), 1), feature(poly(sq_m(mx + 3e6, my, 5)), 2),
          feature(poly(sq_m(mx - 3e6, my, 5)), 3)], ["--crs", "EPSG:3857"], crs="urn:ogc:def:crs:EPSG::3857")
    with_skip("fail_build_out_of_range_skip_failures")

    # ------------------------------------------------------------------- files
    sq = [[ring(square(5, 5, 5))]]
    for variant in ("missing_shx", "missing_dbf", "truncated_shp", "bad_prj", "non_utf8"):
        base = os.path.join(out, f"file_{variant}")
        attrs = [b"caf\xe9 \xff\xfe"] if variant == "non_utf8" else None
        write_shapefile(base, 5, sq, attrs=attrs)
        if variant == "missing_shx":
            os.remove(base + ".shx")
        elif variant == "missing_dbf":
            os.remove(base + ".dbf")
        elif variant == "truncated_shp":
            data = open(base + ".shp", "rb").read()
            open(base + ".shp", "wb").write(data[:len(data) - 40])
        elif variant == "bad_prj":
            open(base + ".prj", "w").write("GEOGCS[this is not a CRS")
        case(f"file_{variant}", f"file_{variant}.shp", "polygon")
    case("file_zero_features", "file_zero_features.geojson", "polygon", [])
    # The same empty layer beside a layer with data: the package is built,
    # with the empty layer in it and a manifest note.
    case("file_zero_features_beside_data", "zero_beside_data.geojson", "polygon",
         [feature(poly(ring(square(5, 5, 5))), 1)])
    with open(os.path.join(out, "file_zero_features_beside_data.toml"), "w", encoding="utf-8") as f:
        f.write(f'[[layer]]\nname = "empty"\nsource = "{os.path.join(out, "file_zero_features.geojson")}"\n'
                f'kind = "polygon"\n\n[[layer]]\nname = "data"\nsource = "{os.path.join(out, "zero_beside_data.geojson")}"\n'
                f'kind = "polygon"\n')
    cases[-1]["path"] = os.path.join(out, "file_zero_features_beside_data.toml")
    odd = "path with spaces ü é"
    os.makedirs(os.path.join(out, odd), exist_ok=True)
    case("file_odd_path", os.path.join(odd, "données.geojson"), "polygon", [feature(poly(ring(square(5, 5, 5))), 1)])

    with open(os.path.join(out, "cases.json"), "w", encoding="utf-8") as f:
        json.dump(cases, f, indent=1, ensure_ascii=False)
    print(f"hostile: wrote {len(cases)} cases to {out}")


if __name__ == "__main__":
    main()
