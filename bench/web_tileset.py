#!/usr/bin/env python3
"""bench/web_tileset.py — a tileset of 10^6 vertices streamed by the browser
viewer, at three zooms.

  bench/web_tileset.py [--build-dir build/release] [--work bench/out/web_tileset]
                       [--out bench/report] [--sizes 640x360,1280x720] [--frames 5]
                       [--vertices 1e6] [--backend webgpu]

Builds bench/gen_synthetic.py "fine" (smooth polygons with a vertex every
0.2 m, smooth 3 m lines; --vertices over 8 km) as 1 km tiles with
`--levels auto`, then for each view and size draws it with
`decalprep view --screenshot --frames N --stats` (web/src/render in
headless Chromium; without a GPU its WebGPU adapter is SwiftShader) and,
in the same run, `decalprep render --stats` (GL, here Mesa llvmpipe),
both over flat ground:

  whole     the whole extent, --fit --pitch 45;
  district  an oblique view from 1.2 km up, 1.2 km south-west of the centre;
  street    an oblique view from 250 m up, 280 m south-west of the centre.

Figures per view: the browser's warm frame (median of the frames after the
first: renderFrame's encode, submit and queue done, no read-back) and its
first frame; its per-pass times (GPU timestamps where the adapter has them);
the GL frame (render --stats, every tile read and decoded in it); the tiles
chosen per level; the bytes the server sent (tileset.json and the tiles, as
counted by the server) against the full detail of the view (the level-0 tiles
it meets). Writes web_tileset.csv and web_tileset.svg (frame times and bytes
per view) and prints a Markdown table for bench/REPORT.md. Both renderers
are CPU rasterisers here: their times are not GPU times. Standard library
only (and ogr2ogr, as gen_synthetic); exits 77 (skip) without Chromium.
"""
import argparse
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import gen_synthetic  # noqa: E402  (beside this script)
from measure import add_build_and_out, bars_svg, decalprep_of  # noqa: E402


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    if r.returncode == 12 and cmd[1] == "view":
        print("SKIP: no Chromium:", r.stderr.strip())
        sys.exit(77)
    if r.returncode:
        sys.exit(f"{' '.join(cmd)} exited {r.returncode}:\n{r.stderr[-3000:]}")
    return r.stdout + r.stderr


def field(pattern, text, what):
    m = re.search(pattern, text, re.M)
    if not m:
        sys.exit(f"no {what} in:\n{text[-3000:]}")
    return m


