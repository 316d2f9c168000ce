#!/usr/bin/env python3
"""A tileset streamed by the browser viewer (tests/web/CMakeLists.txt,
Web.TilesetStreaming): `decalprep view --screenshot` of a generated tileset
of more than 10^6 vertices with overview levels, counted at the server.

The tileset: bench/gen_synthetic.py "fine" (smooth polygons with a vertex
every 0.2 m and smooth 3 m lines, 10^6 vertices over 8 km), built with
1 km tiles and `--levels auto`. Every view is 640x360 over flat ground.
What the server sent comes from `view --stats` ("data:" and "data files:",
counted by the server as it answers /data/ requests, not by the page).

  whole extent, top-down and oblique (--fit --pitch 45):
    - the server sent less than 5% of the full-detail bytes (the level-0
      tiles' files, tileset.json's sizes), tileset.json included;
    - each file was sent once (one Range request a tile);
    - the frame differs from `render --level 0` (GL, --aa none: every
      level-0 tile) on less than 1% of its pixels (a pixel differs when a
      channel is more than 2/255 away);
    - it equals `render` of the same view (GL, the levels render chooses)
      on at least 99.9% of its pixels: the browser drew what render draws;
  close-up (an oblique view of a few hundred metres):
    - the tile files the server sent are exactly the tiles
      prep::render::select_tiles chooses for that camera (view_oracle
      tiles), fewer than the tileset holds, and no tile outside the view;
    - the frame equals `render` of the view on at least 99.9% of pixels;
  the same close-up with `view --gpu-budget` at 60% of its decoded blob
    bytes: the tiles sent whole are exactly those select_tiles chooses
    under that budget (coarsened: fewer bytes), the others only read for
    their header; the frame equals `render --gpu-budget` of the view;
  whole extent top-down with --backend webgl2: the same counts and
    agreement with render (the WebGL2 renderer draws tilesets too);
  stand-ins (`view --stand-in-level L`: only level L's tiles fetched, as
    the viewer shows a view before its own tiles arrive): the close-up from
    level 2 (coarser tiles drawn in the squares of the finer ones they stand
    in for) and the whole extent from level 3 (finer tiles filling a coarser
    one's square) equal `render --level L` of the view on at least 99.9% of
    pixels, and the server sent level L's tiles alone: no hole;
  the Monaco sample as 500 m tiles with --levels auto, with its dynamic
    roads (pixel-width lines), oblique over the whole and close up: the
    frame equals render's on at least 99.9% of pixels, and on 99% of the
    pixels the dynamic lines change (render against render --only
    polygons,lines): each tile's dynamic lines drawn in its square;
  a continent: discs over 5,200 km in EPSG:3857 as 200 km tiles over a DEM
    of 40 km hills (tileset.terrain), top-down and oblique, so that tiles lie
    beyond 2^31 quanta (2,147 km) of the eye and draw around an anchor of
    their own: the frame equals render's on at least 99.9% of pixels, with
    each backend.

Prints the figures of each view. Exit 0 when all hold, 1 when one fails,
77 (skip) when Chromium, numpy or GDAL's Python bindings are missing.

Usage: tileset_stream_test.py DECALPREP VIEW_ORACLE REPO_ROOT WORK_DIR
"""
import json
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pixel_agreement import SKIP, chromium, screenshot_skip  # noqa: E402
SIZE = (640, 360)
VERTICES = 1_000_000
EXTENT_M = 8000.0
TILE_M = 1000


