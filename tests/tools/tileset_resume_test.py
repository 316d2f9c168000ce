#!/usr/bin/env python3
"""A tileset build killed with SIGKILL, then run again, equals an
uninterrupted build, and the second run rebuilds only the tiles the first
had not finished (formats/SPEC.md "Tilesets", resume).

Builds the Monaco sample as a 500 m tileset once, uninterrupted, and reads
from its report how long the stages before the tiles take and how long the
tiles take. Then RUNS times: `timeout -s KILL T decalprep build ...` with T
drawn uniformly over the middle of the tiles stage, then the same build
again with --progress json. After the second run every file of the tileset
must equal the uninterrupted build's byte for byte, no other file may be
there, and its report and its progress must say it kept the tiles the
killed run finished (built + reused = tiles, reused > 0 in at least one run).

Usage: tileset_resume_test.py DECALPREP SOURCE_DIR WORK_DIR [RUNS] [SHARED]
SHARED: the folder of tileset_fixture.sh, whose tiles/ and tiles.json are
the uninterrupted build (made here when it is missing).
"""
import json
import os
import random
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tileset_util import tree  # noqa: E402


def main():
    tool, src, work = sys.argv[1:4]
    runs = int(sys.argv[4]) if len(sys.argv) > 4 else 2
    shared = sys.argv[5] if len(sys.argv) > 5 else ""
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    scene = os.path.join(src, "samples", "monaco", "scene.toml")
    build = [tool, "build", scene, "--tile-size", "500", "--jobs", "2"]
    if shared and os.path.exists(os.path.join(shared, "done")):
        ref = os.path.join(shared, "tiles")
        report = os.path.join(shared, "tiles.json")
    else:
        ref = os.path.join(work, "ref")
        report = os.path.join(work, "ref.json")
        r = subprocess.run(build + ["-o", ref, "--report", report, "-q"], capture_output=True,
                           text=True)
        if r.returncode != 0:
            print("FAIL: the uninterrupted build failed:", r.stderr)
            return 1
    t = json.load(open(report))["timings_s"]
    before = t["read"] + t["project"] + t["clean"]
    tiles = t["tiles"]
    want = tree(ref)
    ntiles = json.load(open(report))["tileset"]["tiles"]
    print("uninterrupted: %d tiles, %.2f s before the tiles, %.2f s of tiles" % (ntiles, before, tiles))
    rng = random.Random(20261124)
    any_reused = False
    for run in range(runs):
        out = os.path.join(work, "run%d" % run)
        kill_at = before + tiles * rng.uniform(0.25, 0.85)
        k = subprocess.run(["timeout", "-s", "KILL", "%.3f" % kill_at] + build + ["-o", out, "-q"],
                           capture_output=True, text=True)
        killed = k.returncode in (124, 137)  # timeout says 124 when it killed the build
        index_after_kill = os.path.exists(os.path.join(out, "tileset.json"))
        if killed and index_after_kill:
            print("FAIL: run %d: tileset.json exists although the build was killed" % run)
            return 1
        rep = os.path.join(work, "run%d.json" % run)
        r = subprocess.run(build + ["-o", out, "--report", rep, "--progress", "json"],
                           capture_output=True, text=True)
        if r.returncode != 0:
            print("FAIL: run %d: the second build failed:" % run, r.stderr)
            return 1
        got = tree(out)
        if got != want:
            missing = sorted(set(want) - set(got))
            extra = sorted(set(got) - set(want))
            differ = sorted(f for f in set(want) & set(got) if want[f] != got[f])
            print("FAIL: run %d differs from the uninterrupted build: missing %s extra %s differ %s"
                  % (run, missing[:5], extra[:5], differ[:5]))
            return 1
        ts = json.load(open(rep))["tileset"]
        events = [json.loads(line) for line in r.stderr.splitlines() if line.startswith("{")]
        said = [e for e in events if e.get("event") == "tileset"]
        if not said or said[-1]["reused"] != ts["reused"] or said[-1]["built"] != ts["built"]:
            print("FAIL: run %d: the progress does not say what was kept: %s" % (run, said))
            return 1
        if ts["built"] + ts["reused"] != ntiles:
            print("FAIL: run %d: built %d + reused %d != %d tiles" % (run, ts["built"], ts["reused"], ntiles))
            return 1
        any_reused = any_reused or ts["reused"] > 0
        print("run %d: killed at %.2f s (%s); re-run built %d, kept %d of %d tiles; identical"
              % (run, kill_at, "killed" if killed else "had finished", ts["built"], ts["reused"], ntiles))
    if not any_reused:
        print("FAIL: no re-run kept a tile: resume never happened")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
