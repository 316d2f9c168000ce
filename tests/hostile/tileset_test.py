#!/usr/bin/env python3
"""Hostile tilesets: a built tileset altered the ways a hostile user would
(swapped tiles with their sizes and hashes swapped in the index, lying
counts, a frame CRS no library reads, counts of 2^64-1, an inverted or
1e308 extent, a negative margin, versions "1.0garbage" and
"1.99999999999999999999", a tile that is a FIFO or a link to /dev/zero, an
index above the size limit). `decalprep verify` (and `info` where the
index alone is at fault, `dump --tile` for a swapped or FIFO tile) must end each with exit 5 and a message naming
the field, within 10 s and 200 MB of peak resident memory (wait4's
ru_maxrss of the one run), never hang or say "ok".

Usage: tileset_test.py DECALPREP WORK_DIR
"""
import json
import os
import shutil
import signal
import subprocess
import sys
import threading

LIMIT_S = 10
LIMIT_MB = 200


def run(tool, args):
    """Runs the tool; returns (exit code or None when killed at LIMIT_S,
    output, peak RSS in MB of this run alone)."""
    p = subprocess.Popen([tool] + args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         stdin=subprocess.DEVNULL, start_new_session=True)
    killed = []

    def kill():
        killed.append(True)
        os.killpg(p.pid, signal.SIGKILL)

    timer = threading.Timer(LIMIT_S, kill)
    timer.start()
    out = p.stdout.read().decode(errors="replace")
    _, status, usage = os.wait4(p.pid, 0)
    timer.cancel()
    p.returncode = os.waitstatus_to_exitcode(status)
    return (None if killed else p.returncode), out, usage.ru_maxrss / 1024.0


