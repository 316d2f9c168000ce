#!/usr/bin/env python3
"""bench/web_frames.py — the browser's WebGPU renderer beside the GL renderer.

  bench/web_frames.py [--build-dir build/release] [--work bench/out/web_frames]
                      [--out bench/report] [--size 1280x720] [--frames 5] [--repeats 3]
                      [--data <checkout>/../shared/data]

Draws the same views with `decalprep render --stats` (the GL renderer; here
Mesa llvmpipe) and `decalprep view --screenshot --stats` (web/src/render in
headless Chromium; without a GPU, Chromium's WebGPU adapter is SwiftShader),
alternating the two --repeats times, each a run of --frames frames:

  monaco-oblique   the Monaco sample over its SRTM terrain (the package's
                   STEM.terrain for the browser, the build DEM for render),
                   --fit --pitch 45;
  monaco-topdown   the Monaco sample, top-down over its whole extent;
  li-oblique       Liechtenstein (casing, dashes; flat ground; from the
                   real-data folder, left out without it), --fit --pitch 45.

Both draw static polygons and lines only (`--only polygons,lines`: the
passes the GL figure sums). The figures compared:

  gl_ms      the GL frame's passes, wall clock (terrain, static lines,
             static polygons, composite) of the last frame: warm;
  webgpu_ms  the median renderFrame time of the warm frames (all but the
             first): encode, submit and the queue done, no read-back;
  webgpu_first_ms  the first frame (pipelines compiled, buffers uploaded).

Writes web_frames.csv (one row per run; the load average before and after as
'#' lines), web_frames.svg (a bar chart of the medians) and prints the
medians as a Markdown table for bench/REPORT.md. Both are CPU rasterisers
here: their times are not GPU times. Standard library only; exits 77 (skip)
without Chromium.
"""
import argparse
import csv
import os
import re
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
from measure import bars_svg  # noqa: E402  (beside this script)

GL_PASSES = ("terrain", "static lines", "static polygons", "composite")


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    if r.returncode:
        sys.exit(f"{' '.join(cmd)} exited {r.returncode}:\n{r.stderr[-3000:]}")
    return r.stdout + r.stderr


def gl_frame(out):
    """(pass-sum wall ms, device) from render --stats."""
    total, device = 0.0, "?"
    for line in out.splitlines():
        m = re.match(r"^device: (.*?), \d+x\d+,", line)
        if m:
            device = m.group(1)
        m = re.match(r"^(terrain|static lines|static polygons|composite)\b.*?([\d.]+)\s+([\d.]+)\s*$", line)
        if m:
            total += float(m.group(3))
    return total, device


def web_frame(out):
    """(warm median ms, first ms, device) from view --screenshot --stats."""
    m = re.search(r"^frame: ([\d.]+) ms median of \d+ warm frames?, first ([\d.]+) ms", out, re.M)
    d = re.search(r"^device: (.*?), \d+x\d+$", out, re.M)
    if not m:
        sys.exit("view --stats printed no frame line:\n" + out[-2000:])
    return float(m.group(1)), float(m.group(2)), d.group(1) if d else "?"


