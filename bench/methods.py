#!/usr/bin/env python3
"""bench/methods.py — the decal, volume and texture methods side by side.

  bench/methods.py [--datasets monaco,liechtenstein,syn1e5,syn1e6]
                   [--package P.decals] [--build-dir build/release]
                   [--out bench/report] [--work bench/out/methods]
                   [--frames 3] [--texture-resolution M] [--report-md bench/REPORT.md]
  bench/methods.py --from-csv bench/report/methods.csv [--report-md bench/REPORT.md]

`decalprep render --method decal|volume|texture` (thesis §5.2.2) on several
packages, static polygons and lines only. Datasets (built into --work, the
build timed):
- monaco: the sample scene (samples/monaco/scene.toml);
- liechtenstein: bench/scenes/liechtenstein.toml (skipped, saying so, where
  the OSM extract its `source` names is missing);
- syn1e5: synthetic polygons with holes + street-like lines (bench/gen_synthetic.py,
  seed 1), about 10^5 vertices, UTM 32N, built twice: lines 2 m and 8 m wide
  (syn1e5_w2, syn1e5_w8: the line-width factor of thesis Table 5.4);
- syn1e6: the same at about 10^6 vertices, lines 4 m wide.
--package P runs one given package instead (dataset name: its file name).

Per dataset and method (thesis Table 5.4's factors, as far as cheap):
- frame time (sum of the last of --frames frames' pass times, GL timestamps:
  terrain, the method's passes, composite; the texture's one-off
  rasterisation reported apart as raster_once_ms) top-down over 1600 m at
  640x360 and 1920x1080 (image size);
- the method's own GPU memory: the package's blobs (decal), the prism vertex
  buffer (volume, 12 bytes a vertex), the texture with mipmaps (texture);
- misclassified pixels against the CPU evaluator (`render --cpu`, decal alpha
  off by more than 0.5) in every render: the two 1600 m views and three zooms
  (top-down views 3200, 800 and 200 m wide, 640x360), all centred on the
  package origin.
Writes methods.csv (one row per render; the load average before and after as
'#' comment lines), methods_time.png (misclassified share against frame time)
and methods_memory.png (misclassified share against GPU memory; gnuplot).
With --report-md, also replaces the generated part of the "Methods: decal,
volume, texture" section of that file (between its begin/end markers).
--from-csv redraws the charts (and the report part) from an earlier CSV
without rendering.
Standard library only. On llvmpipe the times are CPU times of software GL,
not GPU times.
"""
import argparse
import array
import csv
import json
import os
import platform
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
METHODS = ["decal", "volume", "texture"]
SIZES = [(640, 360), (1920, 1080)]
TIMING_WIDTH = 1600.0  # view width in metres of the frame-time renders
ZOOMS = [3200.0, 800.0, 200.0]  # view widths in metres, centred on the package origin
ALL_DATASETS = ["monaco", "liechtenstein", "syn1e5", "syn1e6"]
BEGIN = "<!-- begin bench/methods.py -->"
END = "<!-- end bench/methods.py -->"
FIELDS = ["dataset", "method", "size", "zoom_m", "frame_ms", "raster_once_ms", "memory_bytes",
          "texel_m", "misclassified", "pixels", "share", "build_s", "input_vertices"]


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if p.returncode != 0:
        raise RuntimeError("%s failed (%d): %s" % (" ".join(cmd), p.returncode, p.stdout[-2000:]))
    return p.stdout


def origin(info):
    o = info.get("origin") or info.get("metadata", {}).get("origin")
    return float(o["x"]), float(o["y"])


def view(ox, oy, width, w, h):
    half_w, half_h = width / 2, width / 2 * h / w
    return "%.3f,%.3f,%.3f,%.3f" % (ox - half_w, oy - half_h, ox + half_w, oy + half_h)


def render(tool, package, method, extent, w, h, raw, args):
    cmd = [tool, "render", package, "--extent", extent, "--size", "%dx%d" % (w, h),
           "--only", "polygons,lines", "--raw", raw, "-o", raw + ".png"]
    if method == "cpu":
        cmd.append("--cpu")
    else:
        cmd += ["--method", method, "--stats", "--frames", str(args.frames)]
        if method == "texture" and args.texture_resolution:
            cmd += ["--texture-resolution", str(args.texture_resolution)]
    return run(cmd)