def main():
    if len(sys.argv) != 5:
        print(__doc__)
        return 2
    decalprep, oracle, root, work = sys.argv[1:5]
    try:
        import numpy  # noqa: F401
        from osgeo import gdal  # noqa: F401
    except ImportError as e:
        print("SKIP: numpy or GDAL's Python bindings are missing:", e)
        return SKIP
    if not chromium():
        print("SKIP: no Chromium (scripts/deps installs it)")
        return SKIP
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    sys.path.insert(0, os.path.join(root, "bench"))
    import gen_synthetic
    scene, _ = gen_synthetic.mix_scene(work, VERTICES, "fine", extent=EXTENT_M, kind="fine")
    tiles_dir = os.path.join(work, "tiles")
    subprocess.run([decalprep, "build", scene, "-o", tiles_dir, "--tile-size", str(TILE_M),
                    "--levels", "auto", "-q"], check=True)
    with open(os.path.join(tiles_dir, "tileset.json")) as f:
        index = json.load(f)
    vertices = sum(layer["vertices_in"] for layer in index["manifest"]["layers"])
    level0 = {t["file"]: t for t in index["tiles"]}
    files = dict(level0)
    for lv in index["levels"]:
        files.update({t["file"]: t for t in lv["tiles"]})
    full = sum(t["bytes"] for t in level0.values())
    print(f"tileset: {vertices} vertices, {len(level0)} level-0 tiles ({full} bytes), "
          f"levels 1..{len(index['levels'])}, {len(files)} tile files")
    if vertices < VERTICES:
        print(f"FAIL: the generated tileset has {vertices} vertices, fewer than {VERTICES}")
        return 1
    if not index["levels"]:
        print("FAIL: --levels auto made no overview level")
        return 1

    ext = index["extent"]
    cx, cy = (ext[0] + ext[2]) / 2, (ext[1] + ext[3]) / 2
    half_w = max(ext[2] - ext[0], (ext[3] - ext[1]) * SIZE[0] / SIZE[1]) / 2
    top = ["--extent", "%.3f,%.3f,%.3f,%.3f" % (cx - half_w, cy - half_w * SIZE[1] / SIZE[0],
                                                 cx + half_w, cy + half_w * SIZE[1] / SIZE[0])]
    ox, oy = index["frame"]["origin"]
    # The close-up: 250 m up, looking north-east at a point 400 m away.
    tx, ty = cx - ox, cy - oy
    eye, target = [tx - 280.0, ty - 280.0, 250.0], [tx, ty, 0.0]
    close = ["--eye", "%.3f,%.3f,%.3f" % tuple(eye), "--target", "%.3f,%.3f,%.3f" % tuple(target)]
    views = [("whole, top-down", top, "webgpu", True), ("whole, oblique", ["--fit", "--pitch", "45"], "webgpu", True),
             ("close-up", close, "webgpu", False), ("whole, top-down, WebGL2", top, "webgl2", True)]
    failures = []
    for name, camera, backend, whole in views:
        failures += check_view(decalprep, oracle, work, tiles_dir, name, camera, backend, whole, files, full,
                               (eye, target))
    for name, camera, level in (("close-up from level 2", close, 2), ("whole, top-down, from level 3", top, 3)):
        failures += check_stand_in(decalprep, work, tiles_dir, name, camera, level, files)
    budget = int(0.6 * oracle_tiles(oracle, work, tiles_dir, eye, target, 0)["blob_bytes"])
    failures += check_view(decalprep, oracle, work, tiles_dir, "close-up, GPU budget", close, "webgpu", False, files,
                           full, (eye, target), budget)
    failures += check_dynamic(decalprep, root, work)
    failures += check_continent(decalprep, work)
    for f in failures:
        print("FAIL:", f)
    return 1 if failures else 0


def check_stand_in(decalprep, work, tiles_dir, name, camera, level, files):
    """A view drawn from level `level`'s tiles alone, against render --level."""
    slug = re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")
    size = ["--size", "%dx%d" % SIZE]
    shot, gl = os.path.join(work, slug + ".view.png"), os.path.join(work, slug + ".render.png")
    r = subprocess.run([decalprep, "view", tiles_dir, "--screenshot", shot, *size, *camera, "--stats",
                        "--stand-in-level", str(level), "--timeout", "600"], capture_output=True, text=True)
    if r.returncode != 0:
        return [f"{name}: view exited {r.returncode}: {r.stderr[-2000:]}"]
    listed = re.search(r"^data files \(FILE:BYTES sent\): (.*)$", r.stdout, re.M)
    chosen = re.search(r"^tiles: \d+ chosen \((.*?)\)", r.stdout, re.M)
    if not (listed and chosen):
        return [f"{name}: view --stats printed no data files or tiles:\n{r.stdout}"]
    sent = [item.rsplit(":", 1)[0] for item in listed.group(1).split()]
    tiles = [f for f in sent if f in files]
    subprocess.run([decalprep, "render", tiles_dir, "-o", gl, *size, *camera, "--aa", "none", "--flat",
                    "--level", str(level)], check=True, capture_output=True)
    agree, total = agreement(shot, gl)
    print(f"{name}: the view chose {chosen.group(1)}; the server sent {len(tiles)} tiles of levels "
          f"{sorted(levels_of(tiles))}; {agree} of {total} pixels within 2/255 of render --level {level}")
    fails = []
    if not tiles or set(levels_of(tiles)) != {level}:
        fails.append(f"{name}: the server sent tiles {tiles}, not level {level}'s alone")
    if f"L{level}:" in chosen.group(1).replace(" ", ""):
        fails.append(f"{name}: the view chose level {level} itself ({chosen.group(1)}): nothing stood in")
    if agree < 0.999 * total:
        fails.append(f"{name}: only {agree} of {total} pixels agree with render --level {level}")
    return fails


