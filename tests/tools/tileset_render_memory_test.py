#!/usr/bin/env python3
"""`render` of a tileset holds one tile at a time, not the view's tiles.

  tileset_render_memory_test.py DECALPREP TILESET_DIR WORK_DIR

Renders the whole tileset (the default --fit view, and a top-down one) with
--cpu and with GL at 640x360, each in a child whose peak resident set the
kernel reports (wait4's ru_maxrss), and checks each against

  the largest tile's blobs decoded (the sum of raw_size in `info --json`)
  + 2 x the frame (W x H x 36 bytes: the RGBA8 image and the float decal and
    dynamic layers render returns)
  + 300 MiB.

On the Monaco sample in 500 m tiles (57 tiles, 151 MiB of blobs decoded,
8.8 MiB the largest tile; bound 325 MiB) a renderer that opened every tile
of the view before it drew peaked at 535 MiB (--cpu) and 657 MiB (GL), and
fails here; one tile at a time, 95 and 207 MiB. A GL render that cannot
start (no EGL) is skipped with a line; the --cpu ones always run.
"""
import glob
import json
import os
import subprocess
import sys

MIB = 1024.0 * 1024.0
W, H = 640, 360


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def decoded(tool, package):
    info = json.loads(subprocess.run([tool, "info", package, "--json"], check=True,
                                     capture_output=True).stdout)
    return sum(b["raw_size"] for b in info["blobs"])


def peak_rss(cmd):
    """(exit code, stderr, peak resident bytes) of the child."""
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = p.stderr.read().decode(errors="replace")
    _, status, ru = os.wait4(p.pid, 0)
    return os.waitstatus_to_exitcode(status), err, ru.ru_maxrss * 1024.0


def main():
    if len(sys.argv) != 4:
        print(__doc__)
        return 2
    tool, tiles, work = sys.argv[1:4]
    os.makedirs(work, exist_ok=True)
    sizes = [decoded(tool, p) for p in glob.glob(os.path.join(tiles, "tiles", "*.decals"))]
    if not sizes:
        fail("no tile packages under " + tiles)
    bound = max(sizes) + 2 * W * H * 36 + 300 * MIB
    print("%d tiles, blobs decoded %.1f MiB in all, %.1f MiB the largest; bound %.1f MiB"
          % (len(sizes), sum(sizes) / MIB, max(sizes) / MIB, bound / MIB))
    views = {"fit": [], "top-down": ["--ortho", "--fit", "--pitch", "90"]}
    bad = []
    for name, view in views.items():
        for renderer in ("cpu", "gl"):
            png = os.path.join(work, "%s_%s.png" % (name, renderer))
            cmd = [tool, "render", tiles, "--size", "%dx%d" % (W, H), "-o", png, "--stats"] + view
            if renderer == "cpu":
                cmd.append("--cpu")
            rc, err, rss = peak_rss(cmd)
            if rc != 0 and renderer == "gl" and "EGL" in err:
                print("SKIP %s %s: no headless GL: %s" % (name, renderer, err.strip()[-300:]))
                continue
            if rc != 0:
                fail("%s exited %d: %s" % (" ".join(cmd), rc, err[-2000:]))
            # Every tile of the whole extent is drawn: the note says how many.
            if "%d of %d tiles meet the view" % (len(sizes), len(sizes)) not in err:
                fail("%s %s: not every tile was drawn:\n%s" % (name, renderer, err[-1000:]))
            ok = rss <= bound
            print("%s %s: peak %.1f MiB, bound %.1f MiB: %s"
                  % (name, renderer, rss / MIB, bound / MIB, "ok" if ok else "ABOVE"))
            if not ok:
                bad.append("%s %s" % (name, renderer))
    if bad:
        fail("peak above the bound: " + ", ".join(bad))
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
