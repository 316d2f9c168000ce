#!/usr/bin/env python3
"""decalprep builds run as the tasks of a Slurm job array on a private
one-node cluster (scripts/slurm/cluster), give the local build's bytes, and
a failed array task re-submitted alone completes the set.

Starts munged, slurmctld and slurmd in WORK_DIR/slurm on their own ports,
submits `sbatch --wait --array=0-2` where task K builds the Monaco sample
with `--threads K+1` into WORK_DIR/out/taskK.decals, with task 1 made to fail
(exit 1 before it builds). sbatch must report the failure (non-zero), task 1
must have left no package, and tasks 0 and 2 must equal the local build byte
for byte. Then task 1 alone is submitted again (`--array=1`) and must equal it
too. The daemons are stopped by the pids recorded at start, whatever happens.

Skips (exit 77), saying why, when not root or when the Slurm and munge
packages are missing (scripts/deps installs them).

Usage: slurm_array_test.py DECALPREP SOURCE_DIR WORK_DIR
"""
import os
import shutil
import subprocess
import sys


def main():
    tool, src, work = sys.argv[1:4]
    if os.geteuid() != 0:
        print("SKIP: a private Slurm cluster needs root (munged runs as the munge user)")
        return 77
    missing = [t for t in ("munged", "mungekey", "slurmctld", "slurmd", "sbatch", "sinfo")
               if not shutil.which(t) and not os.path.exists("/usr/sbin/" + t)]
    if missing:
        print("SKIP: not installed:", " ".join(missing), "(scripts/deps installs them)")
        return 77

    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(os.path.join(work, "out"))
    cluster = os.path.join(src, "scripts", "slurm", "cluster")
    env = dict(os.environ, DECALPREP_SLURM_DIR=os.path.join(work, "slurm"),
               DECALPREP_SLURM_PORT="16837")
    env["SLURM_CONF"] = os.path.join(work, "slurm", "slurm.conf")
    scene = os.path.join(src, "samples", "monaco", "scene.toml")

    local = os.path.join(work, "local.decals")
    r = subprocess.run([tool, "build", scene, "-o", local, "-q"], capture_output=True, text=True)
    if r.returncode != 0:
        print("FAIL: the local build failed:", r.stderr)
        return 1
    want = open(local, "rb").read()

    job = os.path.join(work, "task.sh")
    with open(job, "w") as f:
        f.write("#!/bin/sh\n"
                "# One array task: task K builds with K+1 threads; FAIL_TASK fails one.\n"
                'K=$SLURM_ARRAY_TASK_ID\n'
                'if [ "$K" = "${FAIL_TASK:-none}" ]; then echo "task $K: made to fail"; exit 1; fi\n'
                f'exec "{tool}" build "{scene}" -o "{work}/out/task$K.decals" '
                '--threads $((K + 1)) -q\n')
    os.chmod(job, 0o755)

    def sbatch(array, fail_task):
        e = dict(env, FAIL_TASK=fail_task)
        return subprocess.run(["sbatch", "--wait", "--array=" + array, "--export=ALL",
                               "-o", os.path.join(work, "task-%A-%a.log"), job],
                              env=e, capture_output=True, text=True, timeout=600)

    failures = []
    started = subprocess.run([cluster, "start"], env=env, capture_output=True, text=True)
    try:
        if started.returncode != 0:
            print("FAIL: the cluster did not start:", started.stderr)
            return 1
        first = sbatch("0-2", "1")
        print("first submission:", first.stdout.strip(), "exit", first.returncode)
        if first.returncode == 0:
            failures.append("sbatch --wait returned 0 although task 1 failed")
        if os.path.exists(os.path.join(work, "out", "task1.decals")):
            failures.append("the failed task left a package")
        for k in (0, 2):
            p = os.path.join(work, "out", f"task{k}.decals")
            if not os.path.exists(p) or open(p, "rb").read() != want:
                failures.append(f"task {k}'s package differs from the local build (or is missing)")
        again = sbatch("1", "none")
        print("re-submitted task 1:", again.stdout.strip(), "exit", again.returncode)
        if again.returncode != 0:
            failures.append("the re-submitted task failed: " + again.stderr.strip())
        p = os.path.join(work, "out", "task1.decals")
        if not os.path.exists(p) or open(p, "rb").read() != want:
            failures.append("the re-submitted task's package differs from the local build")
    finally:
        stopped = subprocess.run([cluster, "stop"], env=env, capture_output=True, text=True)
        if stopped.returncode != 0:
            failures.append("stopping the cluster failed: " + stopped.stderr.strip())

    for f in failures:
        print("FAIL:", f)
    if not failures:
        print(f"3 array tasks + 1 re-submitted: every package equals the local build "
              f"({len(want)} bytes)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
