#!/usr/bin/env python3
"""bench/slurm_overhead.py — a tileset built on Slurm against the same build run locally.

  bench/slurm_overhead.py [--vertices 1e6[,1e7]] [--tasks 2,4,8] [--tile-size 2000]
                          [--jobs 2] [--repeat 1] [--build-dir build/release]
                          [--out bench/report] [--slurm-dir /tmp/slurmbench-slurm]
                          [--slurm-port 16917] [--append]
  bench/slurm_overhead.py --from-csv [--out bench/report]

For each size: synthetic polygons and lines (bench/gen_synthetic.py "mix", as
bench/tileset_scale.py makes them) in FlatGeobuf, then, alternately in the
same run, for each N of --tasks:
  (a) the local build, `decalprep build SCENE -o DIR --tile-size S --jobs J`
      (wall by this script's clock, CPU and peak RSS from wait4), and
  (b) the same build through Slurm, `scripts/slurm/submit --wait` with N tile
      jobs (prepare, array 0..N-1 after it, finalize after that; every step
      `--threads 1`, one CPU each, as docs/cluster.md advises), on a private
      one-node cluster started here by `scripts/slurm/cluster start` (state in
      --slurm-dir, ports --slurm-port and the next one, so the cluster test's
      defaults are left alone) and stopped by `scripts/slurm/cluster stop`
      whatever happens.
The Slurm wall time runs from the submit to the end of the finalize step.
Every Slurm tileset is compared with the local one, every file's bytes
(tileset.json, manifest.json, every tile); a difference stops the run with
exit 1, naming the files.

The cluster has no accounting (scripts/slurm/cluster: no sacct), so each step
runs through a wrapper (`--tool`) that records its start and end (wall clock,
ns) and /usr/bin/time's user, system and maximum RSS: per-step wall, CPU and
peak RSS, and the scheduler's idle gaps between dependent jobs (submit to
prepare start; prepare end to the first tile job's start; a tile job's end to
the start of the next one on its freed CPU; the last tile job's end to
finalize's start; each includes the job's launch by slurmd).

Writes slurm_overhead.csv (one row per build; the 1-minute load average
before and after each), slurm_overhead_jobs.csv (one row per Slurm step) and
slurm_overhead.png (gnuplot: wall time by N, local against Slurm), and prints
a table with a per-size summary (CPU a tile and an input vertex, peak RSS
of a tile job, the mean gaps). --append keeps the rows already in --out's
CSVs (a second size measured later); --from-csv builds nothing and prints
the table and redraws the chart from them. On a shared machine with Linux's
autogroup scheduling each Slurm job is a session of its own and gets its
own CPU share against other users, the local build one share: compare the
CPU columns, or measure on an idle machine. Standard library only; needs
root, the Slurm and munge packages (scripts/deps --cluster), ogr2ogr,
/usr/bin/time and gnuplot.
"""
import argparse
import csv
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import gen_synthetic  # beside this script
from measure import measured  # beside this script

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLUSTER = os.path.join(ROOT, "scripts", "slurm", "cluster")
SUBMIT = os.path.join(ROOT, "scripts", "slurm", "submit")


def load1():
    return round(os.getloadavg()[0], 2)