def oracle_tiles(oracle, work, tiles_dir, eye, target, budget):
    """view_oracle tiles: prep::render::select_tiles of the camera, flat ground."""
    views_path = os.path.join(work, "oracle_views.json")
    with open(views_path, "w") as f:
        json.dump([{"name": "view", "eye": eye, "target": target, "fov": 45}], f)
    o = subprocess.run([oracle, "tiles", tiles_dir, views_path, str(SIZE[0]), str(SIZE[1]), str(budget)],
                       capture_output=True, text=True, check=True)
    return json.loads(o.stdout)[0]


def check_view(decalprep, oracle, work, tiles_dir, name, camera, backend, whole, files, full, close, budget=0):
    slug = re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")
    size = ["--size", "%dx%d" % SIZE]
    shot = os.path.join(work, slug + ".view.png")
    limit = ["--gpu-budget", str(budget)] if budget else []
    r = subprocess.run([decalprep, "view", tiles_dir, "--screenshot", shot, *size, *camera, "--stats",
                        "--backend", backend, "--timeout", "600", *limit], capture_output=True, text=True)
    skip = screenshot_skip(r)
    if skip:
        print("SKIP:", skip)
        sys.exit(SKIP)
    if r.returncode != 0:
        return [f"{name}: view exited {r.returncode}: {r.stderr[-2000:]}"]
    out = r.stdout
    m = re.search(r"^data: (\d+) requests, (\d+) bytes", out, re.M)
    listed = re.search(r"^data files \(FILE:BYTES sent\): (.*)$", out, re.M)
    device = re.search(r"^device: (\S+)", out, re.M)
    if not (m and listed and device):
        return [f"{name}: view --stats printed no data counts or device:\n{out}"]
    requests, sent = int(m.group(1)), int(m.group(2))
    sent_bytes = {f: int(b) for f, b in (item.rsplit(":", 1) for item in listed.group(1).split())}
    sent_files = list(sent_bytes)
    # Tiles sent whole (with a budget, others are read for their headers alone).
    tiles_sent = [f for f in sent_files if f in files and sent_bytes[f] >= files[f]["bytes"]]
    headers_only = [f for f in sent_files if f in files and f not in tiles_sent]
    fails = []
    if device.group(1).lower() != backend:
        fails.append(f"{name}: the page drew with {device.group(1)}, not {backend}")
    others = [f for f in sent_files if f not in files and f != "tileset.json"]
    if others:
        fails.append(f"{name}: the server sent files that are neither tiles nor the index: {others}")
    if not budget and requests != len(sent_files):
        fails.append(f"{name}: {requests} requests for {len(sent_files)} files (one request a file expected)")
    if not budget and headers_only:
        fails.append(f"{name}: files sent in part without a budget: {headers_only}")
    tile_bytes = sum(files[f]["bytes"] for f in tiles_sent)
    print(f"{name} ({backend}): the server answered {requests} requests, {sent} bytes "
          f"({100.0 * sent / full:.2f}% of the full detail's {full}); {len(tiles_sent)} tiles, {tile_bytes} "
          f"bytes; levels " + ", ".join(f"L{lv}: {n}" for lv, n in sorted(levels_of(tiles_sent).items())))

    gl = os.path.join(work, slug + ".render.png")
    subprocess.run([decalprep, "render", tiles_dir, "-o", gl, *size, *camera, "--aa", "none", "--flat", *limit],
                   check=True, capture_output=True)
    same = agreement(shot, gl)
    print(f"  against render of the view: {same[0]} of {same[1]} pixels within 2/255 ({100.0 * same[0] / same[1]:.3f}%)")
    if same[0] < 0.999 * same[1]:
        fails.append(f"{name}: only {same[0]} of {same[1]} pixels agree with render's frame of the view")
    if whole:
        if sent >= 0.05 * full:
            fails.append(f"{name}: the server sent {sent} bytes, not less than 5% of the full detail's {full}")
        l0 = os.path.join(work, slug + ".level0.png")
        subprocess.run([decalprep, "render", tiles_dir, "-o", l0, *size, *camera, "--aa", "none", "--flat",
                        "--level", "0"], check=True, capture_output=True)
        agree, total = agreement(shot, l0)
        print(f"  against render --level 0: {total - agree} of {total} pixels differ "
              f"({100.0 * (total - agree) / total:.3f}%)")
        if total - agree >= 0.01 * total:
            fails.append(f"{name}: {total - agree} of {total} pixels differ from render --level 0 (1% allowed)")
    else:
        eye, target = close
        o = oracle_tiles(oracle, work, tiles_dir, eye, target, budget)
        want = sorted(file_of(files, lv, x, y) for lv, x, y, _ in o["tiles"])
        print(f"  select_tiles chooses {len(want)} tiles of {len(files)}" +
              (f" under a budget of {budget} bytes ({o['coarsened']} coarsened, {o['blob_bytes']} used)"
               if budget else "") + f"; the server sent {len(tiles_sent)} whole, {len(headers_only)} headers")
        if budget and not o["coarsened"]:
            fails.append(f"{name}: a budget of {budget} bytes coarsens nothing: it proves nothing")
        if sorted(tiles_sent) != want:
            fails.append(f"{name}: the server sent tiles {sorted(tiles_sent)}, the view's tiles are {want}")
        if not 0 < len(want) < len(files) // 4:
            fails.append(f"{name}: a close-up of {len(want)} of {len(files)} tiles proves nothing")
    return fails


