#!/usr/bin/env python3
"""Cell occupancy of a decal package: how many entries each grid cell lists.

    python3 plot_cells.py PACKAGE OUT.png [--counts OUT.npy]

A package's decal grid (formats/SPEC.md "Metadata", `grid`) gives every
cell the list of line segments and of polygons that can cover a point of
it; a renderer walks those lists per pixel, so their lengths are its cost.
This script reads them with the `decalprep` Python package (python/,
`pip install ./python`), sums the line and polygon entries of each cell and
draws the grid as an image (matplotlib, Agg backend: no display needed).
It prints a one-line JSON summary; --counts saves the per-cell totals
(int64, shape (ny, nx)) for a check.

The cells are written in "# %%" sections, so an editor that runs notebook
cells (VS Code, Spyder, Jupytext) can step through them.
"""

# %% Arguments and the package
import argparse
import json

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import decalprep  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
ap.add_argument("package")
ap.add_argument("png")
ap.add_argument("--counts", help="save the per-cell totals as .npy")
args = ap.parse_args()

pkg = decalprep.open(args.package)
nx, ny = pkg.metadata["grid"]["dims"]
cell_w, cell_h = pkg.metadata["grid"]["cell"]
quantum = pkg.metadata.get("quantum_m", 0.001)


# %% Entries per cell
def entries_per_cell(first_name, range_name):
    """Cell c lists entries [x_c, x_{c+1}) of the v1.3 per-cell firsts
    (SPEC "Compact layout (v1.3)"), or `count` of the v1.2 per-cell range;
    a kind with no per-cell blob lists nothing."""
    first = pkg.array(first_name)
    if len(first):
        return np.diff(first[:, 0].astype(np.int64))
    ranges = pkg.array(range_name)
    if len(ranges):
        return ranges[:, 1].astype(np.int64)
    return np.zeros(nx * ny, dtype=np.int64)


lines = entries_per_cell("cell_line_first", "cell_segment_range")
polys = entries_per_cell("cell_poly_first", "cell_poly_range")
# Cell (ix, iy) has index ix + nx * iy: rows are y.
occupancy = (lines + polys).reshape(ny, nx)
pkg.close()

summary = {"cells": nx * ny, "dims": [nx, ny], "line_entries": int(lines.sum()),
           "poly_entries": int(polys.sum()), "total": int(occupancy.sum()),
           "max": int(occupancy.max()) if occupancy.size else 0,
           "empty_cells": int((occupancy == 0).sum())}
print(json.dumps(summary))
if args.counts:
    np.save(args.counts, occupancy)

# %% The picture
w_m, h_m = nx * cell_w * quantum, ny * cell_h * quantum
aspect = h_m / w_m if w_m > 0 else 1.0
fig, ax = plt.subplots(figsize=(8, min(16, max(3, 8 * aspect))), dpi=100)
# log(1 + n): a few crowded cells would otherwise wash out the rest.
im = ax.imshow(np.log1p(occupancy), origin="lower", cmap="viridis", interpolation="nearest",
               extent=[0, w_m, 0, h_m])
cb = fig.colorbar(im, ax=ax, shrink=0.8)
cb.set_label("log(1 + entries per cell)")
ax.set_xlabel("x from the grid origin (m)")
ax.set_ylabel("y from the grid origin (m)")
ax.set_title("%s: %d x %d cells, %d entries (max %d)"
             % (args.package.rsplit("/", 1)[-1], nx, ny, summary["total"], summary["max"]), fontsize=10)
fig.savefig(args.png, bbox_inches="tight")
