#!/usr/bin/env python3
"""A tileset built as separate steps (`--plan N`, then `--step prepare`,
`--step tiles K/N`, `--step finalize`, each in its own process, run from the
command lines plan.json gives) equals the tileset built in one process, byte
for byte; every step run twice leaves the same bytes (the tileset's, and the work
folder's plan and entries); finalize with a tile
job missing exits non-zero and names the missing tiles; --step without
--tile-size is a usage error.

Usage: tileset_steps_test.py DECALPREP SOURCE_DIR WORK_DIR [SHARED]
SHARED: the folder of tileset_fixture.sh, whose tiles/ is the one-process
build (made here when it is missing).
"""
import json
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tileset_util import StepRunner, plan_steps, tree  # noqa: E402

N = 3


def main():
    tool, src, work = sys.argv[1:4]
    shared = sys.argv[4] if len(sys.argv) > 4 else ""
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    scene = os.path.join(src, "samples", "monaco", "scene.toml")
    failures = []

    if shared and os.path.exists(os.path.join(shared, "done")):
        ref = os.path.join(shared, "tiles")
    else:
        ref = os.path.join(work, "ref")
        r = subprocess.run([tool, "build", scene, "--tile-size", "500", "--jobs", "2", "-o", ref,
                            "-q"], capture_output=True, text=True)
        if r.returncode != 0:
            print("FAIL: the one-process build failed:", r.stderr)
            return 1
    want = tree(ref, skip=("plan.json",))

    out = os.path.join(work, "stepped")
    plan = plan_steps([tool, "build", scene, "--tile-size", "500"], out, N, work)
    steps = {s["step"]: s for s in plan["steps"]}
    if [s["step"] for s in plan["steps"]] != ["prepare", "tiles", "finalize"]:
        failures.append("plan.json steps are %s" % [s["step"] for s in plan["steps"]])
    if steps["tiles"]["jobs"] != N:
        failures.append("plan.json says %s tile jobs, not %d" % (steps["tiles"]["jobs"], N))

    runner = StepRunner(plan, out, failures)
    step, run_twice = runner.step, runner.run_twice

    # Finalize with tile job N-1 not run: refused, naming the missing tiles.
    early = runner.run_all_but_last_tile_job(N)
    missing = re.findall(r"x-?\d+_y-?\d+", early.stderr)
    count = re.search(r"(\d+) of (\d+) tiles have not been built", early.stderr)
    print("finalize before the last tile job: exit %d, %s" % (early.returncode,
                                                               early.stderr.strip()[:300]))
    if early.returncode == 0:
        failures.append("finalize with a tile job missing exited 0")
    if not missing or not count:
        failures.append("finalize did not name the missing tiles: " + early.stderr.strip())
    elif int(count.group(1)) < len(missing) or (int(count.group(1)) <= 20 and
                                                 int(count.group(1)) != len(missing)):
        failures.append("finalize named %d tiles but counted %s" % (len(missing), count.group(1)))
    if any(os.path.exists(os.path.join(out, "tiles", m + ".decals")) for m in missing):
        failures.append("finalize named a tile that was built")
    if os.path.exists(os.path.join(out, "tileset.json")):
        failures.append("the refused finalize wrote tileset.json")

    run_twice("tiles", N - 1)
    if missing and not any(os.path.exists(os.path.join(out, "tiles", m + ".decals"))
                           for m in missing):
        failures.append("the last tile job built none of the tiles finalize named")
    run_twice("finalize")
    got = tree(out, skip=("plan.json",))
    if got != want:
        only_ref = sorted(set(want) - set(got))[:5]
        only_got = sorted(set(got) - set(want))[:5]
        differ = sorted(k for k in set(want) & set(got) if want[k] != got[k])[:5]
        failures.append("stepped tileset differs: missing %s, extra %s, different %s" %
                        (only_ref, only_got, differ))

    bad = subprocess.run([tool, "build", scene, "-o", os.path.join(work, "x"), "--step",
                          "prepare", "-q"], capture_output=True, text=True)
    if bad.returncode != 2 or "--tile-size" not in bad.stderr:
        failures.append("--step without --tile-size: exit %d, %s" % (bad.returncode,
                                                                     bad.stderr.strip()))

    for f in failures:
        print("FAIL:", f)
    if not failures:
        print("prepare, %d tile jobs and finalize, each run twice: %d files equal the one-process "
              "build" % (N, len(want)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
