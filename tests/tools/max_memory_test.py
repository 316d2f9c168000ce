#!/usr/bin/env python3
"""`decalprep build --max-memory`: the build stops early with exit
code 6 and writes nothing when the estimate exceeds the limit; a generous
limit builds; and the estimate of the peak for a mid-size generated input is
at least the peak RSS measured for the child process (getrusage via wait4)
and at most 3x it. A fixed fine grid, whose cells the vertex counts do not
foresee, is stopped by the check after the grid choice. Batch mode applies
the limit to every scene. A tileset build checks each tile as it is cut:
its estimate (the tile's counts times --jobs) bounds the measured peak, a
limit between one and two tiles at once stops the build with two jobs and
lets it through with one, which then stays under the limit and gives the
same tileset; a --step tiles run is checked the same way.

  max_memory_test.py DECALPREP SOURCE_DIR WORK_DIR
"""
import json
import os
import shutil
import subprocess
import sys

tool, src, work = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        failures.append(what)


def build(args):
    """Runs decalprep in a child; returns (exit code, peak RSS MiB, stderr)."""
    err = open(os.path.join(work, "stderr.txt"), "w+")
    p = subprocess.Popen([tool] + args, stdout=subprocess.DEVNULL, stderr=err)
    _, status, ru = os.wait4(p.pid, 0)
    err.seek(0)
    return os.waitstatus_to_exitcode(status), ru.ru_maxrss / 1024.0, err.read()


# A mid-size input: 3e5 polygon vertices (~1700 star polygons with holes), in
# a projected CRS, through the real GDAL path.
geojsonl = os.path.join(work, "polygons.geojsonl")
source = os.path.join(work, "polygons.fgb")
subprocess.run([sys.executable, os.path.join(src, "bench/gen_synthetic.py"), "polygons", "3e5", geojsonl], check=True)
subprocess.run(["ogr2ogr", "-f", "FlatGeobuf", source, geojsonl, "-a_srs", "EPSG:32632"], check=True)
common = [source, "--kind", "polygon", "-q", "--threads", "2"]

# 1. A limit below the base (GDAL, PROJ, GEOS loaded): stops before reading.
pkg = os.path.join(work, "tiny.decals")
code, _, err = build(["build"] + common + ["-o", pkg, "--max-memory", "16M"])
check(code == 6, f"--max-memory 16M exits 6 (got {code})")
check(not os.path.exists(pkg), "--max-memory 16M writes no package")
check("estimate before read" in err and "over --max-memory 16.0 MiB" in err and "Raise --max-memory" in err,
      "the error gives the estimate, the limit and what to do: " + err.strip())

# 2. A limit the source sizes pass but the vertex count does not: stops
#    after read, before the build stage.
pkg = os.path.join(work, "small.decals")
report = os.path.join(work, "small.json")
code, _, err = build(["build"] + common + ["-o", pkg, "--report", report, "--max-memory", "100M"])
check(code == 6, f"--max-memory 100M exits 6 (got {code})")
check(not os.path.exists(pkg), "--max-memory 100M writes no package")
check("estimate after read" in err and "polygon vertices" in err, "it stops after read: " + err.strip())
check(json.load(open(report)).get("exit_code") == 6, "the report of the failed build says exit_code 6")

# 3. A generous limit builds, and the estimates bound the measured peak.
pkg = os.path.join(work, "ok.decals")
report = os.path.join(work, "ok.json")
code, peak, err = build(["build"] + common + ["-o", pkg, "--report", report, "--max-memory", "4G"])
check(code == 0 and os.path.exists(pkg), f"--max-memory 4G builds (exit {code}) {err.strip()}")
if code == 0:
    est = json.load(open(report))["memory_estimate"]
    for point in ("after read", "after clean", "after grid"):
        e = est[point]["mib"]
        print(f"     estimate {point}: {e:.1f} MiB, measured peak RSS {peak:.1f} MiB, ratio {e / peak:.2f}")
        check(peak <= e <= 3 * peak, f"estimate {point} within [1, 3] x the measured peak")

# 4. A fixed fine grid: 2000x2000 cells on the same input peak at about
#    270-300 MiB, more than the vertex counts say (the estimates after read and
#    after clean assume the adaptive grid, ~132 MiB). The check after the
#    grid choice sees the cells coming and stops before they are made.
pkg = os.path.join(work, "fine.decals")
report = os.path.join(work, "fine.json")
fine = common + ["-o", pkg, "--report", report, "--grid", "2000x2000"]
code, peak, err = build(["build"] + fine)
check(code == 0 and peak > 200,
      f"without a limit that build peaks over 200 MiB (exit {code}, peak RSS {peak:.1f} MiB)")
if code == 0:
    est = json.load(open(report))["memory_estimate"]
    check(est["after clean"]["mib"] < 200 < est["after grid"]["mib"],
          "only the estimate after the grid is over 200 MiB: " +
          ", ".join(f"{k} {v['mib']:.1f} MiB" for k, v in est.items()))
    e = est["after grid"]["mib"]
    check(peak <= e <= 3 * peak, f"estimate after grid {e:.1f} MiB within [1, 3] x the peak {peak:.1f} MiB")
