#!/usr/bin/env python3
"""The browser renderer against decalprep's own (tests/web/CMakeLists.txt,
Web.PixelAgreement).

For each case it draws the same view twice, with `decalprep render` and with
`decalprep view --screenshot` (the WebGPU renderer of web/src/render in a
headless Chromium), and compares the images: the share of pixels within
1/255 on every channel, leaving out a one-pixel band along feature edges
(a pixel whose 3x3 neighbourhood in the reference image is not uniform),
must reach the case's threshold.

  top-down cases: render --cpu --decals against view --decals (the static
                  decal layer alone, straight alpha): the CPU evaluator's
                  query points are the pixel centres, as the browser's are;
                  one with --only lines (the page must hide the polygons)
                  and --frames 2 --stats (the frame times printed);
  oblique cases:  render (GL, --aa none) -o against view's final frame,
                  both at --fit --pitch 45 and --only polygons,lines (the
                  dynamic lines: dynamic_agreement.py): Liechtenstein
                  over flat ground (no DEM), Monaco over its SRTM terrain
                  (render: the build DEM; view: a copy of the package and
                  its STEM.terrain, written by `decalprep terrain`, moved
                  away from the DEM);
  minimum widths and an unlit layer (tests/web/webgpu_widths.toml): top-down
                  decals at 8 m pixels, and the lit final frame oblique
                  over its terrain.

With WebGPU, view must not say it leaves dynamic layers out (it draws
them); with WebGL2 (which does not), it must name them (Monaco's motorways)
when the view asks for every kind, and not with --only. --backend
webgpu|webgl2 (default webgpu) is passed to every `view`
(Web.PixelAgreementWebGL2 runs the cases with webgl2), and each view's
--stats device line must name that backend ("device: WebGPU ..." or
"device: WebGL2 ..."), so a page that fell back to the other one fails.
Every case here compares static decals, which both backends draw. Prints
one line per case with the counts. Exit 0 when every case passes,
1 when one fails (a wrong renderer fails here, it is never skipped), 77
(skip) only when Chromium is missing or cannot start.

Usage: pixel_agreement.py DECALPREP REPO_ROOT WORK_DIR SHARED_DATA_DIR [--backend webgpu|webgl2]
"""
import json
import os
import re
import shutil
import struct
import subprocess
import sys
import zlib

SKIP = 77
BROWSER_EXIT = 12  # view --screenshot: no Chromium (docs/cli.md)
LIECHTENSTEIN = "liechtenstein/liechtenstein-2013-08-03.osm.pbf"  # in SHARED_DATA_DIR


def chromium():
    """The Chromium `view --screenshot` would start ($DECALPREP_CHROMIUM, else
    chromium or chromium-headless-shell on PATH), or None."""
    return (os.environ.get("DECALPREP_CHROMIUM") or shutil.which("chromium")
            or shutil.which("chromium-headless-shell"))


def screenshot_skip(v):
    """Why a finished `view --screenshot` (a CompletedProcess with text
    stderr) is a skip rather than a failure, or None: no Chromium (exit 12),
    or a Chromium that exited before the page could run."""
    if v.returncode == BROWSER_EXIT:
        return "no Chromium: " + v.stderr.strip()
    if v.returncode and "Chromium" in v.stderr and "exited" in v.stderr and "before the page" in v.stderr \
            and "the page failed" not in v.stderr:
        return "Chromium could not start: " + v.stderr[-2000:]
    return None


def monaco_package(decalprep, root, work):
    """Empties `work` and builds the Monaco sample into WORK/monaco.decals, as
    the web tests draw it. Returns (path, None), or (None, the build's
    stderr tail) when the build fails."""
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    pkg = os.path.join(work, "monaco.decals")
    b = subprocess.run([decalprep, "build", os.path.join(root, "samples/monaco/scene.toml"), "-o", pkg],
                       capture_output=True, text=True)
    return (pkg, None) if b.returncode == 0 else (None, b.stderr[-2000:])