def frame_ms(stats):
    """Sum of the pass times (GPU ms) of the last frame, the one-off texture
    rasterisation and the total line apart."""
    frame, once = 0.0, 0.0
    for line in stats.splitlines():
        m = re.match(r"^(.*?)\s+([0-9.]+)\s+([0-9.]+)$", line)
        if not m or line.startswith("pass"):
            continue
        name = m.group(1)
        if name.startswith("total"):
            continue
        if name.startswith("texture raster"):
            once += float(m.group(2))
        else:
            frame += float(m.group(2))
    return frame, once


def method_bytes(method, stats, package_bytes):
    if method == "decal":
        return package_bytes
    if method == "volume":
        m = re.search(r"volume: (\d+) prism triangles", stats)
        return int(m.group(1)) * 3 * 12 if m else 0
    m = re.search(r"texture: \d+x\d+ texels at [0-9.]+ m, (\d+) bytes", stats)
    return int(m.group(1)) if m else 0


def texel_m(stats):
    m = re.search(r"texture: \d+x\d+ texels at ([0-9.]+) m", stats)
    return float(m.group(1)) if m else ""


def alpha(raw):
    a = array.array("f")
    with open(raw, "rb") as f:
        a.frombytes(f.read())
    return a[3::4]


def timed_build(tool, args_, package):
    t0 = time.monotonic()
    run([tool, "build"] + args_ + ["-o", package, "-q"])
    return time.monotonic() - t0


