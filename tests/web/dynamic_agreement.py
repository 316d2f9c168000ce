#!/usr/bin/env python3
"""Dynamic lines in the browser renderer against decalprep's GL renderer
(tests/web/CMakeLists.txt, Web.DynamicLinesAgreeWithGL).

The oracle is `decalprep render` (GL: libprep/render/gl_dynamic.cpp with
formats/gl/shaders/dyn_*.glsl, --aa none) and, for the crossing, the
front-to-back composite worked out here from the scene's colours and
drawing order; the browser is `decalprep view --screenshot` (WebGPU,
web/src/render/wgsl_dynamic.js, in a headless Chromium).

  Monaco over its terrain, two perspective views of its motorways (the
  dynamic layer, 4 px, min_width_m 12), 640x360. render draws the package
  with its build DEM, view a moved copy with the terrain file `decalprep
  terrain` writes (as pixel_agreement.py does). Per view:
    - the final frames, every pixel: at least 99.9% within 2/255 on every
      channel;
    - the motorway pixels, where GL's frame differs from GL's frame with
      --only polygons,lines (at least MIN_LINE_PIXELS of them) or the
      browser's from the browser's: 99% within 2/255;
    - --only dynamic (terrain and motorways alone), every pixel: 99.9%
      within 2/255.
  The same sample with its motorways dashed (dash = [16, 8] pixels: each
  kept vertex's screen distance along its line, per frame), the second
  view: the final frame and its motorway pixels as above.
  Twelve translucent lines through one pixel (the scene of
  tests/render/test_dynamic.cpp TwelveTransparentLinesThroughOnePixel...
  as a package: one layer per line, so that the drawing order, later layer
  on top, is the permutation 5k mod 12 of the line index k), top-down,
  flat: the crossing pixel within 2/255 of GL's and of the analytic
  composite (the lines front to back in drawing order over the terrain
  colour GL draws away from the lines), which compositing in index order
  misses by more than 10/255; and the whole frame 99.9% within 2/255.
  Sixty nearly transparent lines on one another (tests/render/
  test_dynamic.cpp GrowTheListBufferWhenItOverflows), 64x32: far more list
  nodes than the two per pixel the node buffer starts with, so the lists
  pass must grow it and draw again; a pixel on the lines within 2/255 of
  GL's and of all sixty composited (alpha 1 - (1 - 16/255)^60).

Prints one line per check with its counts. Exit 0 when all pass, 1 when
one fails, 77 (skip) only when Chromium is missing or
cannot start.

Usage: dynamic_agreement.py DECALPREP REPO_ROOT WORK_DIR
"""
import json
import math
import os
import shutil
import sys
import time

from pixel_agreement import SKIP, blank, read_png, run, screenshot_skip

SIZE = (640, 360)
# Eye and target, frame metres: the A8 north of Monaco from the south, and
# along it from the east.
VIEWS = [("from the south", "-600,300,900", "-600,1150,480"),
         ("along it from the east", "400,1500,750", "-700,1150,480")]
MIN_LINE_PIXELS = 2000
# The crossing scene: a UTM frame, lines through (X0 + 100.5, Y0 + 50.5),
# drawn over [X0, X0 + 200] x [Y0, Y0 + 100] at 1 m pixels.
X0, Y0 = 500000.0, 4800000.0
LINES = 12


def pixels(path):
    w, h, rows = read_png(path)
    return w, h, [[tuple(rows[y][4 * x:4 * x + 4]) for x in range(w)] for y in range(h)]


def agreement(ref, got, where=None):
    """(pixels compared, within 2/255, largest channel difference) over
    every pixel, or those (x, y) in `where`."""
    w, h, a = ref
    w2, h2, b = got
    if (w, h) != (w2, h2):
        raise ValueError(f"sizes differ: {w}x{h} and {w2}x{h2}")
    keys = where if where is not None else [(x, y) for y in range(h) for x in range(w)]
    n = ok = worst = 0
    for x, y in keys:
        d = max(abs(p - q) for p, q in zip(a[y][x], b[y][x]))
        n += 1
        ok += d <= 2
        worst = max(worst, d)
    return n, ok, worst


