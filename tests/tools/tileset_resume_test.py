#!/usr/bin/env python3
"""A tileset build killed with SIGKILL, then run again, equals an
uninterrupted build, and the second run rebuilds only the tiles the first
had not finished (formats/SPEC.md "Tilesets", resume).

Builds the Monaco sample as a 500 m tileset once, uninterrupted (or takes
the shared fixture's build). Then RUNS times: the same build, watched, and
killed with SIGKILL once K of its tiles are in the output's tiles/ folder,
K drawn uniformly over 25-85 % of the tiles (the build at nice 19, so a busy
machine does not starve the watcher; should it finish unseen all the same,
it is tried again with K halved); then the same build again with
--progress json. The kill follows the build's own progress, not a clock, so
a loaded machine moves it no more than an idle one. After the second run
every file of the tileset must equal the uninterrupted build's byte for
byte, no other file may be there, and its report and its progress must say
it kept at least the tiles the killed run had finished (built + reused =
tiles, reused >= the finished tiles seen at the kill).

Usage: tileset_resume_test.py DECALPREP SOURCE_DIR WORK_DIR [RUNS] [SHARED]
SHARED: the folder of tileset_fixture.sh, whose tiles/ and tiles.json are
the uninterrupted build (made here when it is missing).
"""
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tileset_util import tree  # noqa: E402


def finished_tiles(folder):
    """Tile packages in the output's tiles/ folder: each is renamed into
    place only when it is whole, so each is a finished tile."""
    try:
        return sum(1 for f in os.listdir(folder) if f.endswith(".decals"))
    except FileNotFoundError:
        return 0


def kill_after_tiles(cmd, folder, k, limit_s=300):
    """Runs cmd in a session of its own and SIGKILLs the session once k
    finished tiles are in folder. (killed, finished tiles at the kill)."""
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True)
    end = time.monotonic() + limit_s
    while p.poll() is None and time.monotonic() < end:
        n = finished_tiles(folder)
        if n >= k:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
            return True, finished_tiles(folder)
        time.sleep(0.002)
    if p.poll() is None:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
    return False, finished_tiles(folder)


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
    want = tree(ref)
    ntiles = json.load(open(report))["tileset"]["tiles"]
    print("uninterrupted: %d tiles" % ntiles)
    rng = random.Random(20261124)
    for run in range(runs):
        out = os.path.join(work, "run%d" % run)
        k = max(1, int(ntiles * rng.uniform(0.25, 0.85)))
        # The build runs at the lowest priority so that, on a loaded machine,
        # the watcher still sees its tiles arrive. Should the build still end
        # before the watcher looks, it is tried again from scratch with half
        # the tiles; a run is only counted once it was killed.
        for attempt in range(3):
            shutil.rmtree(out, ignore_errors=True)
            killed, seen = kill_after_tiles(["nice", "-n", "19"] + build + ["-o", out, "-q"],
                                            os.path.join(out, "tiles"), k)
            if killed:
                break
            print("run %d: the build finished before %d tiles were seen (%d); again with %d"
                  % (run, k, seen, max(1, k // 2)))
            k = max(1, k // 2)
        if not killed:
            print("FAIL: run %d: the build was never killed mid-way in 3 attempts" % run)
            return 1
        if os.path.exists(os.path.join(out, "tileset.json")):
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
        if ts["reused"] < seen:
            print("FAIL: run %d: %d tiles were finished at the kill, the re-run kept only %d"
                  % (run, seen, ts["reused"]))
            return 1
        print("run %d: killed with %d of %d tiles finished; re-run built %d, kept %d; identical"
              % (run, seen, ntiles, ts["built"], ts["reused"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