def main():
    tool, work = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    # 12 short lines near Monaco, 500 m tiles: a tileset of a few tiles.
    feats = [{"type": "Feature", "id": k + 1, "properties": {},
              "geometry": {"type": "LineString",
                           "coordinates": [[7.42, 43.73 + k * 3e-4], [7.425, 43.7301 + k * 3e-4]]}}
             for k in range(12)]
    src = os.path.join(work, "lines.geojson")
    with open(src, "w") as f:
        json.dump({"type": "FeatureCollection", "features": feats}, f)
    good = os.path.join(work, "good")
    r = subprocess.run([tool, "build", src, "-o", good, "--kind", "line", "--width", "3",
                        "--tile-size", "500", "-q"], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"cannot build the tileset: {r.stderr}")
    with open(os.path.join(good, "tileset.json")) as f:
        index = json.load(f)
    if len(index["tiles"]) < 2:
        sys.exit(f"the tileset has {len(index['tiles'])} tiles; the swap case needs 2")

    fails, passed = [], 0

    def case(name, alter, needles, commands=(("verify",),)):
        nonlocal passed
        d = os.path.join(work, name)
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(good, d, symlinks=True)
        ix = json.loads(json.dumps(index))
        text = alter(d, ix)
        if text is not True:  # True: alter wrote tileset.json itself
            with open(os.path.join(d, "tileset.json"), "w") as f:
                f.write(text if isinstance(text, str) else json.dumps(ix, indent=2))
        failed_before = len(fails)
        for cmd in commands:
            args = [cmd[0], d] + list(cmd[1:])
            code, out, peak = run(tool, args)
            what = f"{name}: decalprep {' '.join(args)}"
            if code is None:
                fails.append(f"{what}: hung (killed after {LIMIT_S} s)\n{out[-1500:]}")
            elif code != 5:
                fails.append(f"{what}: exit {code}, expected 5\n{out[-1500:]}")
            elif not any(n in out for n in needles):
                fails.append(f"{what}: the message names none of {needles}\n{out[-1500:]}")
            elif peak > LIMIT_MB:
                fails.append(f"{what}: peak RSS {peak:.0f} MB, above {LIMIT_MB} MB")
            else:
                passed += 1
                print(f"[  OK  ] {what} (exit 5, {peak:.0f} MB)")
        if len(fails) == failed_before:
            shutil.rmtree(d)  # kept only to look at a failure (the oversized one is 140 MB)

    def swap(d, ix):
        a, b = ix["tiles"][0], ix["tiles"][1]
        fa, fb = os.path.join(d, a["file"]), os.path.join(d, b["file"])
        os.rename(fa, fa + ".tmp")
        os.rename(fb, fa)
        os.rename(fa + ".tmp", fb)
        for k in ("bytes", "xxh64", "counts", "layers"):
            a[k], b[k] = b[k], a[k]
    t0 = f"{index['tiles'][0]['x']},{index['tiles'][0]['y']}"
    case("swapped_tiles", swap, ["tile.x", "tile.y", "package metadata tile"],
         [("verify",), ("dump", "--tile", t0)])

    def lying_read(d, ix):
        ix["manifest"]["layers"][0]["read"] += 1
    case("lying_read", lying_read, ["manifest.layers[0]"], [("verify",), ("info",)])

    def lying_kept(d, ix):
        # One more kept than all tiles hold together; read = kept +
        # clipped_away + dropped still holds, so only the tiles betray it.
        in_tiles = sum(c["kept"] for t in ix["tiles"] for c in t["layers"] if c["layer"] == "layer0")
        m = ix["manifest"]["layers"][0]
        m["read"] += in_tiles + 1 - m["kept"]
        m["kept"] = in_tiles + 1
    case("kept_more_than_tiles_hold", lying_kept, ["manifest.layers[0].kept"])

    def lying_tile_counts(d, ix):
        ix["tiles"][0]["counts"]["lines"] += 1
    case("lying_tile_counts", lying_tile_counts, ["counts.lines"])

    def huge_counts(d, ix):
        m = ix["manifest"]["layers"][0]
        m["read"] = m["kept"] = 2**64 - 1
        m["clipped_away"] = m["dropped"] = 0
    case("counts_2_64", huge_counts, ["manifest.layers[0].read"], [("verify",), ("info",)])

    def bad_crs(d, ix):
        ix["frame"]["crs_wkt"] = "not a crs"
    case("bad_crs", bad_crs, ["frame.crs_wkt"], [("verify",), ("info",)])

    def inverted(d, ix):
        e = ix["extent"]
        ix["extent"] = [e[2], e[3], e[0], e[1]]
    case("inverted_extent", inverted, ["extent"], [("verify",), ("info",)])

    def huge_extent(d, ix):
        return json.dumps(ix, indent=2).replace(json.dumps(ix["extent"][2]), "1e308", 1)
    case("extent_1e308", huge_extent, ["extent[2]"], [("verify",), ("info",)])

    def negative_margin(d, ix):
        ix["tiling"]["margin_m"] = -5.0
    case("negative_margin", negative_margin, ["tiling.margin_m"], [("verify",), ("info",)])

    for name, v in (("version_garbage", "1.0garbage"), ("version_overflow", "1.99999999999999999999")):
        def version(d, ix, v=v):
            ix["tileset_version"] = v
        case(name, version, ["tileset_version"], [("verify",), ("info",)])

    def fifo_tile(d, ix):
        p = os.path.join(d, ix["tiles"][0]["file"])
        os.remove(p)
        os.mkfifo(p)
    case("fifo_tile", fifo_tile, ["FIFO"], [("verify",), ("dump", "--tile", t0)])

    def dev_zero_tile(d, ix):
        p = os.path.join(d, ix["tiles"][0]["file"])
        os.remove(p)
        os.symlink("/dev/zero", p)
    case("dev_zero_tile", dev_zero_tile, ["character device"])

    def oversized(d, ix):
        # A valid index grown past 128 MiB by notes: refused before parsing.
        # Written piece by piece, so that this script stays small (a forked
        # child's peak counts the parent's pages until it execs).
        ix["manifest"]["notes"] = ["NOTES"]
        head, tail = json.dumps(ix).split('"NOTES"')
        note = '"' + "x" * 1000 + '", '
        with open(os.path.join(d, "tileset.json"), "w") as f:
            f.write(head)
            for _ in range(140):
                f.write(note * 1024)
            f.write('"x"' + tail)
        return True
    case("oversized_index", oversized, ["bytes, above the"], [("verify",), ("info",)])

    for f in fails:
        print(f"[ FAIL ] {f}")
    print(f"{passed} passed, {len(fails)} failed")
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
