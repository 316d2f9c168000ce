#!/usr/bin/env python3
"""LOD at draw time in the browser (tests/web/CMakeLists.txt,
Web.LodSelectionIsTheCppSelection): the segments the WebGPU compute pass
(web/src/render/lod.js, f32 around an integer anchor) keeps equal the ones
decal::visible_segments keeps in double (tests/web/view_oracle.cpp lod, the
selection `render` and its GL pass use; view_oracle.cpp) on Liechtenstein's OpenStreetMap
roads built as dynamic lines with `lod = true`, in near, middle and far
perspective views and a far top-down view (the views of
tests/render/test_lod_gpu.cpp), at two tolerances. Also: the view
parameters the browser's lodView() makes of each camera equal
prep::render::lod_view's. Prints the counts per view and the smallest
relative margin |e* - eps(d - d*)| / eps of any point, the distance to a
tie the f32 evaluation has to stay clear of. Then the browser draws the LOD
lines from its selection (wgsl_dynamic.js DYN_LOD_WGSL): in the middle and
far views its frame is GL's with --lod on (99.9% of pixels within 2/255),
not GL's with --lod off.

Usage: lod_agreement.py DECALPREP VIEW_ORACLE REPO_ROOT WORK_DIR SHARED_DATA
Exit 77 (skip) without node, Chromium or the Liechtenstein extract.
"""
import json
import math
import os
import shutil
import subprocess
import sys

SKIP = 77
H = 270
VIEWS = [
    {"name": "near", "eye": [-150, -500, 250], "target": [0, 0, 0], "fov": 40},
    {"name": "middle", "eye": [500, -5000, 3000], "target": [0, 0, 0], "fov": 40},
    {"name": "far", "eye": [0, -26000, 16000], "target": [0, 0, 0], "fov": 40},
    {"name": "far top-down", "topdown": [-26667, -15000, 26667, 15000]},
]


def lod_points(pkg):
    """The package's lod_points as numpy columns, read by the independent
    Python reader (python/decalprep, written from formats/SPEC.md)."""
    sys.path.insert(0, os.path.join(ROOT, "python"))
    import decalprep  # noqa: E402
    with decalprep.open(pkg) as p:
        a = p.array("lod_points")
        return {k: a[k].copy() for k in ("eval_x", "eval_y", "e_star", "d_star", "flags")}


def margin(pts, view):
    """The smallest |e* - eps(d - d*)| / eps over the points not always
    included, in double (formats/SPEC.md "Visibility rule"): how close the
    view comes to a tie that a less precise evaluation could break."""
    import numpy as np
    d = np.sqrt((pts["eval_x"] * 1e-3 - view["cx"]) ** 2 + (pts["eval_y"] * 1e-3 - view["cy"]) ** 2 +
                view["cz"] ** 2) - pts["d_star"].astype(np.float64)
    eps = view["base"] + view["slope"] * np.maximum(d, 0.0)
    keep = ((pts["flags"] & 1) == 0) & (eps > 0)
    if not keep.any():
        return None
    return float(np.min(np.abs(pts["e_star"][keep].astype(np.float64) - eps[keep]) / eps[keep]))


