#!/usr/bin/env python3
"""A tileset built on a Slurm cluster (scripts/slurm/submit: a prepare job,
an array of N tile jobs after it, a finalize job after them) equals the
tileset built locally in one process, byte for byte; a failed array task
re-submitted alone (`submit --tasks K`) completes it.

Starts munged, slurmctld and slurmd (scripts/slurm/cluster) with their state
in WORK_DIR/slurm and their own ports, and stops them by the pids recorded
at start, whatever happens. The chain is submitted with a wrapper around
decalprep that makes array task 1 fail once: sbatch --wait must then report
the failure, finalize must not run (no tileset.json), and the re-submitted
task plus finalize must complete the tileset. Prints the wall times of the
local build and of the Slurm chain (the scheduler's overhead).

Skips (exit 77), saying why, when not root or when the Slurm and munge
packages are missing (scripts/deps --cluster installs them).

Usage: slurm_array_test.py DECALPREP SOURCE_DIR WORK_DIR [N]
"""
import os
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tools"))
from tileset_util import tree  # noqa: E402


def main():
    tool, src, work = (os.path.abspath(a) for a in sys.argv[1:4])
    n = int(sys.argv[4]) if len(sys.argv) > 4 else 3
    if os.geteuid() != 0:
        print("SKIP: a private Slurm cluster needs root (munged runs as the munge user)")
        return 77
    missing = [t for t in ("munged", "mungekey", "slurmctld", "slurmd", "sbatch", "sinfo")
               if not shutil.which(t) and not os.path.exists("/usr/sbin/" + t)]
    if missing:
        print("SKIP: not installed:", " ".join(missing), "(scripts/deps --cluster installs them)")
        return 77

    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    cluster = os.path.join(src, "scripts", "slurm", "cluster")
    submit = os.path.join(src, "scripts", "slurm", "submit")
    env = dict(os.environ, DECALPREP_SLURM_DIR=os.path.join(work, "slurm"),
               DECALPREP_SLURM_PORT="16837")
    env["SLURM_CONF"] = os.path.join(work, "slurm", "slurm.conf")
    scene = os.path.join(src, "samples", "monaco", "scene.toml")
    opts = ["--tile-size", "500", "--threads", "1"]

    t0 = time.monotonic()
    local = os.path.join(work, "local")
    r = subprocess.run([tool, "build", scene, "-o", local, "-q"] + opts, capture_output=True,
                       text=True)
    local_s = time.monotonic() - t0
    if r.returncode != 0:
        print("FAIL: the local build failed:", r.stderr)
        return 1
    want = tree(local)

    # decalprep, but array task 1 fails once (while the marker exists).
    marker = os.path.join(work, "fail-task-1-once")
    open(marker, "w").close()
    wrapper = os.path.join(work, "decalprep-failing-once")
    with open(wrapper, "w") as f:
        f.write("#!/bin/sh\n"
                f'if [ "${{SLURM_ARRAY_TASK_ID:-}}" = 1 ] && rm "{marker}" 2>/dev/null; then\n'
                '  echo "array task 1: made to fail once" >&2; exit 1\n'
                "fi\n"
                f'exec "{tool}" "$@"\n')
    os.chmod(wrapper, 0o755)

    out = os.path.join(work, "cluster")
    failures = []
    started = subprocess.run([cluster, "start"], env=env, capture_output=True, text=True)
    try:
        if started.returncode != 0:
            print("FAIL: the cluster did not start:", started.stderr)
            return 1
        t0 = time.monotonic()
        first = subprocess.run([submit, "--wait", "--tool", wrapper, scene, out, str(n)] + opts,
                               env=env, capture_output=True, text=True, timeout=900)
        first_s = time.monotonic() - t0
        print("chain with task 1 failing: exit %d in %.1f s\n%s%s" %
              (first.returncode, first_s, first.stdout, first.stderr))
        if first.returncode == 0:
            failures.append("submit --wait returned 0 although array task 1 failed")
        if os.path.exists(marker):
            failures.append("array task 1 never ran")
        if os.path.exists(os.path.join(out, "tileset.json")):
            failures.append("finalize ran although a tile task had failed")
        t0 = time.monotonic()
        again = subprocess.run([submit, "--wait", "--tasks", "1", "--tool", wrapper, scene, out,
                                str(n)] + opts, env=env, capture_output=True, text=True,
                               timeout=900)
        again_s = time.monotonic() - t0
        print("task 1 re-submitted alone, then finalize: exit %d in %.1f s\n%s%s" %
              (again.returncode, again_s, again.stdout, again.stderr))
        if again.returncode != 0:
            failures.append("the re-submitted task or finalize failed")
    finally:
        stopped = subprocess.run([cluster, "stop"], env=env, capture_output=True, text=True)
        if stopped.returncode != 0:
            failures.append("stopping the cluster failed: " + stopped.stderr.strip())

    got = tree(out) if os.path.isdir(out) else {}
    got.pop("plan.json", None)
    if got != want:
        differ = sorted(k for k in set(want) | set(got) if want.get(k) != got.get(k))
        failures.append("the cluster's tileset differs from the local one in %d files: %s" %
                        (len(differ), differ[:5]))
    for f in failures:
        print("FAIL:", f)
    if not failures:
        print("Slurm chain (prepare, %d tile tasks, finalize; one task failed and re-submitted): "
              "%d files equal the local build; local %.1f s, chain %.1f s + re-submit %.1f s" %
              (n, len(want), local_s, first_s, again_s))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
