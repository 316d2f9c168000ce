#!/usr/bin/env python3
"""bench/blob_bytes.py — raw bytes per blob and per input vertex, before and
after, in one run.

  bench/blob_bytes.py --before DIR [--after DIR] [--out DIR] [--big] [--samples N]

DIR is a build directory (tools/decalprep/decalprep and bench/bench_accuracy
inside): --before the build of the commit to compare with (e.g. a worktree of
main built in its own build dir), --after this checkout's build/release.
Datasets: synthetic polygons at 10^6 vertices (bench/gen_synthetic.py, seed 1,
UTM 32N as bench/run builds them), with --big also 10^7, the Monaco sample
(samples/monaco/scene.toml), and the 400 m window of the 10^5 synthetic
polygons that bench/run's texture baseline uses (same extent rule). Each is
built by both tools; `decalprep info --json` gives every blob's raw (decoded)
and stored bytes; bench_accuracy --package gives the query cost per covered
point (mean, p99: BVH nodes + quad-tree nodes + edge tests + segment tests) and
the misclassified points against the GEOS oracle, on the same samples for both.

Writes OUT/blob_bytes.csv (one row per dataset, tool and blob) and
OUT/blob_bytes_summary.csv (one row per dataset and tool: raw bytes, bytes per
input vertex, package bytes on disk, query cost), and prints the summary.
Default OUT: bench/report. Standard library only.
"""
import argparse
import csv
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
UTM = "EPSG:32632"


def run(cmd, cwd=None):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd)
    if p.returncode != 0:
        sys.exit("%s failed (%d): %s" % (" ".join(cmd), p.returncode, p.stderr[-2000:]))
    return p.stdout


def gen(work, n):
    path = os.path.join(work, "polygons_%d.fgb" % n)
    if not os.path.exists(path):
        tmp = path[:-4] + ".geojsonl"
        run([sys.executable, os.path.join(ROOT, "bench", "gen_synthetic.py"), "polygons", str(n), tmp])
        run(["ogr2ogr", "-f", "FlatGeobuf", "-a_srs", UTM, path, tmp])
        os.remove(tmp)
    return path


def accuracy(tool_dir, inp, pkg, extra, samples):
    cmd = [os.path.join(tool_dir, "bench", "bench_accuracy"), inp, "--samples", str(samples)]
    if not inp.endswith(".toml"):
        cmd += ["--kind", "polygon", "--crs", UTM]
    if pkg:
        cmd += ["--package", pkg]
    res = {}
    for line in run(cmd + list(extra)).splitlines():
        o = json.loads(line)
        res[o["what"]] = o
    return res