os.remove(pkg)
code, peak, err = build(["build"] + fine + ["--max-memory", "200M"])
check(code == 6, f"--grid 2000x2000 --max-memory 200M exits 6 (got {code})")
check(not os.path.exists(pkg), "--grid 2000x2000 --max-memory 200M writes no package")
check("estimate after grid" in err and "4000000 grid cells" in err, "it stops after the grid choice: " + err.strip())
check(peak < 200, f"it stopped before the cells were made (peak RSS {peak:.1f} MiB < 200)")
failed = json.load(open(report))
check(failed.get("exit_code") == 6 and failed.get("max_memory_mib") == 200 and
      failed.get("memory_estimate", {}).get("after grid", {}).get("mib", 0) > 200 and
      "clean" in failed.get("peak_rss_mib_after", {}),
      "the failed build's report gives the limit, the estimate that stopped it and the peaks so far: " +
      json.dumps({k: failed.get(k) for k in ("exit_code", "max_memory_mib")}))

# 5. Batch mode: the limit applies to every scene (each fails with exit 6).
scenes = os.path.join(work, "scenes")
os.makedirs(scenes)
for name in ("a", "b"):
    with open(os.path.join(scenes, name + ".toml"), "w") as f:
        f.write(f'source = "{source}"\n\n[[layer]]\nname = "{name}"\nkind = "polygon"\n')
out = os.path.join(work, "batch")
code, _, err = build(["build", scenes, "-o", out, "-q", "--max-memory", "100M", "--jobs", "2"])
check(code == 6, f"batch with --max-memory 100M exits 6 (got {code})")
summary = json.load(open(os.path.join(out, "summary.json")))
check(all(p["exit_code"] == 6 and "--max-memory" in p["error"] for p in summary["packages"]),
      "every scene of the batch failed on --max-memory: " + json.dumps(summary["packages"])[:400])
check(not any(n.endswith(".decals") for n in os.listdir(out)), "the batch wrote no package")

# 6. A tileset: each tile is checked once its window is cut, against the
#    resident set when the tiles began plus --jobs times the tile's part.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tileset_util import tree  # noqa: E402

tiled = [source, "--kind", "polygon", "-q", "--tile-size", "2000"]
ref = os.path.join(work, "tiles_ref")
report = os.path.join(work, "tiles_ref.json")
code, peak, err = build(["build"] + tiled + ["-o", ref, "--report", report, "--jobs", "2",
                                               "--max-memory", "4G"])
check(code == 0, f"a tileset with --max-memory 4G builds (exit {code}) {err.strip()}")
tile_est = json.load(open(report))["memory_estimate"].get("tile", {}) if code == 0 else {}
check(tile_est.get("jobs") == 2 and tile_est.get("tile", "").startswith("tiles/"),
      "the report names the largest tile's estimate and its jobs: " + json.dumps(tile_est)[:300])
if tile_est:
    e, r = tile_est["mib"], tile_est["resident_mib"]
    print(f"     tile estimate {e:.1f} MiB ({r:.1f} resident), measured peak RSS {peak:.1f} MiB, "
          f"ratio {e / peak:.2f}")
    check(peak <= e <= 3 * peak, "the tile estimate is within [1, 3] x the measured peak")
    # Between one tile at once and two: stops with --jobs 2, not with --jobs 1.
    part = (e - r) / 2
    limit = r + 1.5 * part
    out = os.path.join(work, "tiles_limited")
    report = os.path.join(work, "tiles_limited.json")
    lim = ["--max-memory", "%.0fM" % limit]
    code, _, err = build(["build"] + tiled + ["-o", out, "--report", report, "--jobs", "2"] + lim)
    check(code == 6, f"--jobs 2 --max-memory {limit:.0f}M exits 6 (got {code})")
    check("estimate tile" in err and "--jobs" in err and "tiles/" in err,
          "the error names the tile and says to build fewer at once: " + err.strip())
    check(not os.path.exists(os.path.join(out, "tileset.json")), "the stopped tileset has no index")
    failed = json.load(open(report))
    check(failed.get("exit_code") == 6 and
          failed.get("memory_estimate", {}).get("tile", {}).get("mib", 0) > limit,
          "the failed build's report has the tile estimate that stopped it")
    code, peak1, err = build(["build"] + tiled + ["-o", out, "--jobs", "1"] + lim)
    check(code == 0, f"--jobs 1 under the same limit builds (exit {code}) {err.strip()}")
    check(peak1 <= limit, f"and stays under it: peak RSS {peak1:.1f} MiB <= {limit:.1f}")
    if code == 0:
        check(tree(out) == tree(ref), "it equals the --jobs 2 tileset file for file")
    # A step of a cluster build is checked the same way (its own process:
    # a lower resident set, so a limit under two tiles' parts).
    steps = os.path.join(work, "tiles_steps")
    code, _, err = build(["build"] + tiled + ["-o", steps, "--step", "prepare"])
    check(code == 0, f"--step prepare (exit {code}) {err.strip()}")
    report = os.path.join(work, "tiles_step.json")
    step_limit = ["--max-memory", "%.0fM" % (1.5 * part)]
    code, _, err = build(["build"] + tiled + ["-o", steps, "--step", "tiles", "0/1", "--jobs", "2",
                                              "--report", report] + step_limit)
    check(code == 6 and "estimate tile" in err,
          f"--step tiles 0/1 --jobs 2 {step_limit[1]} exits 6 (got {code}) {err.strip()}")
    check(json.load(open(report)).get("memory_estimate", {}).get("tile", {}).get("jobs") == 2,
          "the step's failed report has the tile estimate")

sys.exit(1 if failures else 0)
