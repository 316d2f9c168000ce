#!/usr/bin/env python3
"""Examples.PythonPlotCells: examples/python/plot_cells.py on the Monaco
sample, checked with the tool.

    plot_cells_test.py DECALPREP SOURCE_ROOT WORK_DIR

Builds samples/monaco/scene.toml, runs plot_cells.py on it (the decalprep
package from SOURCE_ROOT/python) and checks, with `decalprep dump --json`
as the oracle:
- the per-cell occupancy it saves equals, cell by cell, the line entries
  plus polygon entries that dump's cell_line_first / cell_poly_first (or
  v1.2 cell_segment_range / cell_poly_range) give for the grid of dump's
  metadata; its total equals dump's cell_segments plus cell_poly_entries
  (plus cell_polys) counts, and it prints that total;
- the PNG is a PNG of a plausible size with many colours (not blank).
Exit 0 pass, 1 fail, 77 skip (numpy or matplotlib missing).
"""

import json
import os
import shutil
import struct
import subprocess
import sys

failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL: " + msg, flush=True)
    return cond


def run(args, **kw):
    return subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


def dump_blob(tool, package, name, present):
    if name not in present:
        return None, None
    r = run([tool, "dump", "--json", "--blob", name, package])
    if not check(r.returncode == 0, "dump --blob %s failed: %s" % (name, r.stderr.decode())):
        return None, None
    d = json.loads(r.stdout)
    return d, (d["blobs"][0] if d["blobs"] else None)


def main():
    if len(sys.argv) != 4:
        print("usage: plot_cells_test.py DECALPREP SOURCE_ROOT WORK_DIR")
        return 2
    tool, root, work = sys.argv[1], os.path.abspath(sys.argv[2]), os.path.abspath(sys.argv[3])
    try:
        import numpy as np
        import matplotlib.image
    except ImportError as e:
        print("SKIP: %s needs python3-numpy and python3-matplotlib (scripts/deps): %s" % (sys.executable, e))
        return 77
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    pkg = os.path.join(work, "monaco.decals")
    r = run([tool, "build", os.path.join(root, "samples", "monaco", "scene.toml"), "-o", pkg, "-q"])
    if not check(r.returncode == 0, "build failed: %s" % r.stderr.decode()[-2000:]):
        return 1
    png, counts = os.path.join(work, "cells.png"), os.path.join(work, "cells.npy")
    env = dict(os.environ, PYTHONPATH=os.path.join(root, "python"))
    r = run([sys.executable, os.path.join(root, "examples", "python", "plot_cells.py"), pkg, png,
             "--counts", counts], env=env, cwd=work)
    if not check(r.returncode == 0, "plot_cells.py failed: %s" % (r.stdout + r.stderr).decode()[-3000:]):
        return 1
    summary = json.loads(r.stdout.decode().strip().splitlines()[-1])
    print("plot_cells.py: %s" % summary)

    # The oracle: per-cell entries from dump's own per-cell blobs (those the
    # package has: `info --json` lists them).
    r = run([tool, "info", "--json", pkg])
    if not check(r.returncode == 0, "info failed: %s" % r.stderr.decode()):
        return 1
    info = json.loads(r.stdout)
    present = {b["name"] for b in info["blobs"]}
    nx, ny = info["metadata"]["grid"]["dims"]
    want = np.zeros(nx * ny, dtype=np.int64)
    listed = 0
    for first, rng, lst in (("cell_line_first", "cell_segment_range", "cell_segments"),
                            ("cell_poly_first", "cell_poly_range", "cell_poly_entries")):
        _, fb = dump_blob(tool, pkg, first, present)
        _, rb = dump_blob(tool, pkg, rng, present)
        if fb is not None and fb["count"]:
            xs = np.array([e[0] for e in fb["elements"]], dtype=np.int64)
            check(len(xs) == nx * ny + 1, "dump: %s has %d elements for %d cells" % (first, len(xs), nx * ny))
            want += np.diff(xs)
        elif rb is not None and rb["count"]:
            want += np.array([e[1] for e in rb["elements"]], dtype=np.int64)
        for name in (lst, "cell_polys") if lst == "cell_poly_entries" else (lst,):
            _, lb = dump_blob(tool, pkg, name, present)
            listed += lb["count"] if lb is not None else 0
    got = np.load(counts)
    check(got.shape == (ny, nx), "occupancy shape %s, grid dims (nx %d, ny %d)" % (got.shape, nx, ny))
    if got.shape == (ny, nx):
        bad = np.flatnonzero(got.reshape(-1) != want)
        check(bad.size == 0, "occupancy differs from dump in %d cells, first cell %s: %d vs %d"
              % (bad.size, bad[:1], got.reshape(-1)[bad[0]] if bad.size else 0, want[bad[0]] if bad.size else 0))
    check(int(got.sum()) == listed == summary["total"],
          "total occupancy %d, printed %d, dump's cell entries %d" % (got.sum(), summary["total"], listed))
    check(listed > 100000, "the Monaco sample lists only %d cell entries" % listed)

    # The picture.
    with open(png, "rb") as f:
        head = f.read(24)
    check(head[:8] == b"\x89PNG\r\n\x1a\n", "%s is not a PNG" % png)
    w, h = struct.unpack(">II", head[16:24]) if len(head) == 24 else (0, 0)
    check(w >= 300 and h >= 300 and os.path.getsize(png) > 20000,
          "%s is %dx%d, %d bytes: too small to show the grid" % (png, w, h, os.path.getsize(png)))
    img = matplotlib.image.imread(png)
    colours = len(np.unique(img.reshape(-1, img.shape[-1]), axis=0))
    check(colours > 50, "%s has %d colours: blank or nearly" % (png, colours))
    print("occupancy of %d cells equals dump's (%d entries), PNG %dx%d with %d colours"
          % (nx * ny, listed, w, h, colours))
    if failures:
        print("%d failure(s)" % len(failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
