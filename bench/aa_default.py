#!/usr/bin/env python3
"""bench/aa_default.py — which `render --aa` a cartographer would choose.

  bench/aa_default.py [--build-dir build/release] [--out bench/report] [--super 3]

Builds the Monaco sample (samples/monaco/scene.toml) and draws its static
decal layer (`--raw`, straight-alpha float32 RGBA) in GL at 640x360 with each
of `--aa none`, `coverage` and `msaa4`, in three views over flat terrain: a
top-down view of the whole package, a top-down close-up of the old town, and
an oblique view (`--fit --pitch 25`) whose far half has thin lines a few
tenths of a pixel wide. The reference is the CPU evaluator (the format's
normative rule, formats/SPEC.md "Drawing rules") at --super times the size,
box-filtered to 640x360 in premultiplied colour: the picture an ideal
anti-aliasing would give. For each view and mode: the mean absolute error
of the premultiplied RGBA against the reference (in 1/255), the share of
pixels more than 16/255 off, and the GL frame's wall time from `--stats`
(llvmpipe: not a GPU time). Prints the table and writes aa_default.csv.
Standard library only.
"""
import argparse
import array
import os
import re
import subprocess
import sys
import tempfile

from measure import add_build_and_out, decalprep_of, write_rows

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
W, H = 640, 360
VIEWS = {
    "top-down whole": ["--fit", "--ortho", "--pitch", "90"],
    "top-down old town": ["--extent-crs", "EPSG:4326", "--extent", "7.4190,43.7290,7.4270,43.7335"],
    "oblique": ["--fit", "--pitch", "25"],
}


def raw(path):
    a = array.array("f")
    with open(path, "rb") as f:
        a.frombytes(f.read())
    return a


def premultiplied_box(a, w, h, k):
    """The straight-alpha image `a` (w x h) box-filtered by k x k, premultiplied."""
    out = array.array("f", bytes(4 * 4 * (w // k) * (h // k)))
    ow = w // k
    inv = 1.0 / (k * k)
    for j in range(h):
        oj = (j // k) * ow
        row = j * w * 4
        for i in range(w):
            at = row + 4 * i
            al = a[at + 3]
            if al == 0.0:
                continue
            o = 4 * (oj + i // k)
            out[o] += a[at] * al * inv
            out[o + 1] += a[at + 1] * al * inv
            out[o + 2] += a[at + 2] * al * inv
            out[o + 3] += al * inv
    return out


def premultiplied(a):
    out = array.array("f", a)
    for p in range(0, len(a), 4):
        al = a[p + 3]
        out[p] *= al
        out[p + 1] *= al
        out[p + 2] *= al
    return out


def compare(ref, img):
    total, off = 0.0, 0
    for p in range(0, len(ref), 4):
        d = max(abs(ref[p + c] - img[p + c]) for c in range(4))
        total += sum(abs(ref[p + c] - img[p + c]) for c in range(4)) / 4
        off += d > 16 / 255
    n = len(ref) // 4
    return 255 * total / n, 100.0 * off / n


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--super", type=int, default=3)
    add_build_and_out(ap)
    a = ap.parse_args()
    tool = decalprep_of(a)
    work = tempfile.mkdtemp(prefix="aa_default_")
    pkg = os.path.join(work, "monaco.decals")
    subprocess.run([tool, "build", os.path.join(ROOT, "samples", "monaco", "scene.toml"), "-o", pkg,
                    "-q"], check=True)
    rows = []
    for view, args in VIEWS.items():
        k = a.super
        ref_path = os.path.join(work, "ref.raw")
        subprocess.run([tool, "render", pkg, "--flat", "--cpu", "--size", "%dx%d" % (W * k, H * k),
                        "--stretch", "--raw", ref_path, "-o", os.path.join(work, "ref.png")] + args,
                       check=True, stdout=subprocess.DEVNULL)
        ref = premultiplied_box(raw(ref_path), W * k, H * k, k)
        for mode in ("none", "coverage", "msaa4"):
            path = os.path.join(work, mode + ".raw")
            r = subprocess.run([tool, "render", pkg, "--flat", "--size", "%dx%d" % (W, H), "--stretch",
                                "--aa", mode, "--stats", "--raw", path,
                                "-o", os.path.join(work, mode + ".png")] + args,
                               check=True, capture_output=True, text=True)
            m = re.search(r"frame: ([0-9.]+) ms", r.stdout + r.stderr)
            mae, off = compare(ref, premultiplied(raw(path)))
            row = {"view": view, "aa": mode, "mean_abs_error_255": round(mae, 3),
                   "pixels_off_16_pct": round(off, 3), "frame_ms_llvmpipe": float(m.group(1)) if m else ""}
            rows.append(row)
            print("%-18s %-9s mean |error| %6.3f/255  pixels > 16/255 off %6.3f%%  frame %s ms" %
                  (view, mode, mae, off, row["frame_ms_llvmpipe"]))
    write_rows(os.path.join(a.out, "aa_default.csv"), rows)
    print("wrote", os.path.join(a.out, "aa_default.csv"))


if __name__ == "__main__":
    sys.exit(main())