class Runner:
    def __init__(self, decalprep, work):
        self.decalprep, self.work, self.failed, self.checks = decalprep, work, 0, 0

    def render(self, pkg, out, opts):
        t = time.time()
        r = run([self.decalprep, "render", pkg, "-o", out, "--aa", "none"] + opts)
        if r.returncode:
            raise RuntimeError(f"render exited {r.returncode}: {r.stderr[-2000:]}")
        return time.time() - t

    def view(self, pkg, out, opts):
        """Seconds taken, or None for a skip (no Chromium)."""
        t = time.time()
        v = run([self.decalprep, "view", pkg, "--screenshot", out, "--timeout", "300"] + opts)
        skip = screenshot_skip(v)
        if skip:
            print("SKIP:", skip)
            return None
        if v.returncode:
            raise RuntimeError(f"view --screenshot exited {v.returncode}: {v.stderr[-3000:]}")
        if "left out" in v.stderr:
            raise RuntimeError(f"view says it leaves layers out: {v.stderr[-2000:]}")
        return time.time() - t

    def build_and_draw(self, scene, name, opts):
        """Builds `scene` into WORK/NAME.decals and draws it with render and
        view (`opts`); returns (GL PNG path, browser PNG path), or None for a
        skip."""
        pkg = os.path.join(self.work, name + ".decals")
        b = run([self.decalprep, "build", scene, "-o", pkg])
        if b.returncode:
            raise RuntimeError(f"building {scene}: {b.stderr[-2000:]}")
        gl_png, web_png = os.path.join(self.work, name + "_gl.png"), os.path.join(self.work, name + "_web.png")
        self.render(pkg, gl_png, opts)
        return None if self.view(pkg, web_png, opts) is None else (gl_png, web_png)

    def check(self, name, ok, detail):
        self.checks += 1
        self.failed += not ok
        print(f"{'ok  ' if ok else 'FAIL'} {name}: {detail}")

    def share(self, name, counts, need):
        n, ok, worst = counts
        s = ok / n if n else 0.0
        self.check(name, n > 0 and s >= need, f"{ok} of {n} pixels within 2/255 ({100 * s:.3f}%, need "
                   f"{100 * need:.1f}%), largest difference {worst}/255")


def monaco(r, root, dashed=False):
    """The Monaco sample (dashed: its motorways dashed, a scene written
    here with the sample's paths made absolute) in VIEWS (dashed: the
    second)."""
    stem = "dashed" if dashed else "monaco"
    scene = os.path.join(root, "samples/monaco/scene.toml")
    if dashed:
        sample = os.path.abspath(os.path.join(root, "samples/monaco"))
        with open(scene) as f:
            text = f.read()
        for old, new in (('source = "monaco.osm.pbf"', f'source = "{sample}/monaco.osm.pbf"'),
                         ('"/vsizip/N43E007', f'"/vsizip/{sample}/N43E007'),
                         ("min_width_m = 12 ", "dash = [16.0, 8.0]\nmin_width_m = 12 ")):
            if old not in text:
                raise RuntimeError(f"{scene}: no '{old}' to change for the dashed copy")
            text = text.replace(old, new)
        scene = os.path.join(r.work, "dashed.toml")
        with open(scene, "w") as f:
            f.write(text)
    pkg = os.path.join(r.work, stem + ".decals")
    b = run([r.decalprep, "build", scene, "-o", pkg])
    if b.returncode:
        raise RuntimeError(f"building {scene}: {b.stderr[-2000:]}")
    t = run([r.decalprep, "terrain", pkg])
    if t.returncode:
        raise RuntimeError(f"decalprep terrain {pkg}: {t.stderr[-2000:]}")
    moved = os.path.join(r.work, "moved_" + stem)
    os.makedirs(moved)
    for ext in (".decals", ".terrain"):
        shutil.copyfile(os.path.join(r.work, stem + ext), os.path.join(moved, stem + ext))
    view_pkg = os.path.join(moved, stem + ".decals")
    for k, (name, eye, target) in enumerate(VIEWS):
        if dashed and k != 1:
            continue
        cam = ["--eye", eye, "--target", target, "--size", f"{SIZE[0]}x{SIZE[1]}"]
        f = lambda what: os.path.join(r.work, f"{stem}{k}_{what}.png")
        gl_s = r.render(pkg, f("gl"), cam)
        r.render(pkg, f("gl_static"), cam + ["--only", "polygons,lines"])
        web_s = r.view(view_pkg, f("web"), cam)
        if web_s is None or r.view(view_pkg, f("web_static"), cam + ["--only", "polygons,lines"]) is None:
            return SKIP
        if not dashed:
            r.render(pkg, f("gl_dynamic"), cam + ["--only", "dynamic"])
            if r.view(view_pkg, f("web_dynamic"), cam + ["--only", "dynamic"]) is None:
                return SKIP
        gl, gl_static, web, web_static = (pixels(f(what)) for what in ("gl", "gl_static", "web", "web_static"))
        line = [(x, y) for y in range(SIZE[1]) for x in range(SIZE[0]) if gl[2][y][x] != gl_static[2][y][x]]
        # and where the browser draws a line that GL does not
        drawn = sorted(set(line) | {(x, y) for y in range(SIZE[1]) for x in range(SIZE[0])
                                    if web[2][y][x] != web_static[2][y][x]})
        label = f"{'monaco, motorways dashed,' if dashed else 'monaco'} {name} (--eye {eye} --target {target})"
        print(f"     {label}: render {gl_s:.1f} s, view {web_s:.1f} s")
        r.share(f"{label}, final frame", agreement(gl, web), 0.999)
        need = MIN_LINE_PIXELS // 2 if dashed else MIN_LINE_PIXELS  # the dashes' gaps
        r.check(f"{label}, motorways in view", len(line) >= need,
                f"{len(line)} pixels where GL's frame differs from its --only polygons,lines frame "
                f"(need {need})")
        r.share(f"{label}, final frame on the motorway pixels, GL's or the browser's", agreement(gl, web, drawn), 0.99)
        if not dashed:
            r.share(f"{label}, --only dynamic", agreement(pixels(f("gl_dynamic")), pixels(f("web_dynamic"))),
                    0.999)
    return 0