def tree(root):
    out = {}
    for d, _, files in os.walk(root):
        for f in files:
            p = os.path.join(d, f)
            h = hashlib.sha256()
            with open(p, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    h.update(block)
            out[os.path.relpath(p, root)] = h.hexdigest()
    return out


def write_wrapper(path, tool, stats):
    # One record per step: its Slurm ids, its arguments, the wall clock at start
    # and end, and /usr/bin/time's elapsed, user, system and max RSS (KiB).
    with open(path, "w") as f:
        f.write("#!/bin/sh\n"
                'f="%s/job-${SLURM_JOB_ID:-none}.txt"\n'
                'echo "start $(date +%%s.%%N)" >"$f"\n'
                'echo "array ${SLURM_ARRAY_JOB_ID:-} ${SLURM_ARRAY_TASK_ID:-}" >>"$f"\n'
                'echo "args $*" >>"$f"\n'
                '/usr/bin/time -a -o "$f" -f "time %%e %%U %%S %%M" "%s" "$@"\n'
                "rc=$?\n"
                'echo "end $(date +%%s.%%N)" >>"$f"\n'
                'echo "rc $rc" >>"$f"\n'
                "exit $rc\n" % (stats, tool))
    os.chmod(path, 0o755)


def read_steps(stats):
    steps = []
    for name in sorted(os.listdir(stats)):
        d = {"job": name[4:-4]}
        with open(os.path.join(stats, name)) as f:
            for line in f:
                k, _, v = line.rstrip("\n").partition(" ")
                if k in ("start", "end"):
                    d[k] = float(v)
                elif k == "args":
                    a = v.split()
                    i = a.index("--step")
                    d["step"] = a[i + 1]
                    d["task"] = int(a[i + 2].split("/")[0]) if a[i + 1] == "tiles" else ""
                elif k == "time":
                    e, u, s, m = v.split()
                    d["wall_s"], d["cpu_s"], d["rss_mib"] = float(e), float(u) + float(s), int(m) / 1024.0
                elif k == "rc":
                    d["rc"] = int(v)
        steps.append(d)
    return steps


def slurm_build(a, env, wrapper, stats, scene, out, n):
    shutil.rmtree(stats, ignore_errors=True)
    os.makedirs(stats)
    l0 = load1()
    t0 = time.time()
    r = subprocess.run([SUBMIT, "--wait", "--tool", wrapper, scene, out, str(n), "--tile-size",
                        a.tile_size, "--threads", "1"], env=env, capture_output=True, text=True)
    returned = time.time() - t0
    if r.returncode != 0:
        raise RuntimeError("submit failed (%d): %s%s" % (r.returncode, r.stdout, r.stderr))
    steps = read_steps(stats)
    bad = [s for s in steps if s.get("rc") != 0 or "wall_s" not in s]
    by = {k: [s for s in steps if s.get("step") == k] for k in ("prepare", "tiles", "finalize")}
    if bad or len(by["prepare"]) != 1 or len(by["finalize"]) != 1 or len(by["tiles"]) != n:
        raise RuntimeError("unexpected step records in %s: %s" % (stats, steps))
    for s in steps:
        s["start_rel_s"] = round(s["start"] - t0, 3)
        s["end_rel_s"] = round(s["end"] - t0, 3)
    prep, fin, tiles = by["prepare"][0], by["finalize"][0], sorted(by["tiles"], key=lambda s: s["start"])
    # A tile job beyond the first wave starts on a CPU that the tile job that
    # ended last before it freed: that wait is the scheduler's and slurmd's.
    refill = []
    ends = sorted(s["end"] for s in tiles)
    for s in tiles:
        before = [e for e in ends if e <= s["start"]]
        if before:
            refill.append(s["start"] - before[-1])
    row = {
        "wall_s": round(fin["end"] - t0, 3),
        "submit_wait_return_s": round(returned, 3),
        "cpu_s": round(sum(s["cpu_s"] for s in steps), 3),
        "peak_rss_mib": round(max(s["rss_mib"] for s in steps), 1),
        "prepare_wall_s": prep["wall_s"], "prepare_cpu_s": round(prep["cpu_s"], 3),
        "prepare_rss_mib": round(prep["rss_mib"], 1),
        "tile_wall_min_s": min(s["wall_s"] for s in tiles), "tile_wall_max_s": max(s["wall_s"] for s in tiles),
        "tile_cpu_min_s": round(min(s["cpu_s"] for s in tiles), 3),
        "tile_cpu_max_s": round(max(s["cpu_s"] for s in tiles), 3),
        "tile_cpu_sum_s": round(sum(s["cpu_s"] for s in tiles), 3),
        "tile_rss_min_mib": round(min(s["rss_mib"] for s in tiles), 1),
        "tile_rss_max_mib": round(max(s["rss_mib"] for s in tiles), 1),
        "finalize_wall_s": fin["wall_s"], "finalize_cpu_s": round(fin["cpu_s"], 3),
        "finalize_rss_mib": round(fin["rss_mib"], 1),
        "gap_submit_to_prepare_s": round(prep["start"] - t0, 3),
        "gap_prepare_to_tiles_s": round(tiles[0]["start"] - prep["end"], 3),
        "gap_refill_mean_s": round(sum(refill) / len(refill), 3) if refill else "",
        "gap_refill_max_s": round(max(refill), 3) if refill else "",
        "gap_tiles_to_finalize_s": round(fin["start"] - max(ends), 3),
        "loadavg_1min_before": l0, "loadavg_1min_after": load1(),
    }
    return row, steps


def num(x):
    for t in (int, float):
        try:
            return t(x)
        except ValueError:
            pass
    return x


def load_csv(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return [{k: num(v) for k, v in r.items()} for r in csv.DictReader(f)]


def save(out, rows, jobs):
    """Writes both CSVs whole (after every pair, so that a run cut short keeps
    what it measured)."""
    paths = []
    for name, rs in (("slurm_overhead.csv", rows), ("slurm_overhead_jobs.csv", jobs)):
        fields = []
        for r in rs:
            fields += [k for k in r if k not in fields]
        path = os.path.join(out, name)
        with open(path + ".tmp", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields, restval="")
            w.writeheader()
            w.writerows(rs)
        os.replace(path + ".tmp", path)
        paths.append(path)
    return paths


def fmt_s(x):
    return "" if x == "" else ("%.2f" % x)


def measure(a, rows, jobs):
    """The builds, local and Slurm, alternately; appends to rows and jobs.
    Returns 1 when a Slurm tileset differs from the local one."""
    tool = os.path.abspath(os.path.join(a.build_dir, "tools", "decalprep", "decalprep"))
    if not os.path.exists(tool):
        sys.exit("slurm_overhead: %s is missing (build the release preset)" % tool)
    if os.geteuid() != 0:
        sys.exit("slurm_overhead: a private Slurm cluster needs root (scripts/slurm/cluster)")
    for t in ("ogr2ogr", "sbatch", "squeue", "scontrol", "/usr/bin/time"):
        if not shutil.which(t):
            sys.exit("slurm_overhead: %s not found (scripts/deps --cluster installs Slurm)" % t)
    tasks = [int(s) for s in a.tasks.split(",")]
    os.makedirs(a.out, exist_ok=True)
    work = tempfile.mkdtemp(prefix="slurm_overhead_")
    env = dict(os.environ, DECALPREP_SLURM_DIR=a.slurm_dir, DECALPREP_SLURM_PORT=a.slurm_port,
               SLURM_CONF=os.path.join(a.slurm_dir, "slurm.conf"))
    wrapper = os.path.join(work, "decalprep-timed")
    stats = os.path.join(work, "steps")
    write_wrapper(wrapper, tool, stats)
    started = False
    try:
        subprocess.run([CLUSTER, "start"], env=env, check=True, stdout=subprocess.DEVNULL)
        started = True
        cpus = subprocess.run(["sinfo", "-h", "-N", "-o", "%c"], env=env, capture_output=True,
                              text=True).stdout.split()
        print("private Slurm cluster: one node, %s CPUs, state in %s, port %s" %
              (cpus[0] if cpus else "?", a.slurm_dir, a.slurm_port), flush=True)
        for v in [int(float(s)) for s in a.vertices.split(",")]:
            scene, fgb = gen_synthetic.mix_scene(work, v, "mix%d" % v)
            for rep in range(a.repeat):
                for n in tasks:
                    # Local, then Slurm, right after each other: the pair shares the load.
                    local = os.path.join(work, "local%d" % v)
                    shutil.rmtree(local, ignore_errors=True)
                    l0 = load1()
                    wall, cpu, rss = measured([tool, "build", scene, "-o", local, "--tile-size", a.tile_size,
                                               "--jobs", a.jobs, "-q"])
                    want = tree(local)
                    ntiles = sum(1 for p in want if p.endswith(".decals"))
                    lrow = {"vertices": v, "mode": "local", "n": n, "rep": rep, "tiles": ntiles,
                            "local_jobs": a.jobs, "wall_s": round(wall, 3), "cpu_s": round(cpu, 3), "peak_rss_mib": round(rss, 1),
                            "loadavg_1min_before": l0, "loadavg_1min_after": load1()}
                    rows.append(lrow)
                    print("%d vertices, local --jobs %s (before N=%d): %.2f s wall, %.2f s CPU, %.1f MiB, "
                          "%d tiles, load %.2f -> %.2f" % (v, a.jobs, n, wall, cpu, rss, ntiles, l0,
                                                            lrow["loadavg_1min_after"]), flush=True)
                    out = os.path.join(work, "slurm%d_%d" % (v, n))
                    shutil.rmtree(out, ignore_errors=True)
                    shutil.rmtree(out + ".slurm-logs", ignore_errors=True)
                    srow, steps = slurm_build(a, env, wrapper, stats, scene, out, n)
                    got = tree(out)
                    if got != want:
                        diff = sorted(k for k in set(got) | set(want) if got.get(k) != want.get(k))
                        print("FAIL: the Slurm tileset (N=%d) differs from the local one in %d files: %s" %
                              (n, len(diff), ", ".join(diff[:20])), file=sys.stderr)
                        return 1
                    srow.update({"vertices": v, "mode": "slurm", "n": n, "rep": rep, "tiles": ntiles,
                                 "identical": "yes", "local_wall_s": lrow["wall_s"],
                                 "overhead_s": round(srow["wall_s"] - lrow["wall_s"], 3),
                                 "ratio": round(srow["wall_s"] / lrow["wall_s"], 3),
                                 "tile_cpu_s_per_tile": round(srow["tile_cpu_sum_s"] / ntiles, 4),
                                 "tile_cpu_us_per_vertex": round(srow["tile_cpu_sum_s"] / v * 1e6, 3),
                                 "prepare_cpu_us_per_vertex": round(srow["prepare_cpu_s"] / v * 1e6, 3)})
                    rows.append(srow)
                    for s in steps:
                        jobs.append({"vertices": v, "n": n, "rep": rep, "job": s["job"], "step": s["step"],
                                     "task": s["task"], "start_rel_s": s["start_rel_s"],
                                     "end_rel_s": s["end_rel_s"], "wall_s": s["wall_s"],
                                     "cpu_s": round(s["cpu_s"], 3), "rss_mib": round(s["rss_mib"], 1)})
                    print("%d vertices, Slurm N=%d: %.2f s wall (submit --wait returned at %.2f s), "
                          "overhead %+.2f s (x%.2f), identical; prepare %.2f s, tile jobs %.2f-%.2f s wall "
                          "%.2f-%.2f s CPU %.0f-%.0f MiB, finalize %.2f s; gaps: submit->prepare %.2f s, "
                          "prepare->tiles %.2f s, refill %s s, tiles->finalize %.2f s; load %.2f -> %.2f" %
                          (v, n, srow["wall_s"], srow["submit_wait_return_s"], srow["overhead_s"], srow["ratio"],
                           srow["prepare_wall_s"], srow["tile_wall_min_s"], srow["tile_wall_max_s"],
                           srow["tile_cpu_min_s"], srow["tile_cpu_max_s"], srow["tile_rss_min_mib"],
                           srow["tile_rss_max_mib"], srow["finalize_wall_s"], srow["gap_submit_to_prepare_s"],
                           srow["gap_prepare_to_tiles_s"], fmt_s(srow["gap_refill_mean_s"]),
                           srow["gap_tiles_to_finalize_s"], srow["loadavg_1min_before"],
                           srow["loadavg_1min_after"]), flush=True)
                    shutil.rmtree(out, ignore_errors=True)
                    shutil.rmtree(out + ".slurm-logs", ignore_errors=True)
                    save(a.out, rows, jobs)
            for p in (fgb, scene):
                os.remove(p)
            shutil.rmtree(os.path.join(work, "local%d" % v), ignore_errors=True)
    finally:
        if started or os.path.exists(os.path.join(a.slurm_dir, "slurmctld.pid")):
            subprocess.run([CLUSTER, "stop"], env=env, check=False)
        shutil.rmtree(work, ignore_errors=True)
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vertices", default="1e6")
    ap.add_argument("--tasks", default="2,4,8", help="the N tile jobs of each Slurm build")
    ap.add_argument("--tile-size", default="2000")
    ap.add_argument("--jobs", default="2", help="--jobs of the local build")
    ap.add_argument("--repeat", type=int, default=1, help="local/Slurm pairs per N")
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "report"))
    ap.add_argument("--slurm-dir", default="/tmp/slurmbench-slurm")
    ap.add_argument("--slurm-port", default="16917")
    ap.add_argument("--append", action="store_true",
                    help="keep the rows of an earlier run's CSVs in --out and add this run's")
    ap.add_argument("--from-csv", action="store_true",
                    help="build nothing: print the table and redraw the chart from --out's CSVs")
    a = ap.parse_args()
    rows, jobs = [], []
    if a.append or a.from_csv:
        rows = load_csv(os.path.join(a.out, "slurm_overhead.csv"))
        jobs = load_csv(os.path.join(a.out, "slurm_overhead_jobs.csv"))
    if not a.from_csv and measure(a, rows, jobs):
        return 1
    if not rows:
        return 1
    if a.from_csv:
        csv_path, jobs_path = (os.path.join(a.out, n) for n in ("slurm_overhead.csv", "slurm_overhead_jobs.csv"))
    else:
        csv_path, jobs_path = save(a.out, rows, jobs)
    a.jobs = next((r["local_jobs"] for r in rows if r.get("local_jobs") not in ("", None)), a.jobs)
    srows = [r for r in rows if r["mode"] == "slurm"]
    print()
    # Each Slurm row's local build is the row just before it.
    pair = {id(r): rows[i - 1] for i, r in enumerate(rows) if r["mode"] == "slurm" and i > 0}
    print("| vertices | N | local wall | Slurm wall | Slurm − local | ratio | CPU local / Slurm | prepare | "
          "tile job wall | tile job CPU | tile job peak RSS | finalize | gaps: submit→prepare, prepare→tiles, "
          "refill, tiles→finalize | CPU per tile | tile CPU per vertex | load (1 min) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in srows:
        lr = pair[id(r)]
        loads = [lr["loadavg_1min_before"], lr["loadavg_1min_after"], r["loadavg_1min_after"]]
        print("| %d | %d | %.1f s | %.1f s | %+.1f s | %.2f× | %.1f / %.1f s | %.2f s | %.1f–%.1f s | "
              "%.1f–%.1f s | %.0f–%.0f MiB | %.2f s | %.2f, %.2f, %s, %.2f s | %.3f s | %.1f µs | %.1f–%.1f |" %
              (r["vertices"], r["n"], r["local_wall_s"], r["wall_s"], r["overhead_s"], r["ratio"], lr["cpu_s"],
               r["cpu_s"], r["prepare_wall_s"], r["tile_wall_min_s"], r["tile_wall_max_s"], r["tile_cpu_min_s"],
               r["tile_cpu_max_s"], r["tile_rss_min_mib"], r["tile_rss_max_mib"], r["finalize_wall_s"],
               r["gap_submit_to_prepare_s"], r["gap_prepare_to_tiles_s"],
               "—" if r["gap_refill_mean_s"] == "" else "%.2f" % r["gap_refill_mean_s"],
               r["gap_tiles_to_finalize_s"], r["tile_cpu_s_per_tile"], r["tile_cpu_us_per_vertex"],
               min(loads), max(loads)))
    print()
    for v in sorted({r["vertices"] for r in srows}):
        rs = [r for r in srows if r["vertices"] == v]

        def mean(k):
            xs = [r[k] for r in rs if r[k] != ""]
            return sum(xs) / len(xs) if xs else float("nan")
        print("%d vertices, %d Slurm builds: tile jobs %.3f s CPU a tile (%d tiles), %.1f µs CPU an input "
              "vertex, peak RSS of a tile job at most %.0f MiB; prepare %.2f µs CPU a vertex, at most %.0f MiB; "
              "scheduler gaps (mean): submit→prepare %.2f s, prepare→tiles %.2f s, CPU refill %.2f s, "
              "tiles→finalize %.2f s; overhead %+.2f s (mean ratio %.2f×)" %
              (v, len(rs), mean("tile_cpu_s_per_tile"), rs[0]["tiles"], mean("tile_cpu_us_per_vertex"),
               max(r["tile_rss_max_mib"] for r in rs), mean("prepare_cpu_us_per_vertex"),
               max(r["prepare_rss_mib"] for r in rs), mean("gap_submit_to_prepare_s"),
               mean("gap_prepare_to_tiles_s"), mean("gap_refill_mean_s"), mean("gap_tiles_to_finalize_s"),
               mean("overhead_s"), mean("ratio")))
    if shutil.which("gnuplot"):
        # One data block per size: N, local wall, Slurm wall (mean over --repeat).
        blocks, plots = [], []
        ns = sorted({r["n"] for r in srows})
        for i, v in enumerate(sorted({r["vertices"] for r in srows})):
            lines = []
            for n in ns:
                rs = [r for r in srows if r["vertices"] == v and r["n"] == n]
                if rs:
                    lines.append("%d %.3f %.3f" % (n, sum(r["local_wall_s"] for r in rs) / len(rs),
                                                   sum(r["wall_s"] for r in rs) / len(rs)))
            blocks.append("$d%d << EOD\n%s\nEOD" % (i, "\n".join(lines)))
            e = len(str(v)) - 1
            exp = "10^%d" % e if v == 10 ** e else str(v)
            plots.append("$d%d using 1:2 with linespoints pt 7 dt 2 lc %d title '%s vertices, local --jobs %s "
                         "(run just before)'" % (i, i + 1, exp, a.jobs))
            plots.append("$d%d using 1:3 with linespoints pt 5 lc %d title '%s vertices, Slurm, N tile jobs'" %
                         (i, i + 1, exp))
        png = os.path.join(a.out, "slurm_overhead.png")
        script = ("set terminal pngcairo size 800,560 noenhanced\nset output '%s'\n%s\n"
                  "set logscale x 2\nset logscale y\nset grid\nset key below\n"
                  "set xtics (%s)\nset xrange [%g:%g]\n"
                  "set xlabel 'N tile jobs (Slurm array; the node has 2 CPUs)'\n"
                  "set ylabel 'wall time to the finished tileset (s)'\n"
                  "set title 'Tileset build, %s m tiles: Slurm (one node) against local (mean of the runs)'\n"
                  "plot %s\n" % (png, "\n".join(blocks), ", ".join(str(n) for n in ns),
                                 min(ns) / 1.3, max(ns) * 1.3, a.tile_size, ", \\\n  ".join(plots)))
        subprocess.run(["gnuplot"], input=script.encode(), check=False)
        print("wrote", png)
    print("wrote", csv_path, "and", jobs_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