def check_dynamic(decalprep, root, work):
    """The Monaco sample as a tileset, its dynamic roads drawn per tile."""
    import numpy as np
    from osgeo import gdal
    out = os.path.join(work, "monaco")
    subprocess.run([decalprep, "build", os.path.join(root, "samples/monaco/scene.toml"), "-o", out,
                    "--tile-size", "500", "--levels", "auto", "-q"], check=True)
    size = ["--size", "%dx%d" % SIZE]
    fails = []
    for name, camera in (("whole", ["--fit", "--pitch", "45"]),
                         ("along the A8", ["--eye", "400,1500,300", "--target", "-700,1150,0"])):
        shot, gl, static = (os.path.join(work, f"monaco_{name}.{k}.png") for k in ("view", "render", "static"))
        r = subprocess.run([decalprep, "view", out, "--screenshot", shot, *size, *camera, "--timeout", "600"],
                           capture_output=True, text=True)
        if r.returncode != 0:
            fails.append(f"Monaco tileset, {name}: view exited {r.returncode}: {r.stderr[-2000:]}")
            continue
        for png, extra in ((gl, []), (static, ["--only", "polygons,lines"])):
            subprocess.run([decalprep, "render", out, "-o", png, *size, *camera, "--aa", "none", "--flat", *extra],
                           check=True, capture_output=True)
        a, b, c = (gdal.Open(p).ReadAsArray().astype(np.int16) for p in (shot, gl, static))
        same = (np.abs(a - b) <= 2).all(axis=0)
        dynamic = (np.abs(b - c) > 2).any(axis=0)
        print(f"Monaco tileset with dynamic roads, {name}: {int(same.sum())} of {same.size} pixels within 2/255 of "
              f"render's; of the {int(dynamic.sum())} pixels its dynamic lines change, {int((same & dynamic).sum())}")
        if same.sum() < 0.999 * same.size:
            fails.append(f"Monaco tileset, {name}: only {int(same.sum())} of {same.size} pixels agree with render's")
        if dynamic.sum() < 100 or (same & dynamic).sum() < 0.99 * dynamic.sum():
            fails.append(f"Monaco tileset, {name}: {int((same & dynamic).sum())} of the {int(dynamic.sum())} "
                         "dynamic-line pixels agree with render's (99% wanted, of at least 100)")
    return fails