def crossing_scene(work):
    """The twelve lines as GeoJSON and a scene of one dynamic layer per
    line; returns (scene path, per line k: rgba, order)."""
    feats, layers, lines = [], [], []
    for k in range(LINES):
        a = k * math.pi / LINES  # 15 degrees apart
        cx, cy = X0 + 100.5, Y0 + 50.5
        coords = [[cx - 40 * math.cos(a), cy - 40 * math.sin(a)], [cx + 40 * math.cos(a), cy + 40 * math.sin(a)]]
        feats.append({"type": "Feature", "properties": {"k": k}, "geometry": {"type": "LineString", "coordinates": coords}})
        rgba = (20 * k, 255 - 20 * k, (37 * k) % 256, 0x59)
        lines.append((rgba, (5 * k) % LINES))  # 5 and 12 are coprime: a permutation
    # Later layer on top: the line of order o is in layer LINES - 1 - o.
    for layer in range(LINES):
        k = next(k for k in range(LINES) if lines[k][1] == LINES - 1 - layer)
        colour = "#" + "".join(f"{c:02x}" for c in lines[k][0])
        layers.append(f'[[layer]]\nname = "line{k}"\nwhere = "k = {k}"\nkind = "line"\ndynamic = true\n'
                      f'width = 4.0\ncorner = "round"\ncolor = "{colour}"\n')
    with open(os.path.join(work, "crossing.geojson"), "w") as f:
        json.dump({"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "EPSG:32632"}},
                   "features": feats}, f)
    scene = os.path.join(work, "crossing.toml")
    with open(scene, "w") as f:
        f.write(f'source = "crossing.geojson"\ncrs = "EPSG:32632"\n'
                f'extent = [{X0}, {Y0}, {X0 + 200}, {Y0 + 100}]\nextent_crs = ""\n\n' + "\n".join(layers))
    return scene, lines


def composite(lines, ordered, terrain):
    """The pixel over `terrain` (RGB bytes) with the lines front to back in
    `ordered` (indices), straight alpha, rounded as the PNG writers do."""
    acc = [0.0, 0.0, 0.0, 0.0]
    for k in ordered:
        c = lines[k][0]
        w = (1 - acc[3]) * c[3] / 255
        for ch in range(3):
            acc[ch] += w * c[ch] / 255
        acc[3] += w
    return tuple(int(math.floor(min(max(acc[ch] + (1 - acc[3]) * terrain[ch] / 255, 0), 1) * 255 + 0.5))
                 for ch in range(3))


