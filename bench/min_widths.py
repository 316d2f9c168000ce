#!/usr/bin/env python3
"""bench/min_widths.py — what minimum widths cost (formats/SPEC.md "Minimum widths").

  bench/min_widths.py [--build-dir build/release] [--out bench/report] [--runs 3]

Both sides in one run: the Monaco sample as shipped (samples/monaco/scene.toml:
streets with min_width_px = 2, motorways with min_width_m = 12) and the same
scene with those two keys taken out. For each: the build's wall time and the
package's bytes, then the demo's oblique view (1280x720, its camera) drawn
in GL with --stats: the static line pass and the frame (llvmpipe here: not
GPU times), best of --runs. Prints the table with the ratios (with keys /
without) and writes min_widths.csv. Standard library only.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

from measure import add_build_and_out, decalprep_of, measured, write_rows

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLE = os.path.join(ROOT, "samples", "monaco")
VIEW = ["--eye", "900,-3200,1300", "--target", "150,-300,60", "--fov", "45", "--size", "1280x720"]


def scene_without_keys(folder):
    """The sample scene without min_width_px / min_width_m, beside its data."""
    text = open(os.path.join(SAMPLE, "scene.toml")).read()
    kept = [l for l in text.splitlines() if not re.match(r"\s*min_width_(px|m)\s*=", l)]
    path = os.path.join(folder, "scene.toml")
    with open(path, "w") as f:
        f.write("\n".join(kept) + "\n")
    for name in ("monaco.osm.pbf", "N43E007.hgt.zip"):
        os.symlink(os.path.join(SAMPLE, name), os.path.join(folder, name))
    return path


def frame_times(tool, pkg, runs):
    """(static line pass ms, frame ms), each the best of `runs` GL draws."""
    lines, frames = [], []
    dem = "/vsizip/" + os.path.join(SAMPLE, "N43E007.hgt.zip") + "/N43E007.hgt"
    for _ in range(runs):
        out = os.path.join(os.path.dirname(pkg), "view.png")
        r = subprocess.run([tool, "render", pkg, "--dem", dem, *VIEW, "-o", out, "--stats"],
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit("render failed (headless GL?): " + r.stderr[-800:])
        text = r.stdout + r.stderr
        m = re.search(r"^static lines \[[^)\n]*\)\s+([0-9.]+)", text, re.M)
        f = re.search(r"^frame: ([0-9.]+) ms", text, re.M)
        lines.append(float(m.group(1)) if m else float("nan"))
        frames.append(float(f.group(1)))
    return min(lines), min(frames)


def main():
    ap = argparse.ArgumentParser()
    add_build_and_out(ap)
    ap.add_argument("--runs", type=int, default=3)
    a = ap.parse_args()
    tool = decalprep_of(a)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        plain = os.path.join(tmp, "plain")
        os.makedirs(plain)
        scenes = {"with keys": os.path.join(SAMPLE, "scene.toml"),
                  "without": scene_without_keys(plain)}
        for side, scene in scenes.items():
            pkg = os.path.join(tmp, side.replace(" ", "_") + ".decals")
            wall, _, _ = measured([tool, "build", scene, "-o", pkg, "-q"])
            line_ms, frame_ms = frame_times(tool, pkg, a.runs)
            rows.append({"side": side, "build_s": round(wall, 3),
                         "package_bytes": os.path.getsize(pkg),
                         "static_lines_ms": round(line_ms, 1), "frame_ms": round(frame_ms, 1)})
    w, wo = rows
    print("%-10s %8s %14s %16s %10s" % ("", "build s", "package bytes", "static lines ms",
                                        "frame ms"))
    for r in rows:
        print("%-10s %8.2f %14d %16.1f %10.1f" % (r["side"], r["build_s"], r["package_bytes"],
                                                  r["static_lines_ms"], r["frame_ms"]))
    print("%-10s %8.2f %14.2f %16.2f %10.2f" % (
        "ratio", w["build_s"] / wo["build_s"], w["package_bytes"] / wo["package_bytes"],
        w["static_lines_ms"] / wo["static_lines_ms"], w["frame_ms"] / wo["frame_ms"]))
    print("(GL on this machine's device; llvmpipe times are not GPU times)")
    write_rows(os.path.join(a.out, "min_widths.csv"), rows)


main()