def check_continent(decalprep, work):
    """Discs of 1.5 degrees every 11 degrees of longitude and 10 of
    latitude (about 5,200 km across in EPSG:3857) over a DEM of 40 km hills,
    built as 200 km tiles with `decalprep terrain`'s tileset.terrain; a
    top-down view inside the data's extent and an oblique one against
    render (over the build DEM: the same mesh), with each backend."""
    import math
    import numpy as np
    from osgeo import gdal, osr
    nx, ny = 600, 400  # 0.1 degree cells over lon -30..30, lat 20..60
    lon, lat = np.meshgrid(-30 + 0.1 * (np.arange(nx) + 0.5), 60 - 0.1 * (np.arange(ny) + 0.5))
    dem = os.path.join(work, "continent_dem.tif")
    ds = gdal.GetDriverByName("GTiff").Create(dem, nx, ny, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((-30, 0.1, 0, 60, 0, -0.1))
    wgs84 = osr.SpatialReference()
    wgs84.ImportFromEPSG(4326)
    ds.SetProjection(wgs84.ExportToWkt())
    ds.GetRasterBand(1).WriteArray((20000 * (1 + np.sin(lon / 3.0) * np.cos(lat / 2.0))).astype(np.float32))
    ds = None
    features = []
    for i in range(5):
        for j in range(3):
            cx, cy = -22.0 + 11.0 * i, 30.0 + 10.0 * j
            ring = [[cx + 1.5 * math.cos(2 * math.pi * k / 256), cy + 1.5 * math.sin(2 * math.pi * k / 256)]
                    for k in range(256)]
            ring.append(ring[0])
            features.append({"type": "Feature", "properties": {"id": len(features)},
                             "geometry": {"type": "Polygon", "coordinates": [ring]}})
    src = os.path.join(work, "continent.geojson")
    with open(src, "w") as f:
        json.dump({"type": "FeatureCollection", "features": features}, f)
    scene = os.path.join(work, "continent.toml")
    with open(scene, "w") as f:
        f.write(f'source = "{src}"\ncrs = "EPSG:3857"\ndem = "{dem}"\n[[layer]]\nname = "discs"\n'
                'kind = "polygon"\ncolor = "#c05020"\n')
    out = os.path.join(work, "continent")
    subprocess.run([decalprep, "build", scene, "-o", out, "--tile-size", "200000", "-q"], check=True)
    subprocess.run([decalprep, "terrain", out], check=True, capture_output=True)
    with open(os.path.join(out, "tileset.json")) as f:
        e = json.load(f)["extent"]
    cx, cy = (e[0] + e[2]) / 2, (e[1] + e[3]) / 2
    hw = min(e[2] - e[0], (e[3] - e[1]) * SIZE[0] / SIZE[1]) / 2  # inside the extent: render's mesh
    hh = hw * SIZE[1] / SIZE[0]
    views = [("top-down", ["--extent", "%.3f,%.3f,%.3f,%.3f" % (cx - hw, cy - hh, cx + hw, cy + hh)]),
             ("oblique", ["--fit", "--pitch", "35"])]
    fails = []
    for name, camera in views:
        gl = os.path.join(work, f"continent_{name}.render.png")
        subprocess.run([decalprep, "render", out, "-o", gl, "--size", "%dx%d" % SIZE, *camera, "--aa", "none"],
                       check=True, capture_output=True)
        for backend in ("webgpu", "webgl2"):
            shot = os.path.join(work, f"continent_{name}.{backend}.png")
            r = subprocess.run([decalprep, "view", out, "--screenshot", shot, "--size", "%dx%d" % SIZE, *camera,
                                "--backend", backend, "--timeout", "600"], capture_output=True, text=True)
            if r.returncode != 0:
                fails.append(f"continent {name} ({backend}): view exited {r.returncode}: {r.stderr[-2000:]}")
                continue
            agree, total = agreement(shot, gl)
            print(f"continent over 40 km hills, {name}, a view {2 * hw / 1000:.0f} km across ({backend}): "
                  f"{agree} of {total} pixels within 2/255 of render's ({100.0 * agree / total:.3f}%)")
            if agree < 0.999 * total:
                fails.append(f"continent {name} ({backend}): only {agree} of {total} pixels agree with render's")
    return fails


def levels_of(names):
    out = {}
    for n in names:
        m = re.match(r"tiles/L(\d+)/", n)
        lv = int(m.group(1)) if m else 0
        out[lv] = out.get(lv, 0) + 1
    return out


def file_of(files, level, x, y):
    for f, t in files.items():
        if t["x"] == x and t["y"] == y and levels_of([f]) == {level: 1}:
            return f
    raise KeyError(f"no tile L{level} {x},{y} in tileset.json")


def agreement(a_path, b_path):
    """(pixels whose channels are all within 2/255, pixels) of two PNGs."""
    import numpy as np
    from osgeo import gdal
    a = gdal.Open(a_path).ReadAsArray().astype(np.int16)
    b = gdal.Open(b_path).ReadAsArray().astype(np.int16)
    if a.shape != b.shape:
        raise SystemExit(f"FAIL: {a_path} is {a.shape}, {b_path} is {b.shape}")
    close = (np.abs(a - b) <= 2).all(axis=0)
    return int(close.sum()), int(close.size)


if __name__ == "__main__":
    sys.exit(main())
