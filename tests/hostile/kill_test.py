#!/usr/bin/env python3
"""Atomic output under SIGKILL (ARCHITECTURE.md "Guarantees" 6).

Builds a scene once to learn how long a build takes, then N times runs
`timeout -s KILL T decalprep build ... -o TARGET` with T drawn uniformly over
the build's duration. After each run TARGET must be exactly one of:
  absent (no previous file), the previous file byte for byte, or a complete
  package that `decalprep verify` accepts.
Odd runs start with a previous package at TARGET, even runs with none.

Usage: kill_test.py DECALPREP DATA_DIR SOURCE_DIR WORK_DIR [RUNS]
The scene is the Monaco sample's scene.toml pointed at Liechtenstein (no DEM)
when DATA_DIR has it, else the Monaco sample itself. Exit 0 on success,
1 on a violation, 77 (ctest SKIP_RETURN_CODE) when no data exists.
"""
import hashlib
import os
import random
import re
import shutil
import subprocess
import sys
import time


def sha(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def main():
    tool, data, src, work = sys.argv[1:5]
    runs = int(sys.argv[5]) if len(sys.argv) > 5 else 20
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    lie = os.path.join(data, "liechtenstein", "liechtenstein-2013-08-03.osm.pbf")
    monaco_scene = os.path.join(src, "samples", "monaco", "scene.toml")
    if not os.path.exists(monaco_scene):
        print("SKIP: no samples/monaco/scene.toml")
        return 77
    if os.path.exists(lie):
        text = open(monaco_scene, encoding="utf-8").read()
        text = re.sub(r'(?m)^source\s*=.*$', 'source = "%s"' % lie, text)
        text = re.sub(r'(?m)^dem\s*=.*$', '', text)
        # Monaco's extent would clip all of Liechtenstein away (a build
        # that keeps nothing now stops with exit 9 instead of writing it).
        text = re.sub(r'(?m)^extent(_crs)?\s*=.*$', '', text)
        scene = os.path.join(work, "liechtenstein.toml")
        open(scene, "w", encoding="utf-8").write(text)
        what = "Liechtenstein"
    else:
        scene = monaco_scene
        what = "Monaco (no Liechtenstein data in %s)" % data
    target = os.path.join(work, "out.decals")
    t0 = time.monotonic()
    full = subprocess.run([tool, "build", scene, "-o", target, "-q"], capture_output=True, text=True)
    duration = time.monotonic() - t0
    if full.returncode != 0:
        print("FAIL: the uninterrupted build failed:", full.stderr)
        return 1
    previous = os.path.join(work, "previous.decals")
    shutil.move(target, previous)
    prev_hash = sha(previous)
    print(f"{what}: a full build takes {duration:.2f} s")

    rng = random.Random(int(os.environ.get("KILL_TEST_SEED", "8")))
    seen = {"absent": 0, "previous": 0, "complete": 0}
    failures = 0
    for i in range(runs):
        if os.path.exists(target):
            os.remove(target)
        with_prev = i % 2 == 1
        if with_prev:
            shutil.copyfile(previous, target)
        after = rng.uniform(0.02, duration * 1.05)
        r = subprocess.run(["timeout", "-s", "KILL", f"{after:.3f}", tool, "build", scene, "-o", target, "-q"],
                           capture_output=True, text=True)
        if not os.path.exists(target):
            state = "absent"
            ok = not with_prev  # a previous file must never vanish
        elif with_prev and sha(target) == prev_hash:
            state = "previous"
            ok = True
        else:
            v = subprocess.run([tool, "verify", target], capture_output=True, text=True)
            state = "complete"
            ok = v.returncode == 0
            if not ok:
                print(f"  run {i}: verify rejected the target: {v.stdout}{v.stderr}")
        seen[state] += 1
        print(f"  run {i:2d}: kill after {after:6.3f} s (rc {r.returncode}, previous file: {with_prev}): "
              f"{state}{'' if ok else '  <-- VIOLATION'}")
        failures += not ok
    leftovers = [f for f in os.listdir(work) if f not in ("out.decals", "previous.decals", os.path.basename(scene))]
    print(f"outcomes: {seen}; files left beside the target by killed builds: {leftovers}")
    if failures:
        print(f"FAIL: {failures} of {runs} runs left a target that is not absent/previous/complete")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