def main():
    global ROOT
    if len(sys.argv) != 6:
        print(__doc__)
        return 2
    decalprep, oracle, ROOT, work, shared = sys.argv[1:]
    data = os.path.join(shared, "liechtenstein", "liechtenstein-2013-08-03.osm.pbf")
    if not os.path.exists(data):
        print("SKIP: Liechtenstein data missing:", data)
        return SKIP
    node = shutil.which("node")
    if not node or not os.path.exists("/usr/bin/chromium"):
        print("SKIP: node or /usr/bin/chromium is missing")
        return SKIP
    if not os.path.isdir(os.path.join(ROOT, "web", "node_modules", "fzstd")):
        print("SKIP: web/node_modules is missing (npm ci in web/)")
        return SKIP
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    toml = os.path.join(work, "roads.toml")
    with open(toml, "w") as f:
        f.write('source = "%s"\nextent = [9.47, 47.04, 9.64, 47.27]\nextent_crs = "EPSG:4326"\n'
                'resolution = 0\n[[layer]]\nname = "roads"\nlayer = "lines"\n'
                'where = "highway IS NOT NULL"\nkind = "line"\ndynamic = true\nlod = true\n'
                'width = 3\ncolor = "#c03020d0"\n' % data)
    pkg = os.path.join(work, "roads.decals")
    b = subprocess.run([decalprep, "build", toml, "-o", pkg, "--no-compress", "-q"],
                       capture_output=True, text=True)
    if b.returncode != 0:
        print("FAIL: building the roads package:", b.stderr[-2000:])
        return 1
    views = os.path.join(work, "views.json")
    with open(views, "w") as f:
        json.dump(VIEWS, f)
    pts = lod_points(pkg)
    failures = 0
    for tol in ("0.5", "2"):
        cpp = json.loads(subprocess.run([oracle, "lod", pkg, views, str(H), tol], capture_output=True,
                                        text=True, check=True).stdout)
        r = subprocess.run([node, os.path.join(ROOT, "tests", "web", "lod_harness.mjs"), "--pkg", pkg,
                            "--views", views, "--height", str(H), "--tolerance", tol],
                           capture_output=True, text=True, timeout=900)
        if r.returncode != 0:
            print(r.stderr[-3000:])
            if "chromium exited early" in r.stderr or "navigator.gpu" in r.stderr:
                print("SKIP: Chromium or WebGPU cannot run here")
                return SKIP
            print("FAIL: lod_harness.mjs exited %d" % r.returncode)
            return 1
        web = json.loads(r.stdout)["views"]
        for c, w in zip(cpp, web):
            name = "%s, %s px" % (c["name"], tol)
            same_view = all(math.isclose(c["view"][k], w["view"][k], rel_tol=1e-12, abs_tol=1e-12)
                            for k in ("cx", "cy", "cz", "base", "slope"))
            cs, ws = c["visible"], w["visible"]
            same = cs == ws
            only_cpp = len(set(cs) - set(ws))
            only_web = len(set(ws) - set(cs))
            m = margin(pts, c["view"])
            ok = same_view and same
            failures += not ok
            print("%s %-18s %7d of %7d LOD segments visible (C++ %d); only C++ %d, only WebGPU %d; "
                  "view %s; compute %.1f ms; nearest tie %s" % (
                      "ok  " if ok else "FAIL", name, len(ws), c["segments"], len(cs), only_cpp,
                      only_web, "equal" if same_view else "DIFFERS %s vs %s" % (c["view"], w["view"]),
                      w["ms"], "%.2e" % m if m is not None else "?"))
    failures += draw_checks(decalprep, pkg, work)
    return 1 if failures else 0


def differing(path_a, path_b):
    """Pixels whose RGB differ by more than 2/255 in some channel."""
    sys.path.insert(0, os.path.join(ROOT, "tests", "web"))
    from pixel_agreement import read_png  # noqa: E402
    w, h, a = read_png(path_a)
    w2, h2, b = read_png(path_b)
    if (w, h) != (w2, h2):
        return w * h
    return sum(1 for y in range(h) for x in range(w)
               if max(abs(a[y][4 * x + k] - b[y][4 * x + k]) for k in range(3)) > 2), w * h


def draw_checks(decalprep, pkg, work):
    """The browser draws the LOD lines from the segments it selects: its
    frame (view --screenshot, WebGPU) against render's (GL, --aa none, --lod
    on by default) in the middle and near views, at least 99.9% of pixels
    within 2/255; and the selection shows: GL with --lod off differs from
    --lod on in many pixels, and the browser is the --lod on image."""
    failures = 0
    for v in VIEWS[1:3]:
        cam = ["--eye", ",".join(map(str, v["eye"])), "--target", ",".join(map(str, v["target"])),
               "--fov", str(v["fov"]), "--size", "640x%d" % (640 * H // 480)]
        out = {k: os.path.join(work, "%s_%s.png" % (v["name"], k)) for k in ("gl", "gl_off", "web")}
        for k, extra in (("gl", []), ("gl_off", ["--lod", "off"])):
            r = subprocess.run([decalprep, "render", pkg, "-o", out[k], "--aa", "none"] + cam + extra,
                               capture_output=True, text=True)
            if r.returncode != 0:
                print("SKIP the drawing check: render (GL) exited %d: %s" % (r.returncode, r.stderr[-500:]))
                return 0
        r = subprocess.run([decalprep, "view", pkg, "--screenshot", out["web"], "--backend", "webgpu"] + cam,
                           capture_output=True, text=True, timeout=600)
        if r.returncode != 0:
            print("FAIL %s: view --screenshot exited %d: %s" % (v["name"], r.returncode, r.stderr[-1500:]))
            failures += 1
            continue
        web_on, n = differing(out["gl"], out["web"])
        web_off, _ = differing(out["gl_off"], out["web"])
        on_off, _ = differing(out["gl"], out["gl_off"])
        ok = web_on <= n // 1000 and on_off >= 100 and web_off >= 10 * max(1, web_on)
        failures += not ok
        print("%s %s view drawn: browser against GL --lod on %d of %d pixels differ (GL --lod off: %d; "
              "GL on against off: %d)" % ("ok  " if ok else "FAIL", v["name"], web_on, n, web_off, on_off))
    return failures


if __name__ == "__main__":
    sys.exit(main())