def write_markdown(path, rows, summary):
    """The summary and, per dataset, raw bytes per input vertex of every blob
    before and after (blobs of either side, largest after first)."""
    out = ["| dataset | tool | format | vertices | raw bytes | raw B/vertex | after/before | package bytes (zstd) "
           "| blobs | cost mean | cost p99 | misclassified |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    version = {(r["dataset"], r["tool"]): r["version"] for r in rows}
    for i, s in enumerate(summary):
        ratio = "%.3f" % (s["raw_bytes"] / summary[i - 1]["raw_bytes"]) if s["tool"] == "after" else ""
        out.append("| %s | %s | %s | %d | %d | %.1f | %s | %d | %d | %.3f | %.0f | %d of %d |" % (
            s["dataset"], s["tool"], version.get((s["dataset"], s["tool"]), ""), s["vertices"], s["raw_bytes"],
            s["raw_bytes_per_vertex"], ratio, s["package_bytes"], s["blobs"], s["cost_mean"], s["cost_p99"],
            s["misclassified"], s["samples"]))
    for ds in dict.fromkeys(r["dataset"] for r in rows):
        out += ["", "%s, raw bytes per input vertex:" % ds, "",
                "| blob | before B/vertex | after B/vertex | after elements |", "|---|---|---|---|"]
        per = {}
        for r in rows:
            if r["dataset"] == ds:
                per.setdefault(r["blob"], {})[r["tool"]] = r
        for blob, d in sorted(per.items(), key=lambda kv: -max(x["raw_bytes"] for x in kv[1].values())):
            bb, aa = d.get("before"), d.get("after")
            out.append("| %s | %s | %s | %s |" % (blob, "%.2f" % bb["raw_bytes_per_vertex"] if bb else "",
                                                  "%.2f" % aa["raw_bytes_per_vertex"] if aa else "",
                                                  aa["count"] if aa else ""))
    with open(path, "w") as fh:
        fh.write("\n".join(out) + "\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))
    ap.add_argument("--work", default=None)
    ap.add_argument("--big", action="store_true", help="also the 10^7 synthetic set")
    ap.add_argument("--samples", type=int, default=100000)
    a = ap.parse_args()
    work = a.work or os.path.join(a.out, "work_blob_bytes")
    os.makedirs(work, exist_ok=True)
    os.makedirs(a.out, exist_ok=True)

    sets = [("polygons_1000000", gen(work, 10**6), [], 10**6)]
    if a.big:
        sets.append(("polygons_10000000", gen(work, 10**7), [], 10**7))
    sets.append(("monaco", os.path.join(ROOT, "samples", "monaco", "scene.toml"), [], None))
    # bench/run exp_raster: a 400 m square around the centre of the 10^5 set.
    p5 = gen(work, 10**5)
    o = accuracy(a.after, p5, None, [], 1000)["oracle"]
    cx, cy = (o["xmin"] + o["xmax"]) / 2 + o["origin_x"], (o["ymin"] + o["ymax"]) / 2 + o["origin_y"]
    win = ["--extent", "%.3f,%.3f,%.3f,%.3f" % (cx - 200, cy - 200, cx + 200, cy + 200), "--extent-crs", UTM]
    sets.append(("window_400m", p5, win, None))

    rows, summary = [], []
    for name, inp, extra, n in sets:
        for side, d in (("before", a.before), ("after", a.after)):
            tool = os.path.join(d, "tools", "decalprep", "decalprep")
            pkg = os.path.join(work, "%s_%s.decals" % (name, side))
            rep = pkg[:-7] + ".report.json"
            cmd = [tool, "build", inp, "-o", pkg, "--report", rep, "-q"]
            if not inp.endswith(".toml"):
                cmd += ["--kind", "polygon", "--crs", UTM]
            run(cmd + extra)
            verts = n or json.load(open(rep))["manifest"]["totals"]["vertices_in"]
            info = json.loads(run([tool, "info", "--json", pkg]))
            raw = sum(b["raw_size"] for b in info["blobs"])
            for b in info["blobs"]:
                if b["raw_size"]:
                    rows.append({"dataset": name, "tool": side, "version": "%d.%d" % (info["version"]["major"],
                                                                                      info["version"]["minor"]),
                                 "blob": b["name"], "id": b["id"], "count": b["count"], "raw_bytes": b["raw_size"],
                                 "raw_bytes_per_vertex": round(b["raw_size"] / verts, 3),
                                 "share": round(b["raw_size"] / raw, 4), "stored_bytes": b["stored_size"]})
            acc = accuracy(d, inp, pkg, extra, a.samples)
            c, pk = acc["cost"], acc["package"]
            meta = info["header"]["metadata_size"] if "metadata_size" in info.get("header", {}) else ""
            summary.append({"dataset": name, "tool": side, "vertices": verts, "raw_bytes": raw,
                            "raw_bytes_per_vertex": round(raw / verts, 2), "package_bytes": info["file_size"],
                            "zstd_blob_bytes": sum(b["stored_size"] for b in info["blobs"]), "metadata_bytes": meta,
                            "blobs": len(info["blobs"]), "cost_mean": c["total_mean"], "cost_p99": c["total_p99"],
                            "misclassified": pk["misclassified"], "samples": pk["samples"]})
            print("%-18s %-6s %6.1f B/vertex raw, %9d B on disk, cost mean %.3f p99 %.0f, misclassified %d" % (
                name, side, raw / verts, info["file_size"], c["total_mean"], c["total_p99"], pk["misclassified"]),
                file=sys.stderr)
        b, f = summary[-2], summary[-1]
        print("%-18s after/before raw bytes per vertex %.3f" % (name, f["raw_bytes"] / b["raw_bytes"]),
              file=sys.stderr)
    write_markdown(os.path.join(a.out, "blob_bytes.md"), rows, summary)
    with open(os.path.join(a.out, "blob_bytes.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(os.path.join(a.out, "blob_bytes_summary.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(summary[0]))
        w.writeheader()
        w.writerows(summary)


if __name__ == "__main__":
    main()
