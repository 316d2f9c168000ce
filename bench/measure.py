"""What the scripted benches beside this file share: running and measuring a
command, their --build-dir and --out options, and writing their CSV."""
import csv
import os
import subprocess
import time


def measured(cmd, env=None):
    """Runs `cmd` (stdout discarded) and returns (wall seconds, CPU seconds,
    peak resident MiB) of the child, from the kernel (wait4's rusage).
    Raises RuntimeError with the end of its stderr when it fails."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    err = p.stderr.read()
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError("%s failed: %s" % (" ".join(cmd), err.decode()[-2000:]))
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def add_build_and_out(ap):
    """The options the scripted benches share: --build-dir (the build whose
    decalprep runs) and --out (where CSV and charts go)."""
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))


def decalprep_of(a):
    """The decalprep binary of --build-dir; makes --out."""
    os.makedirs(a.out, exist_ok=True)
    return os.path.join(a.build_dir, "tools", "decalprep", "decalprep")


def write_rows(path, rows):
    """Writes `rows` (dicts with the same keys) as CSV with a header."""
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)


def vertex_counts(text):
    """--vertices "1e6,1e7" as integers."""
    return [int(float(s)) for s in text.split(",")]