def synthetic(tool, work, name, vertices, widths):
    """Generates polygons + lines (half the vertices each), converts them to
    FlatGeobuf and builds one package per line width. Returns
    [(dataset, package, build_s, vertices)]."""
    gen = os.path.join(ROOT, "bench", "gen_synthetic.py")
    src = {}
    for kind in ("polygons", "lines"):
        fgb = os.path.join(work, "%s_%s.fgb" % (name, kind))
        if not os.path.exists(fgb):
            seq = fgb[:-4] + ".geojsonl"
            run([sys.executable, gen, kind, str(vertices // 2), seq, "--seed", "1"])
            run(["ogr2ogr", "-f", "FlatGeobuf", fgb, seq, "-a_srs", "EPSG:32632"])
            os.remove(seq)
        src[kind] = fgb
    out = []
    for width in widths:
        dataset = name if len(widths) == 1 else "%s_w%g" % (name, width)
        scene = os.path.join(work, dataset + ".toml")
        with open(scene, "w") as f:
            f.write('crs = "EPSG:32632"\nresolution = 0.1\n\n'
                    '[[layer]]\nname = "polygons"\nsource = "%s"\nkind = "polygon"\ncolor = "#a9c98f"\n\n'
                    '[[layer]]\nname = "lines"\nsource = "%s"\nkind = "line"\nwidth = %g\n'
                    'corner = "round"\ncolor = "#ffffff"\n' % (src["polygons"], src["lines"], width))
        package = os.path.join(work, dataset + ".decals")
        out.append((dataset, package, timed_build(tool, [scene], package), vertices))
    return out


def datasets(tool, work, args):
    if args.package:
        return [(os.path.splitext(os.path.basename(args.package))[0], args.package, "", "")]
    out = []
    for name in args.datasets.split(","):
        if name == "monaco":
            p = os.path.join(work, "monaco.decals")
            out.append((name, p, timed_build(tool, [os.path.join(ROOT, "samples", "monaco", "scene.toml")], p), ""))
        elif name == "liechtenstein":
            scene = os.path.join(ROOT, "bench", "scenes", "liechtenstein.toml")
            with open(scene) as f:
                m = re.search(r'^source\s*=\s*"([^"]+)"', f.read(), re.M)
            data = os.path.join(os.path.dirname(scene), m.group(1)) if m else ""
            if not os.path.exists(data):
                print("liechtenstein: %s missing, skipped" % os.path.normpath(data), flush=True)
                continue
            p = os.path.join(work, "liechtenstein.decals")
            out.append((name, p, timed_build(tool, [scene], p), ""))
        elif name == "syn1e5":
            out += synthetic(tool, work, name, 100_000, [2.0, 8.0])
        elif name == "syn1e6":
            out += synthetic(tool, work, name, 1_000_000, [4.0])
        else:
            sys.exit("methods.py: unknown dataset '%s' (%s)" % (name, ",".join(ALL_DATASETS)))
    return out


def measure(tool, dataset, package, build_s, vertices, work, args):
    info = json.loads(run([tool, "info", package, "--json"]))
    ox, oy = origin(info)
    # The decal method's GPU data: the blobs as uploaded (uncompressed sizes).
    package_bytes = sum(int(b.get("raw_size", 0)) for b in info.get("blobs", []) if b.get("name") != "manifest_entries")
    views = [(TIMING_WIDTH, w, h) for w, h in SIZES] + [(z, 640, 360) for z in ZOOMS if z != TIMING_WIDTH]
    rows = []
    for method in METHODS:
        for width, w, h in views:
            tag = "%s_%s_%d_%dx%d" % (dataset, method, width, w, h)
            raw = os.path.join(work, tag + ".rgba")
            oracle = os.path.join(work, "%s_cpu_%d_%dx%d.rgba" % (dataset, width, w, h))
            ext = view(ox, oy, width, w, h)
            if method == METHODS[0] or not os.path.exists(oracle):
                render(tool, package, "cpu", ext, w, h, oracle, args)
            try:
                stats = render(tool, package, method, ext, w, h, raw, args)
            except RuntimeError as e:  # reported and left out, the other renders go on
                print("%s: %s" % (tag, e), file=sys.stderr, flush=True)
                continue
            frame, once = frame_ms(stats)
            a, b = alpha(raw), alpha(oracle)
            wrong = sum(1 for x, y in zip(a, b) if abs(x - y) > 0.5)
            row = {"dataset": dataset, "method": method, "size": "%dx%d" % (w, h), "zoom_m": int(width),
                   "frame_ms": round(frame, 3), "raster_once_ms": round(once, 3) if method == "texture" else "",
                   "memory_bytes": method_bytes(method, stats, package_bytes), "texel_m": texel_m(stats),
                   "misclassified": wrong, "pixels": len(b), "share": round(wrong / len(b), 6),
                   "build_s": round(build_s, 3) if build_s != "" else "", "input_vertices": vertices}
            rows.append(row)
            print(row, flush=True)
            os.remove(raw)
            os.remove(raw + ".png")
    return rows


def summary(rows):
    """One line per dataset and method: the figures of the report table."""
    out = []
    for r in rows:
        key = (r["dataset"], r["method"])
        if not out or out[-1]["key"] != key:
            out.append({"key": key, "dataset": r["dataset"], "method": r["method"], "build_s": r["build_s"],
                        "memory_bytes": r["memory_bytes"], "texel_m": r["texel_m"], "raster_once_ms": None,
                        "frame": {}, "zoom": {}})
        s = out[-1]
        if r["zoom_m"] == int(TIMING_WIDTH):
            s["frame"][r["size"]] = r["frame_ms"]
        if r["raster_once_ms"] != "":  # the same pass in every render: the least disturbed one
            s["raster_once_ms"] = min(s["raster_once_ms"] or r["raster_once_ms"], r["raster_once_ms"])
        if r["size"] == "640x360":
            s["zoom"][r["zoom_m"]] = (r["misclassified"], r["share"])
    return out


def charts(rows, args, work):
    """Two gnuplot charts over the 640x360 renders (every zoom): misclassified
    share against frame time and against the method's GPU memory."""
    sums = summary(rows)
    dat = os.path.join(work, "methods.dat")
    with open(dat, "w") as f:
        for i, method in enumerate(METHODS):
            f.write("# %s\n" % method)
            for s in sums:
                if s["method"] != method:
                    continue
                err = sum(sh for _, sh in s["zoom"].values()) / max(len(s["zoom"]), 1)
                f.write("%s %f %f %d %g\n" % (s["dataset"], s["frame"].get("640x360", 0),
                                              s["frame"].get("1920x1080", 0), s["memory_bytes"], max(err, 1e-6)))
            f.write("\n\n")
    common = """set terminal pngcairo size 1000,600 noenhanced
set logscale xy
set ylabel "misclassified share vs CPU evaluator\\n(mean of 4 views at 640x360; 0 drawn at 1e-6)"
set key outside right top
set grid
set offsets graph 0.05, graph 0.2, graph 0.1, graph 0.1
set format y '%g'
"""
    plots = []
    for i, method in enumerate(METHODS):
        plots.append(("'%s' index %d using {X}:5 with points pt %d ps 1.5 title '%s', "
                      "'' index %d using {X}:5:1 with labels left rotate by 35 offset 0.6,0.6 font ',8' notitle")
                     % (dat, i, [7, 5, 9][i], method, i))
    out = []
    for name, x, xlabel in (("methods_time.png", "2", "frame time at 640x360, ms (llvmpipe: CPU time of software GL)"),
                            ("methods_memory.png", "4", "method's GPU memory, bytes (blobs / prism vertices / texture + mipmaps)")):
        png = os.path.join(args.out, name)
        script = common + "set output '%s'\nset xlabel \"%s\"\nplot %s\n" % (
            png, xlabel, ", \\\n     ".join(p.replace("{X}", x) for p in plots))
        try:
            subprocess.run(["gnuplot"], input=script, text=True, check=True)
            out.append(png)
        except (OSError, subprocess.CalledProcessError) as e:
            print("gnuplot failed: %s" % e, file=sys.stderr)
    return out


def mib(b):
    return "%.1f MiB" % (b / 2**20) if b >= 2**20 else "%.0f KiB" % (b / 2**10)


def report_block(rows, load0, load1, took, args):
    sums = summary(rows)
    L = [BEGIN, "",
         "Generated by `bench/methods.py` (%s UTC, %d s, --frames %d, --texture-resolution %s). Device: Mesa llvmpipe on a "
         "%d-core VM (%s); frame times are CPU rasteriser times, not GPU times. Load average (1/5/15 min) at start "
         "%.2f/%.2f/%.2f, at end %.2f/%.2f/%.2f (the machine is shared). Every row of every render: "
         "[report/methods.csv](report/methods.csv)." % (
             time.strftime("%Y-%m-%d %H:%M", time.gmtime()), took, args.frames,
             "%g" % args.texture_resolution if args.texture_resolution else "default",
             os.cpu_count(), platform.platform(), *load0, *load1),
         "",
         "| dataset | method | preprocessing | GPU memory | frame 640x360 | frame 1920x1080 | misclassified 3200 m | 800 m | 200 m |",
         "|---|---|---|---|---|---|---|---|---|"]
    done = {s["key"] for s in sums}
    for d in dict.fromkeys(s["dataset"] for s in sums):  # a method none of whose renders succeeded
        for m in METHODS:
            if (d, m) not in done:
                sums.append({"key": (d, m), "dataset": d, "method": m, "failed": True})
    order = {d: i for i, d in enumerate(dict.fromkeys(s["dataset"] for s in sums))}
    sums.sort(key=lambda s: (order[s["dataset"]], METHODS.index(s["method"])))
    for s in sums:
        if s.get("failed"):
            L.append("| %s | %s | every render failed (the run's stderr names the command and exit status) |||||||"
                     % (s["dataset"], s["method"]))
            continue
        pre = "build %.2f s" % s["build_s"] if s["build_s"] != "" else "—"
        if s["method"] == "texture":
            pre += " + raster %.0f ms" % s["raster_once_ms"]
        mem = mib(s["memory_bytes"])
        if s["texel_m"] != "":
            mem += " (%g m texels)" % s["texel_m"]
        zs = []
        for z in ZOOMS:
            n, sh = s["zoom"].get(int(z), ("", 0))
            zs.append("—" if n == "" else "0" if n == 0 else "%d (%.3g%%)" % (n, 100 * sh))
        L.append("| %s | %s | %s | %s | %.1f ms | %.1f ms | %s |" % (
            s["dataset"], s["method"], pre, mem, s["frame"].get("640x360", 0), s["frame"].get("1920x1080", 0),
            " | ".join(zs)))
    L += ["",
          "Preprocessing: `decalprep build` wall time of the package (every method starts from it) and, for the "
          "texture, the one-off rasterisation pass (GL timestamps). Frame time: the sum of the last frame's pass times "
          "(terrain, the method's passes, composite), top-down over 1600 m. Misclassified: pixels of the 640x360 views "
          "3200, 800 and 200 m wide whose alpha differs by more than 0.5 from `decalprep render --cpu` (the decal "
          "evaluator); 640x360 has 230400 pixels.",
          "",
          "![Misclassified share against frame time](report/methods_time.png)",
          "",
          "![Misclassified share against GPU memory](report/methods_memory.png)",
          "", END]
    return "\n".join(L)


def splice(path, block):
    with open(path) as f:
        text = f.read()
    if BEGIN in text and END in text:
        a, b = text.index(BEGIN), text.index(END) + len(END)
        text = text[:a] + block + text[b:]
    else:
        section = "## Methods: decal, volume, texture\n\n" + block + "\n\n"
        i = text.find("\n## Method\n")
        text = text + "\n" + section if i < 0 else text[:i + 1] + section + text[i + 1:]
    with open(path, "w") as f:
        f.write(text)


def read_csv(path):
    """Rows, load averages and run time of an earlier methods.csv."""
    with open(path) as f:
        head = f.readline()
        rows = list(csv.DictReader(f))
    nums = re.findall(r"[0-9.]+", head.split("at start")[1]) if "at start" in head else []
    load0 = tuple(float(x) for x in nums[0:3]) if len(nums) >= 6 else (0, 0, 0)
    load1 = tuple(float(x) for x in nums[3:6]) if len(nums) >= 6 else (0, 0, 0)
    m = re.search(r"run took ([0-9.]+) s", head)
    for r in rows:
        for k in ("zoom_m", "memory_bytes", "misclassified", "pixels"):
            r[k] = int(r[k])
        for k in ("frame_ms", "share", "raster_once_ms", "texel_m", "build_s"):
            r[k] = float(r[k]) if r[k] != "" else ""
    return rows, load0, load1, float(m.group(1)) if m else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--datasets", default=",".join(ALL_DATASETS))
    ap.add_argument("--package")
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))
    ap.add_argument("--work", default=os.path.join(ROOT, "bench", "out", "methods"))
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--texture-resolution", type=float,
                    help="metres a texel; default: the renderer's (1 m, coarser beyond 8192 texels a side)")
    ap.add_argument("--report-md")
    ap.add_argument("--from-csv")
    args = ap.parse_args()
    if args.from_csv:
        rows, load0, load1, took = read_csv(args.from_csv)
        with open(args.from_csv) as f:
            m = re.search(r"--frames (\d+)", f.readline())
        args.frames = int(m.group(1)) if m else args.frames
        os.makedirs(args.work, exist_ok=True)
        pngs = charts(rows, args, args.work)
        if args.report_md:
            splice(args.report_md, report_block(rows, load0, load1, took, args))
        print("wrote %s" % ", ".join(pngs + ([args.report_md] if args.report_md else [])))
        return
    tool = os.path.join(args.build_dir, "tools", "decalprep", "decalprep")
    os.makedirs(args.out, exist_ok=True)
    os.makedirs(args.work, exist_ok=True)
    load0, t0 = os.getloadavg(), time.monotonic()

    rows = []
    for dataset, package, build_s, vertices in datasets(tool, args.work, args):
        rows += measure(tool, dataset, package, build_s, vertices, args.work, args)
    load1, took = os.getloadavg(), time.monotonic() - t0

    csv_path = os.path.join(args.out, "methods.csv")
    with open(csv_path, "w", newline="") as f:
        f.write("# bench/methods.py; load average (1/5/15 min) at start %.2f/%.2f/%.2f, at end %.2f/%.2f/%.2f; "
                "run took %.0f s; --frames %d; llvmpipe, %d cores\n" % (*load0, *load1, took, args.frames, os.cpu_count()))
        wr = csv.DictWriter(f, fieldnames=FIELDS)
        wr.writeheader()
        wr.writerows(rows)
    pngs = charts(rows, args, args.work)
    if args.report_md:
        splice(args.report_md, report_block(rows, load0, load1, took, args))
    print("wrote %s" % ", ".join([csv_path] + pngs + ([args.report_md] if args.report_md else [])))


if __name__ == "__main__":
    main()