def svg(rows, path):
    """Per view: the warm frame of each renderer, and the MiB the server sent."""
    bars_svg(path, "10^6-vertex tileset streamed: warm frame ms per view (CPU rasterisers; MiB the server sent)",
             [(f"{r['view']} {r['size']}", [float(r["web_ms"]), float(r["gl_ms"])],
               f"{int(r['sent_bytes']) / 1048576:.2f} MiB") for r in rows],
             [("browser (SwiftShader)", "#d07030"), ("render, GL (llvmpipe)", "#4878a8")])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_build_and_out(ap)
    ap.add_argument("--work", default=os.path.join(ROOT, "bench/out/web_tileset"))
    ap.add_argument("--sizes", default="640x360,1280x720")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--vertices", type=float, default=1e6)
    ap.add_argument("--backend", default="webgpu")
    a = ap.parse_args()
    d = decalprep_of(a)
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    t0 = time.time()
    scene, _ = gen_synthetic.mix_scene(a.work, int(a.vertices), "fine", extent=8000.0, kind="fine")
    tiles = os.path.join(a.work, "tiles")
    run([d, "build", scene, "-o", tiles, "--tile-size", "1000", "--levels", "auto", "-q"])
    with open(os.path.join(tiles, "tileset.json")) as f:
        index = json.load(f)
    e, (ox, oy) = index["extent"], index["frame"]["origin"]
    cx, cy = (e[0] + e[2]) / 2 - ox, (e[1] + e[3]) / 2 - oy
    cam = lambda back, up: ["--eye", f"{cx - back:.3f},{cy - back:.3f},{up:.3f}",  # noqa: E731
                            "--target", f"{cx:.3f},{cy:.3f},0"]
    views = [("whole", ["--fit", "--pitch", "45"]), ("district", cam(850.0, 1200.0)),
             ("street", cam(200.0, 250.0))]
    rows, load0 = [], os.getloadavg()
    for size in a.sizes.split(","):
        for name, opts in views:
            common = ["--size", size, "--frames", str(a.frames), "--stats", "--flat"]
            v = run([d, "view", tiles, "--screenshot", os.path.join(a.work, f"{name}_{size}_web.png"),
                     "--timeout", "900", "--backend", a.backend, *opts,
                     *[c for c in common if c != "--flat"]])
            g = run([d, "render", tiles, "--aa", "none", "-o", os.path.join(a.work, f"{name}_{size}_gl.png"),
                     *opts, *common])
            fr = field(r"^frame: ([\d.]+) ms median of \d+ warm frames?, first ([\d.]+) ms", v, "frame line")
            dev = field(r"^device: (.*?), \d+x\d+$", v, "device line").group(1)
            passes = re.search(r"^passes \((.*?), median of the warm frames\): (.*)$", v, re.M)
            data = field(r"^data: (\d+) requests, (\d+) bytes", v, "data line")
            ts = field(r"^tiles: (\d+) chosen \((.*?)\), (\d+) drawn; package bytes (\d+) of the full "
                       r"detail's (\d+)", v, "tiles line")
            glm = field(r"^frame: ([\d.]+) ms \(the gl render call", g, "GL frame line")
            gld = field(r"^device: (.*?), \d+x\d+,", g, "GL device line").group(1)
            row = {"view": name, "size": size, "frames": a.frames, "web_ms": float(fr.group(1)),
                   "web_first_ms": float(fr.group(2)), "gl_ms": float(glm.group(1)),
                   "passes": passes.group(2) if passes else "", "timing": passes.group(1) if passes else "",
                   "tiles": int(ts.group(1)), "levels": ts.group(2), "requests": int(data.group(1)),
                   "sent_bytes": int(data.group(2)), "full_detail_bytes": int(ts.group(5)),
                   "web_device": dev, "gl_device": gld}
            row["sent_pct"] = round(100.0 * row["sent_bytes"] / max(1, row["full_detail_bytes"]), 3)
            rows.append(row)
            print(f"{name} {size}: browser {row['web_ms']:.1f} ms warm (first {row['web_first_ms']:.1f}), "
                  f"GL {row['gl_ms']:.1f} ms; {row['tiles']} tiles ({row['levels']}); {row['requests']} "
                  f"requests, {row['sent_bytes']} bytes = {row['sent_pct']}% of the view's full detail "
                  f"({row['full_detail_bytes']})", flush=True)
    load1 = os.getloadavg()
    path = os.path.join(a.out, "web_tileset.csv")
    with open(path, "w", newline="") as f:
        f.write(f"# bench/web_tileset.py {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
                f"{int(a.vertices)} vertices, {len(index['tiles'])} level-0 tiles, levels 1..{len(index['levels'])}; "
                f"load average before {load0[0]:.2f}/{load0[1]:.2f}/{load0[2]:.2f}\n")
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
        f.write(f"# load average after {load1[0]:.2f}/{load1[1]:.2f}/{load1[2]:.2f}; {time.time() - t0:.0f} s\n")
    svg(rows, os.path.join(a.out, "web_tileset.svg"))
    print(f"\nbrowser: {rows[0]['web_device']}; GL: {rows[0]['gl_device']}; load {load0[0]:.2f} -> "
          f"{load1[0]:.2f}; {time.time() - t0:.0f} s; {path}\n")
    print("| view | size | tiles (levels) | sent by the server | of the view's full detail | browser warm frame "
          "(ms) | browser first frame (ms) | browser passes | GL frame, tiles decoded in it (ms) |")
    print("|---|---|---|---:|---:|---:|---:|---|---:|")
    for r in rows:
        print(f"| {r['view']} | {r['size']} | {r['tiles']} ({r['levels']}) | {r['sent_bytes']:,} B in "
              f"{r['requests']} requests | {r['sent_pct']:.2f}% of {r['full_detail_bytes']:,} B | {r['web_ms']:.1f} | "
              f"{r['web_first_ms']:.1f} | {r['passes']} | {r['gl_ms']:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