def read_png(path):
    """(width, height, rows of RGBA bytes) of an 8-bit RGBA PNG, non-interlaced
    (what the project's PNG writer writes)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    at, idat, width = 8, b"", None
    while at < len(data):
        n, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + n]
        at += 12 + n
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (8, 6, 0):
                raise ValueError(f"{path}: not 8-bit RGBA non-interlaced")
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    stride = width * 4
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - 4] if i >= 4 else 0
            b = prev[i]
            c = prev[i - 4] if i >= 4 else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return width, height, rows


def compare(ref_path, got_path):
    """(compared, agreeing, band, worst channel difference) outside the edge band."""
    w, h, ref = read_png(ref_path)
    w2, h2, got = read_png(got_path)
    if (w, h) != (w2, h2):
        raise ValueError(f"{got_path}: {w2}x{h2}, the reference {ref_path} is {w}x{h}")
    px = [[ref[y][4 * x:4 * x + 4] for x in range(w)] for y in range(h)]
    compared = agree = band = worst = 0
    for y in range(h):
        for x in range(w):
            p = px[y][x]
            edge = any(px[j][i] != p for j in range(max(0, y - 1), min(h, y + 2))
                       for i in range(max(0, x - 1), min(w, x + 2)))
            if edge:
                band += 1
                continue
            q = got[y][4 * x:4 * x + 4]
            d = max(abs(p[k] - q[k]) for k in range(4))
            compared += 1
            agree += d <= 1
            worst = max(worst, d)
    return compared, agree, band, worst


def blank(path):
    """True when every pixel of the PNG is the same."""
    _, _, rows = read_png(path)
    first = rows[0][:4]
    return all(r == first * (len(r) // 4) for r in rows)


def run(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=900, **kw)


def package_centre(decalprep, pkg):
    """The package extent's centre in absolute frame coordinates (render --extent's)."""
    meta = json.loads(run([decalprep, "info", "--json", pkg]).stdout)["metadata"]
    e, o = meta["extent"], meta.get("origin", {"x": 0.0, "y": 0.0})
    return (e[0] + e[2]) / 2 + o["x"], (e[1] + e[3]) / 2 + o["y"]


def main():
    decalprep, root, work, data = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
    backend = sys.argv[6] if len(sys.argv) > 6 and sys.argv[5] == "--backend" else "webgpu"
    if backend not in ("webgpu", "webgl2"):
        print(f"FAIL: --backend {backend}: expected webgpu or webgl2")
        return 1
    device = {"webgpu": "WebGPU", "webgl2": "WebGL2"}[backend]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    size = (480, 270)
    packages = {"monaco": os.path.join(work, "monaco.decals")}
    b = run([decalprep, "build", os.path.join(root, "samples/monaco/scene.toml"), "-o", packages["monaco"]])
    if b.returncode:
        print("FAIL: building the Monaco sample:", b.stderr[-2000:])
        return 1
    # Minimum widths and an unlit layer (tests/web/webgpu_widths.toml).
    widths = os.path.join(work, "widths.decals")
    b = run([decalprep, "build", os.path.join(root, "tests/web/webgpu_widths.toml"), "-o", widths])
    if b.returncode:
        print("FAIL: building webgpu_widths.toml:", b.stderr[-2000:])
        return 1
    li_source = os.path.join(data, LIECHTENSTEIN)
    if os.path.exists(li_source):
        li_scene = os.path.join(work, "webgpu_liechtenstein.toml")
        with open(os.path.join(root, "tests/web/webgpu_liechtenstein.toml")) as f:
            text = f.read().replace("@SHARED_DATA@", os.path.abspath(data))
        with open(li_scene, "w") as f:
            f.write(text)
        packages["liechtenstein"] = os.path.join(work, "liechtenstein.decals")
        b = run([decalprep, "build", li_scene, "-o", packages["liechtenstein"]])
        if b.returncode:
            print("FAIL: building", li_scene, b.stderr[-2000:])
            return 1
    else:
        print(f"note: {li_source} is missing: the Liechtenstein cases are left out")

    # (name, package, reference command options, view options, compare decals?, threshold)
    cases = []
    for name, pkg in packages.items():
        cx, cy = package_centre(decalprep, pkg)
        for metres in (0.5, 4.0):
            hw, hh = size[0] * metres / 2, size[1] * metres / 2
            extent = f"{cx - hw!r},{cy - hh!r},{cx + hw!r},{cy + hh!r}"
            opts = ["--extent", extent, "--size", f"{size[0]}x{size[1]}"]
            cases.append((f"{name} top-down {metres} m", pkg, ["--cpu"] + opts, opts, True, 0.999))
        if name == "monaco":
            # --only reaches the page: the polygon layers hidden, the lines
            # drawn (a page that ignored it would draw the polygons too);
            # --frames/--stats: the frame times printed. The 4 m extent.
            opts = ["--extent", extent, "--size", f"{size[0]}x{size[1]}", "--only", "lines"]
            cases.append((f"{name} top-down 4.0 m --only lines", pkg, ["--cpu"] + opts,
                          opts + ["--frames", "2", "--stats"], True, 0.999))
    # The final frame, oblique, against the GL renderer without
    # anti-aliasing: Liechtenstein on flat ground (built without a DEM, no
    # STEM.terrain), Monaco over the terrain file `decalprep terrain` writes
    # from its build DEM, which render reads itself.
    oblique = ["--fit", "--pitch", "45", "--size", f"{size[0]}x{size[1]}", "--only", "polygons,lines"]
    if "liechtenstein" in packages:
        cases.append(("liechtenstein oblique --fit --pitch 45 flat, final frame",
                      packages["liechtenstein"], ["--aa", "none"] + oblique, oblique, False, 0.999))
    # The view draws a copy of the package and its terrain file moved away
    # from the build DEM (the package names it by a relative path): the
    # page and the camera both take the terrain file, not the DEM.
    t = run([decalprep, "terrain", packages["monaco"]])
    if t.returncode:
        print("FAIL: decalprep terrain on the Monaco sample:", t.stderr[-2000:])
        return 1
    moved = os.path.join(work, "moved")
    os.makedirs(moved)
    for ext in (".decals", ".terrain"):
        shutil.copyfile(os.path.join(work, "monaco" + ext), os.path.join(moved, "monaco" + ext))
    cases.append(("monaco oblique --fit --pitch 45 over terrain, final frame",
                  (packages["monaco"], os.path.join(moved, "monaco.decals")),
                  ["--aa", "none"] + oblique, oblique, False, 0.999))

    # Minimum widths top-down at 8 m pixels (streets and main roads 3 px
    # wide instead of half a pixel), and the unlit parks in the lit final
    # frame over the terrain, oblique, against GL.
    cx, cy = package_centre(decalprep, widths)
    hw, hh = size[0] * 8.0 / 2, size[1] * 8.0 / 2
    opts = ["--extent", f"{cx - hw!r},{cy - hh!r},{cx + hw!r},{cy + hh!r}", "--size", f"{size[0]}x{size[1]}"]
    cases.append(("widths top-down 8.0 m (min_width_px 3)", widths, ["--cpu"] + opts, opts, True, 0.999))
    t = run([decalprep, "terrain", widths])
    if t.returncode:
        print("FAIL: decalprep terrain on webgpu_widths:", t.stderr[-2000:])
        return 1
    cases.append(("widths oblique --fit --pitch 45 over terrain (light = false), final frame",
                  widths, ["--aa", "none"] + oblique, oblique, False, 0.999))

    failed = 0
    for k, (name, pkgs, ref_opts, view_opts, decals, threshold) in enumerate(cases):
        # One package, or (render's, view's) when view draws a moved copy.
        pkg, view_pkg = pkgs if isinstance(pkgs, tuple) else (pkgs, pkgs)
        ref, ref_d = os.path.join(work, f"case{k}_render.png"), os.path.join(work, f"case{k}_render_decals.png")
        web, web_d = os.path.join(work, f"case{k}_view.png"), os.path.join(work, f"case{k}_view_decals.png")
        r = run([decalprep, "render", pkg, "-o", ref] + (["--decals", ref_d] if decals else []) + ref_opts)
        if r.returncode:
            print(f"FAIL {name}: render exited {r.returncode}: {r.stderr[-2000:]}")
            failed += 1
            continue
        v = run([decalprep, "view", view_pkg, "--screenshot", web] + (["--decals", web_d] if decals else []) +
                view_opts + ["--backend", backend, "--stats", "--timeout", "300"])
        skip = screenshot_skip(v)
        if skip:
            print("SKIP:", skip)
            return SKIP
        if v.returncode:
            print(f"FAIL {name}: view --screenshot exited {v.returncode}: {v.stderr[-3000:]}")
            failed += 1
            continue
        # WebGPU draws dynamic lines: no note may say they are left out.
        # WebGL2 does not: the note names Monaco's motorways when the view
        # asks for every kind, and nothing is noted otherwise.
        noted = "left out" in v.stderr
        wants_note = backend == "webgl2" and "--only" not in view_opts and \
            os.path.basename(view_pkg) == "monaco.decals"
        if noted != wants_note or (wants_note and "motorways left out" not in v.stderr):
            print(f"FAIL {name}: the note on dynamic lines {'missing' if wants_note else 'printed'}: "
                  f"{v.stderr[-2000:]}")
            failed += 1
            continue
        if "--stats" in view_opts and not re.search(r"^frame: [\d.]+ ms median of 1 warm frame, first ",
                                                    v.stdout, re.M):
            print(f"FAIL {name}: view --stats printed no frame times: {v.stdout[-2000:]}")
            failed += 1
            continue
        # The backend asked for drew it: --stats names the device.
        if not re.search(rf"^device: {device} ", v.stdout, re.M):
            print(f"FAIL {name}: --backend {backend}, but the page drew with another device: {v.stdout[-2000:]}")
            failed += 1
            continue
        a, bpath = (ref_d, web_d) if decals else (ref, web)
        if blank(a):
            print(f"FAIL {name}: the reference {a} is blank (a case that tests nothing)")
            failed += 1
            continue
        compared, agree, band, worst = compare(a, bpath)
        share = agree / compared if compared else 0.0
        ok = compared > 0 and share >= threshold
        failed += not ok
        print(f"{'ok  ' if ok else 'FAIL'} {name}: {agree} of {compared} pixels within 1/255 "
              f"({100 * share:.3f}%, need {100 * threshold:.1f}%), {band} edge-band pixels left out, "
              f"largest difference {worst}/255; {os.path.basename(a)} vs {os.path.basename(bpath)}")
    print(f"{len(cases) - failed} of {len(cases)} cases agree ({backend})")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
