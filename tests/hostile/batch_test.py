#!/usr/bin/env python3
"""Batch mode: 5 scene files, one with a missing source, in
one folder. `decalprep build DIR -o OUT --jobs 2` must build the other 4
(each accepted by `decalprep verify`), exit non-zero, and write a summary
that names the failed scene and why.

Usage: batch_test.py DECALPREP WORK_DIR
"""
import json
import os
import shutil
import subprocess
import sys


def main():
    tool, work = sys.argv[1:3]
    shutil.rmtree(work, ignore_errors=True)
    scenes = os.path.join(work, "scenes")
    os.makedirs(scenes)
    for k in range(5):
        # A square of 10 m * (k + 1) near Monaco, read through GDAL (GeoJSON).
        d = 1e-4 * (k + 1)
        ring = [[7.42, 43.73], [7.42 + d, 43.73], [7.42 + d, 43.73 + d], [7.42, 43.73 + d], [7.42, 43.73]]
        src = os.path.join(work, f"square{k}.geojson")
        with open(src, "w") as f:
            json.dump({"type": "FeatureCollection", "features": [
                {"type": "Feature", "id": 1, "properties": {}, "geometry": {"type": "Polygon", "coordinates": [ring]}}]}, f)
        if k == 3:
            src = os.path.join(work, "no_such_file.geojson")
        with open(os.path.join(scenes, f"scene{k}.toml"), "w") as f:
            f.write(f'source = "{src}"\n\n[[layer]]\nname = "squares"\nkind = "polygon"\n')
    out = os.path.join(work, "out")
    r = subprocess.run([tool, "build", scenes, "-o", out, "--jobs", "2"], capture_output=True, text=True)
    print(r.stderr)
    fails = []
    if r.returncode == 0:
        fails.append("exit code 0 although scene3 failed")
    summary = json.load(open(os.path.join(out, "summary.json")))
    print(json.dumps(summary, indent=1))
    if summary.get("built") != 4 or summary.get("failed") != 1:
        fails.append(f"summary counts built={summary.get('built')} failed={summary.get('failed')}")
    for p in summary["packages"]:
        name = os.path.basename(p["scene"])
        if name == "scene3.toml":
            if p["status"] != "failed" or "no_such_file.geojson" not in p.get("error", ""):
                fails.append(f"scene3 not reported as failed with its missing source: {p}")
            if os.path.exists(os.path.join(out, "scene3.decals")):
                fails.append("scene3.decals exists")
        else:
            if p["status"] != "built":
                fails.append(f"{name} did not build: {p}")
                continue
            for key in ("seconds", "peak_rss_mib", "counts"):
                if key not in p:
                    fails.append(f"{name}: summary lacks {key}")
            if p.get("counts", {}).get("kept") != 1:
                fails.append(f"{name}: counts {p.get('counts')}")
            v = subprocess.run([tool, "verify", p["output"]], capture_output=True, text=True)
            if v.returncode != 0:
                fails.append(f"{name}: verify rejected {p['output']}: {v.stdout}{v.stderr}")
    # A partial scene (skip_failures dropped a failing feature) beside a clean
    # one: both packages are written, the summary says "partial", exit 4.
    scenes2 = os.path.join(work, "scenes2")
    os.makedirs(scenes2)
    sq = lambda cx: [[cx - 5, 5423000 - 5], [cx + 5, 5423000 - 5], [cx + 5, 5423000 + 5], [cx - 5, 5423000 + 5], [cx - 5, 5423000 - 5]]
    src = os.path.join(work, "far_apart.geojson")
    with open(src, "w") as f:
        json.dump({"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3857"}},
                   "features": [{"type": "Feature", "id": i + 1, "properties": {}, "geometry": {"type": "Polygon", "coordinates": [sq(cx)]}}
                                for i, cx in enumerate([826000.0, 826000.0 + 3e6, 826000.0 - 3e6])]}, f)
    with open(os.path.join(scenes2, "partial.toml"), "w") as f:
        f.write(f'source = "{src}"\ncrs = "EPSG:3857"\nskip_failures = true\n\n[[layer]]\nname = "far"\nkind = "polygon"\n')
    shutil.copy(os.path.join(scenes, "scene0.toml"), os.path.join(scenes2, "whole.toml"))
    out2 = os.path.join(work, "out2")
    r = subprocess.run([tool, "build", scenes2, "-o", out2], capture_output=True, text=True)
    print(r.stderr)
    summary = json.load(open(os.path.join(out2, "summary.json")))
    status = {os.path.basename(p["scene"]): p["status"] for p in summary["packages"]}
    if r.returncode != 4:
        fails.append(f"batch with a partial scene: exit {r.returncode}, expected 4")
    if status != {"partial.toml": "partial", "whole.toml": "built"} or summary.get("partial") != 1:
        fails.append(f"batch with a partial scene: summary {json.dumps(summary)[:400]}")
    for name in ("partial", "whole"):
        if not os.path.exists(os.path.join(out2, name + ".decals")):
            fails.append(f"{name}.decals missing")
    for f in fails:
        print("FAIL:", f)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