def svg(rows, path):
    """A grouped bar chart of the medians: GL and WebGPU per view."""
    views = sorted({r["view"] for r in rows})
    med = lambda v, k: statistics.median(float(r[k]) for r in rows if r["view"] == v)  # noqa: E731
    bars_svg(path, "warm frame ms, medians (CPU rasterisers: llvmpipe GL, SwiftShader WebGPU)",
             [(v, [med(v, "gl_ms"), med(v, "webgpu_ms")], "") for v in views],
             [("GL (llvmpipe)", "#4878a8"), ("WebGPU (SwiftShader)", "#d07030")])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build/release"))
    ap.add_argument("--work", default=os.path.join(ROOT, "bench/out/web_frames"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench/report"))
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--data", default=os.path.join(os.path.dirname(ROOT), "shared", "data"))
    a = ap.parse_args()
    d = os.path.join(a.build_dir, "tools/decalprep/decalprep")
    os.makedirs(a.work, exist_ok=True)
    os.makedirs(a.out, exist_ok=True)
    t0 = time.time()

    monaco = os.path.join(a.work, "monaco.decals")
    run([d, "build", os.path.join(ROOT, "samples/monaco/scene.toml"), "-o", monaco])
    run([d, "terrain", monaco])
    views = [("monaco-oblique", monaco, ["--fit", "--pitch", "45"]),
             ("monaco-topdown", monaco, ["--fit", "--pitch", "90"])]
    li_src = os.path.join(a.data, "liechtenstein/liechtenstein-2013-08-03.osm.pbf")
    if os.path.exists(li_src):
        li = os.path.join(a.work, "li.decals")
        scene = os.path.join(a.work, "li.toml")
        with open(os.path.join(ROOT, "tests/web/webgpu_liechtenstein.toml")) as f:
            text = f.read().replace("@SHARED_DATA@", os.path.abspath(a.data))
        with open(scene, "w") as f:
            f.write(text)
        run([d, "build", scene, "-o", li])
        views.append(("li-oblique", li, ["--fit", "--pitch", "45"]))
    else:
        print(f"note: {li_src} is missing: li-oblique left out")

    common = ["--only", "polygons,lines", "--size", a.size, "--frames", str(a.frames), "--stats"]
    rows, load0 = [], os.getloadavg()
    gl_dev = web_dev = "?"
    for rep in range(a.repeats):
        for name, pkg, opts in views:
            gl_ms, gl_dev = gl_frame(run([d, "render", pkg, "--aa", "none", "-o",
                                          os.path.join(a.work, f"{name}_gl.png")] + opts + common))
            v = subprocess.run([d, "view", pkg, "--screenshot", os.path.join(a.work, f"{name}_web.png"),
                                "--timeout", "600"] + opts + common, capture_output=True, text=True)
            if v.returncode == 12:
                print("SKIP: no Chromium:", v.stderr.strip())
                return 77
            if v.returncode:
                sys.exit(f"view --screenshot exited {v.returncode}:\n{v.stderr[-3000:]}")
            web_ms, web_first, web_dev = web_frame(v.stdout + v.stderr)
            rows.append({"view": name, "repeat": rep, "size": a.size, "frames": a.frames,
                         "gl_ms": f"{gl_ms:.3f}", "webgpu_ms": f"{web_ms:.3f}",
                         "webgpu_first_ms": f"{web_first:.3f}", "gl_device": gl_dev,
                         "webgpu_device": web_dev})
            print(f"{name} #{rep}: GL {gl_ms:.1f} ms, WebGPU {web_ms:.1f} ms (first {web_first:.1f})",
                  flush=True)
    load1 = os.getloadavg()
    path = os.path.join(a.out, "web_frames.csv")
    with open(path, "w", newline="") as f:
        f.write(f"# bench/web_frames.py {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
                f"load average before {load0[0]:.2f}/{load0[1]:.2f}/{load0[2]:.2f}\n")
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
        f.write(f"# load average after {load1[0]:.2f}/{load1[1]:.2f}/{load1[2]:.2f}; "
                f"{time.time() - t0:.0f} s\n")
    svg(rows, os.path.join(a.out, "web_frames.svg"))
    print(f"\nGL: {gl_dev}; WebGPU: {web_dev}; {a.size}, medians of {a.repeats} runs; "
          f"load {load0[0]:.2f} -> {load1[0]:.2f}; {time.time() - t0:.0f} s; {path}\n")
    print("| view | GL, llvmpipe (ms) | WebGPU, SwiftShader, warm (ms) | WebGPU first frame (ms) | WebGPU / GL |")
    print("|---|---:|---:|---:|---:|")
    for name, _, _ in views:
        g = statistics.median(float(r["gl_ms"]) for r in rows if r["view"] == name)
        wv = statistics.median(float(r["webgpu_ms"]) for r in rows if r["view"] == name)
        wf = statistics.median(float(r["webgpu_first_ms"]) for r in rows if r["view"] == name)
        print(f"| {name} | {g:.1f} | {wv:.1f} | {wf:.1f} | {wv / g:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