def crossing(r):
    scene, lines = crossing_scene(r.work)
    drawn = r.build_and_draw(scene, "crossing", ["--extent", f"{X0!r},{Y0!r},{X0 + 200!r},{Y0 + 100!r}",
                                                 "--size", "200x100"])
    if drawn is None:
        return SKIP
    gl_png, web_png = drawn
    if blank(gl_png):
        raise RuntimeError(f"{gl_png} is blank (the lines were not drawn)")
    gl, web = pixels(gl_png), pixels(web_png)
    # Pixel (100, 49) from the top-left: centre (X0 + 100.5, Y0 + 50.5), on every line.
    x, y = 100, 49
    terrain = gl[2][2][2]  # far from every line
    right = composite(lines, sorted(range(LINES), key=lambda k: lines[k][1]), terrain)
    wrong = composite(lines, range(LINES), terrain)
    g, w_ = gl[2][y][x][:3], web[2][y][x][:3]
    d_gl = max(abs(p - q) for p, q in zip(g, w_))
    d_an = max(abs(p - q) for p, q in zip(right, w_))
    d_order = max(abs(p - q) for p, q in zip(right, wrong))
    r.check("twelve lines through one pixel: browser against GL", d_gl <= 2,
            f"pixel ({x}, {y}): browser {w_}, GL {g}, difference {d_gl}/255 (need <= 2)")
    r.check("twelve lines through one pixel: browser against the composite in drawing order", d_an <= 2,
            f"analytic {right} over terrain {terrain[:3]}, difference {d_an}/255 (need <= 2)")
    r.check("twelve lines: index order composites to another colour", d_order > 10,
            f"index order {wrong}, {d_order}/255 from drawing order (need > 10)")
    r.share("twelve lines: the whole frame", agreement(gl, web), 0.999)
    return 0


def stacked(r):
    """Sixty copies of one line in one layer, colour #ffffff10."""
    copies = 60
    line = [[X0 + 20, Y0 + 50], [X0 + 180, Y0 + 50]]
    with open(os.path.join(r.work, "stacked.geojson"), "w") as f:
        json.dump({"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "EPSG:32632"}},
                   "features": [{"type": "Feature", "properties": {"k": k},
                                 "geometry": {"type": "LineString", "coordinates": line}}
                                for k in range(copies)]}, f)
    scene = os.path.join(r.work, "stacked.toml")
    with open(scene, "w") as f:
        f.write(f'source = "stacked.geojson"\ncrs = "EPSG:32632"\n'
                f'extent = [{X0}, {Y0}, {X0 + 200}, {Y0 + 100}]\nextent_crs = ""\n\n'
                '[[layer]]\nname = "stacked"\nkind = "line"\ndynamic = true\nwidth = 4.0\ncolor = "#ffffff10"\n')
    drawn = r.build_and_draw(scene, "stacked", ["--extent", f"{X0 + 90!r},{Y0 + 45!r},{X0 + 110!r},{Y0 + 55!r}",
                                                "--size", "64x32"])
    if drawn is None:
        return SKIP
    gl, web = pixels(drawn[0]), pixels(drawn[1])
    x, y = 32, 15  # centre (X0 + 100.16, Y0 + 50.16): on the lines
    terrain = gl[2][1][x]  # 15 pixels (4.7 m) from the lines
    a = 1 - (1 - 16 / 255) ** copies
    want = tuple(int(math.floor(min(max(a + (1 - a) * terrain[ch] / 255, 0), 1) * 255 + 0.5)) for ch in range(3))
    g, w_ = gl[2][y][x][:3], web[2][y][x][:3]
    d_gl = max(abs(p - q) for p, q in zip(g, w_))
    d_an = max(abs(p - q) for p, q in zip(want, w_))
    r.check("sixty lines on one another: browser against GL", d_gl <= 2,
            f"pixel ({x}, {y}): browser {w_}, GL {g}, difference {d_gl}/255 (need <= 2)")
    r.check("sixty lines on one another: browser against all sixty composited", d_an <= 2,
            f"{want} (alpha {a:.3f}) over terrain {terrain[:3]}, difference {d_an}/255 (need <= 2)")
    return 0


def main():
    decalprep, root, work = sys.argv[1], sys.argv[2], sys.argv[3]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    r = Runner(decalprep, work)
    t = time.time()
    try:
        for part in (crossing, stacked, lambda r: monaco(r, root), lambda r: monaco(r, root, dashed=True)):
            if part(r) == SKIP:
                return SKIP
    except RuntimeError as e:
        print("FAIL:", e)
        return 1
    print(f"{r.checks - r.failed} of {r.checks} checks pass ({time.time() - t:.0f} s)")
    return 1 if r.failed else 0


if __name__ == "__main__":
    sys.exit(main())
