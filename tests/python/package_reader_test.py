#!/usr/bin/env python3
"""Python.PackageReaderAgreesWithDump: the package python/ (decalprep), as
pip installs it, against the tool.

    package_reader_test.py DECALPREP SOURCE_ROOT WORK_DIR

Run with a python3 that imports numpy, xxhash and zstandard (Debian's):
1. makes a venv in WORK_DIR (--system-site-packages, for Debian's numpy,
   xxhash and zstandard) and pip-installs a copy of SOURCE_ROOT/python into
   it without network (--no-index --no-build-isolation);
2. runs the checks below with the venv's python, from WORK_DIR, and first
   checks that `decalprep` comes from the venv, not the source tree.

The oracle is always the tool (`dump --json`, `info --json`, `verify`),
never the code under test:
- packages: the golden scene (zstd), the Monaco sample built --no-compress,
  the checked-in valid seeds of fuzz/corpus/read, and every tile of every
  level of a tileset of the golden scene. Each is opened with
  decalprep.open; its metadata and blob table agree with `info --json`,
  and every element of every blob (`array(name)`, decoded here by field)
  equals `dump --json`'s;
- the tileset: levels and tiles agree with `info DIR --json`; every tile
  opens through the tileset; hostile copies of tileset.json and a tile
  whose bytes changed are refused (and `verify DIR` refuses them too);
- refusals: every fuzz/corpus/read/broken_* seed, bit-flipped, truncated
  and grown copies of valid packages (each also refused by `verify`), and
  a FIFO: each raises decalprep.FormatError (a ValueError) naming the file;
- memory mapping: every non-empty blob of the uncompressed Monaco package
  is a view of the file mapping at the blob's offset (np.shares_memory, the
  base chain ends at the mmap), stays readable after close(); a compressed
  blob is a fresh array.

Exit 0 pass, 1 fail, 77 skip (no venv module or numpy/xxhash/zstandard).
"""

import json
import math
import mmap
import os
import random
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "support"))
from checks import check, failures, run  # noqa: E402

stats = dict(packages=0, tiles=0, blobs=0, elements=0, refused=0, broken_seeds=0, flips=0, mapped_blobs=0)


# ------------------------------------------------------------------ driver --

def driver(tool, root, work):
    """Step 1: the venv and the install; then step 2 in the venv."""
    for mod in ("venv", "numpy", "xxhash", "zstandard", "setuptools"):
        try:
            __import__(mod)
        except ImportError as e:
            print("SKIP: %s needs Debian's python3-venv, python3-numpy, python3-xxhash, python3-zstandard, "
                  "python3-setuptools and python3-pip (scripts/deps): %s" % (sys.executable, e))
            return 77
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    venv, src = os.path.join(work, "venv"), os.path.join(work, "src")
    t = time.time()
    # A copy, so that the build's build/ and *.egg-info stay out of the checkout.
    shutil.copytree(os.path.join(root, "python"), src,
                    ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    r = run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", venv])
    if not check(r.returncode == 0, "venv failed: %s" % r.stderr.decode()):
        return 1
    py = os.path.join(venv, "bin", "python")
    # Debian's pip from the system site packages, run by the venv's python,
    # installs into the venv.
    r = run([py, "-m", "pip", "install", "--no-index", "--no-build-isolation", "--quiet", src])
    if not check(r.returncode == 0, "pip install ./python failed: %s" % (r.stdout + r.stderr).decode()[-3000:]):
        return 1
    print("venv and pip install ./python: %.1f s" % (time.time() - t), flush=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    r = subprocess.run([py, os.path.abspath(__file__), "--inside", tool, root, work], cwd=work, env=env)
    return r.returncode


# ---------------------------------------------------- comparisons with dump --

def finite_or_none(values):
    """JSON (dump) writes non-finite floats as null."""
    return [None if isinstance(v, float) and not math.isfinite(v) else
            (finite_or_none(v) if isinstance(v, list) else v) for v in values]


def decoded(np, arr, blob):
    """An array of the package decoded here into what `dump --json` lists:
    one value (or list) per element, a dict per record."""
    if blob.name == "manifest_entries":
        return json.loads(arr.tobytes().decode("utf-8"))
    if arr.dtype.names is None:
        vals = arr.tolist()
        return finite_or_none(vals) if arr.dtype.kind == "f" else vals
    cols = []
    for f in arr.dtype.names:
        col = arr[f].tolist()
        if arr.dtype[f].base.kind == "f":
            col = finite_or_none(col)
        if blob.record == "LodSegment" and f in ("generator", "splitter"):
            col = [None if v == 0xFFFFFFFF else v for v in col]  # kLodNone
        cols.append((f, col))
    return [{f: col[i] for f, col in cols} for i in range(len(arr))]


def first_difference(a, b):
    if len(a) != len(b):
        return "length %d vs %d" % (len(a), len(b))
    for i, (x, y) in enumerate(zip(a, b)):
        if x != y:
            return "element %d: package %r, dump %r" % (i, x, y)
    return None


def compare_package(np, tool, path, pkg, label):
    """Metadata and table against `info --json`, elements against `dump --json`."""
    r = run([tool, "info", "--json", path])
    if not check(r.returncode == 0, "%s: info failed: %s" % (label, r.stderr.decode())):
        return
    info = json.loads(r.stdout)
    check(info["metadata"] == pkg.metadata, "%s: metadata differs from info" % label)
    check(info["version"] == {"major": pkg.version[0], "minor": pkg.version[1]},
          "%s: version %s, info %s" % (label, pkg.version, info["version"]))
    check(info["flags"] == pkg.header["flags"], "%s: flags %d, info %d" % (label, pkg.header["flags"], info["flags"]))
    check(len(info["blobs"]) == len(pkg.blobs), "%s: %d blobs, info %d" % (label, len(pkg.blobs), len(info["blobs"])))
    for ib, b in zip(info["blobs"], pkg.blobs):
        mine = {"index": b.index, "id": b.id, "name": b.name, "known": b.known, "type": b.type,
                "stride": b.stride, "count": b.count, "codec": b.codec_name, "offset": b.offset,
                "stored_size": b.stored_size, "raw_size": b.raw_size, "xxh64": "%016x" % b.checksum}
        check(ib == mine, "%s: table entry %d: package %s, info %s" % (label, b.index, mine, ib))
    r = run([tool, "dump", "--json", path])
    if not check(r.returncode == 0, "%s: dump failed: %s" % (label, r.stderr.decode())):
        return
    d = json.loads(r.stdout)
    del r
    check(d["metadata"] == pkg.metadata, "%s: metadata differs from dump" % label)
    check(len(d["blobs"]) == len(pkg.blobs), "%s: dump lists %d blobs, the package %d"
          % (label, len(d["blobs"]), len(pkg.blobs)))
    for db, b in zip(d["blobs"], pkg.blobs):
        where = "%s: blob %s" % (label, b.name)
        head = {"id": b.id, "name": b.name, "type": b.type, "stride": b.stride, "count": b.count}
        check({k: db[k] for k in head} == head, "%s: dump %s, package %s" % (where, {k: db[k] for k in head}, head))
        arr = pkg.array(b.name)
        # numpy writes a little-endian dtype's byte order as native ("=") on
        # a little-endian machine; .str spells it out ("<u4").
        parts = [arr.dtype[f].base for f in arr.dtype.names] if arr.dtype.names else [arr.dtype]
        check(all(t.str[0] in "<|" and (t.itemsize == 1 or t.str[0] == "<") for t in parts),
              "%s: dtype %s is not little-endian" % (where, arr.dtype))
        check(len(arr) == b.count, "%s: array of %d elements, count %d" % (where, len(arr), b.count))
        mine = decoded(np, arr, b)
        diff = first_difference(mine, db["elements"])
        check(diff is None, "%s: elements differ from dump: %s" % (where, diff))
        stats["blobs"] += 1
        stats["elements"] += len(mine)
    stats["packages"] += 1


# ------------------------------------------------------------- refusals --

def refused(decalprep, path, label, tool=None):
    """decalprep.open(path) raises FormatError naming the file; with `tool`,
    `decalprep verify` rejects the file too (the oracle)."""
    if tool is not None:
        r = run([tool, "verify", path])
        check(r.returncode != 0, "%s: decalprep verify accepts it, so it is no refusal case" % label)
    try:
        p = decalprep.open(path)
    except decalprep.FormatError as e:
        check(isinstance(e, ValueError), "%s: FormatError is not a ValueError" % label)
        check(path in str(e) and len(str(e)) > len(path) + 8,
              "%s: the message does not name the file and the fault: %s" % (label, e))
        stats["refused"] += 1
        print("  refused %s: ...%s" % (label, str(e)[len(path) + 2:][-110:]), flush=True)
        return str(e)
    except Exception as e:  # noqa: BLE001 - anything else is a failure
        check(False, "%s: raised %s (%s), not FormatError" % (label, type(e).__name__, e))
        return None
    check(False, "%s: opened without complaint" % label)
    getattr(p, "close", lambda: None)()
    return None


def flipped_copies(decalprep, tool, path, tmp, rng, n):
    """n copies of `path` with one bit flipped each (SPEC "File structure":
    every byte of a valid file is covered by a check), one more per
    non-empty blob with a bit flipped in the middle of its stored bytes (the
    message must name the blob), one truncated by a byte, one grown by a
    zero byte."""
    with open(path, "rb") as f:
        data = f.read()
    base = os.path.basename(path)
    cases = []
    # The header (version, flags, sizes), the table, the metadata, the rest.
    fixed = [9, 13, 17, 25, 100, 96 + 96 * 2 + 20]
    for off in fixed + [rng.randrange(len(data)) for _ in range(n - len(fixed))]:
        off %= len(data)
        b = bytearray(data)
        b[off] ^= 1 << rng.randrange(8)
        cases.append(("%s bit flip at %d" % (base, off), bytes(b)))
    r = run([tool, "info", "--json", path])
    if check(r.returncode == 0, "%s: info failed: %s" % (base, r.stderr.decode())):
        for ib in json.loads(r.stdout)["blobs"]:
            if ib["stored_size"]:
                off = ib["offset"] + ib["stored_size"] // 2
                b = bytearray(data)
                b[off] ^= 1 << rng.randrange(8)
                cases.append(("%s bit flip in blob %s at %d" % (base, ib["name"], off), bytes(b), ib["name"]))
    cases.append(("%s truncated by one byte" % base, data[:-1]))
    cases.append(("%s with a byte appended" % base, data + b"\0"))
    for label, blob, *named in cases:
        out = os.path.join(tmp, "flip.decals")
        with open(out, "wb") as f:
            f.write(blob)
        msg = refused(decalprep, out, label, tool)
        if named and msg is not None:
            check("'%s'" % named[0] in msg, "%s: the message does not name the blob: %s" % (label, msg))
        stats["flips"] += 1


# ---------------------------------------------------------- memory mapping --

def check_mapping(np, decalprep, path, label):
    with decalprep.open(path) as pkg:
        check(pkg.mapped, "%s: not memory-mapped" % label)
        check(pkg.header["flags"] & (1 << 16), "%s: not flagged all_uncompressed" % label)
        m = pkg.mapping()
        check(isinstance(m, mmap.mmap), "%s: mapping() is %r, not an mmap" % (label, type(m)))
        whole = np.frombuffer(m, dtype=np.uint8)
        start = whole.ctypes.data
        held = []
        for b in pkg.blobs:
            if b.count == 0:
                continue
            a = pkg.array(b.name)
            where = "%s: blob %s" % (label, b.name)
            check(np.shares_memory(a, whole), "%s: does not share memory with the mapping" % where)
            check(a.ctypes.data - start == b.offset, "%s: starts at file offset %d, the table says %d"
                  % (where, a.ctypes.data - start, b.offset))
            check(not a.flags.owndata and not a.flags.writeable, "%s: owns its data or is writeable" % where)
            base = a
            while getattr(base, "base", None) is not None:
                base = base.base
            if isinstance(base, memoryview):
                base = base.obj
            check(isinstance(base, mmap.mmap), "%s: base chain ends at %r, not the mmap" % (where, type(base)))
            check(bytes(a.tobytes()) == bytes(m[b.offset:b.offset + b.raw_size]),
                  "%s: bytes differ from the file's" % where)
            held.append((b.name, a, a.copy()))
            stats["mapped_blobs"] += 1
        del whole
    check(pkg.mapping() is None, "%s: close() left the mapping on the package" % label)
    for name, a, copy in held:
        check(np.array_equal(a, copy, equal_nan=a.dtype.names is None and a.dtype.kind == "f")
              if a.dtype.names is None else a.tobytes() == copy.tobytes(),
              "%s: blob %s changed after close()" % (label, name))
    try:
        pkg.array(held[0][0] if held else "line_vertices")
        check(False, "%s: array() after close() did not raise" % label)
    except ValueError:
        pass


def check_compressed_copies(np, decalprep, path, label):
    with decalprep.open(path) as pkg:
        whole = np.frombuffer(pkg.mapping(), dtype=np.uint8)
        z = [b for b in pkg.blobs if b.codec_name == "zstd" and b.count]
        check(z, "%s: no zstd blob" % label)
        for b in z:
            check(not np.shares_memory(pkg.array(b.name), whole),
                  "%s: zstd blob %s shares memory with the mapping" % (label, b.name))
        del whole
    with decalprep.open(path, mmap=False) as copy, decalprep.open(path) as mapped:
        check(not copy.mapped, "%s: mmap=False mapped the file" % label)
        for b in mapped.blobs:
            check(copy.array(b.name).tobytes() == mapped.array(b.name).tobytes(),
                  "%s: blob %s differs between mmap=False and the mapping" % (label, b.name))


# --------------------------------------------------------------- tilesets --

def check_tileset(np, decalprep, tool, ts_dir, tmp):
    ts = decalprep.open(ts_dir)
    check(isinstance(ts, decalprep.Tileset), "open(%s) is %r, not a Tileset" % (ts_dir, ts))
    ts2 = decalprep.open(os.path.join(ts_dir, "tileset.json"))
    check([t.file for t in ts2.tiles] == [t.file for t in ts.tiles], "open(tileset.json) differs from open(dir)")
    r = run([tool, "info", "--json", ts_dir])
    if not check(r.returncode == 0, "info %s failed: %s" % (ts_dir, r.stderr.decode())):
        return
    info = json.loads(r.stdout)
    want = [info["tiles"]] + [lv["tiles"] for lv in info.get("levels", [])]
    check(len(ts.levels) == len(want) and len(ts.levels) > 1,
          "tileset: %d levels, info %d (the test builds overview levels)" % (len(ts.levels), len(want)))
    for lv, tiles in zip(ts.levels, want):
        mine = [(t.x, t.y, t.file, t.bytes, t.xxh64) for t in lv.tiles]
        theirs = [(t["x"], t["y"], t["file"], t["bytes"], t["xxh64"]) for t in tiles]
        check(mine == theirs, "tileset level %d: tiles differ from info" % lv.level)
        for t in lv.tiles:
            with ts.open_tile(t) as pkg:
                compare_package(np, tool, os.path.join(ts_dir, t.file), pkg, "tileset L%d %s" % (lv.level, t.file))
            stats["tiles"] += 1
    # A point inside a listed tile's square finds it; one far away none.
    t0 = ts.tiles[0]
    check(ts.tile_at((t0.square[0] + t0.square[2]) / 2, (t0.square[1] + t0.square[3]) / 2) is t0,
          "tile_at the centre of %s does not find it" % t0.file)
    check(ts.tile_at(1e9, 1e9) is None, "tile_at a far point finds a tile")
    n = len(ts.manifest_entries())
    check(n == ts.manifest["entry_count"], "manifest.json has %d entries, the index says %d"
          % (n, ts.manifest["entry_count"]))

    # Hostile copies of the index, each refused by verify too.
    with open(os.path.join(ts_dir, "tileset.json"), encoding="utf-8") as f:
        index = json.load(f)

    def hostile(label, change):
        copy = os.path.join(tmp, "hostile_ts")
        shutil.rmtree(copy, ignore_errors=True)
        shutil.copytree(ts_dir, copy)
        j = json.loads(json.dumps(index))
        change(j)
        with open(os.path.join(copy, "tileset.json"), "w", encoding="utf-8") as f:
            json.dump(j, f)
        msg = refused(decalprep, os.path.join(copy, "tileset.json"), "tileset: " + label, tool)
        r = run([tool, "verify", copy])
        check(r.returncode != 0, "tileset: %s: decalprep verify accepts it" % label)
        return msg

    hostile("major version 2", lambda j: j.update(tileset_version="2.0"))
    hostile("version 1.0garbage", lambda j: j.update(tileset_version="1.0garbage"))
    hostile("a tile file outside tiles/", lambda j: j["tiles"][0].update(file="../x0_y0.decals"))
    hostile("a tile square moved", lambda j: j["tiles"][0]["square"].__setitem__(0, j["tiles"][0]["square"][0] + 1))
    hostile("levels not consecutive", lambda j: j["levels"][0].update(level=2))
    hostile("inverted extent", lambda j: j.update(extent=[1.0, 0.0, 0.0, 1.0]))
    hostile("manifest read != kept + clipped_away + dropped",
            lambda j: j["manifest"]["layers"][0].update(read=j["manifest"]["layers"][0]["read"] + 1))
    # A tile whose bytes changed (same size): the index's hash refuses it.
    copy = os.path.join(tmp, "flipped_tile")
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(ts_dir, copy)
    victim = os.path.join(copy, t0.file)
    with open(victim, "r+b") as f:
        f.seek(t0.bytes // 2)
        c = f.read(1)
        f.seek(t0.bytes // 2)
        f.write(bytes([c[0] ^ 0x10]))
    ts3 = decalprep.open(copy)
    try:
        ts3.open_tile(ts3.tiles[0])
        check(False, "a tile with a flipped byte opened")
    except decalprep.FormatError as e:
        check("xxh64" in str(e), "a tile with a flipped byte: the message names no xxh64: %s" % e)
        stats["refused"] += 1
    r = run([tool, "verify", copy])
    check(r.returncode != 0, "decalprep verify accepts the tileset with a flipped tile")


# ------------------------------------------------------------------ inside --

def inside(tool, root, work):
    import numpy as np
    import decalprep
    here = os.path.dirname(os.path.abspath(decalprep.__file__))
    venv = os.path.join(work, "venv")
    if not check(here.startswith(venv + os.sep) and not here.startswith(os.path.join(root, "python")),
                 "decalprep is imported from %s, not from the venv %s" % (here, venv)):
        return 1
    print("decalprep %s from %s" % (decalprep.__version__, here), flush=True)
    t0 = time.time()
    tmp = os.path.join(work, "tmp")
    os.makedirs(tmp)
    built = {}
    for label, scene, extra in (("golden.decals", "tests/tools/golden/scene.toml", []),
                                ("monaco_none.decals", "samples/monaco/scene.toml", ["--no-compress"]),
                                ("golden_tiles", "tests/tools/golden/scene.toml",
                                 ["--tile-size", "200", "--levels", "2"])):
        out = os.path.join(tmp, label)
        t = time.time()
        r = run([tool, "build", os.path.join(root, scene), "-o", out, "-q"] + extra)
        if check(r.returncode == 0, "build %s %s failed: %s" % (scene, extra, r.stderr.decode()[-2000:])):
            built[label] = out
        print("built %s in %.1f s" % (label, time.time() - t), flush=True)

    seeds = os.path.join(root, "fuzz", "corpus", "read")
    valid = sorted(os.path.join(seeds, f) for f in os.listdir(seeds) if f.startswith("valid_"))
    broken = sorted(os.path.join(seeds, f) for f in os.listdir(seeds) if f.startswith("broken_"))
    check(len(valid) >= 2 and len(broken) >= 10, "fuzz/corpus/read: %d valid, %d broken seeds" % (len(valid), len(broken)))

    for path in [built.get("golden.decals"), built.get("monaco_none.decals")] + valid:
        if path is None:
            continue
        t = time.time()
        label = os.path.basename(path)
        r = run([tool, "verify", path])
        check(r.returncode == 0, "%s: decalprep verify rejects it: %s" % (label, (r.stdout + r.stderr).decode()))
        try:
            pkg = decalprep.open(path)
        except decalprep.FormatError as e:
            check(False, "%s: refused: %s" % (label, e))
            continue
        with pkg:
            compare_package(np, tool, path, pkg, label)
        print("%s: agrees with info and dump (%.1f s)" % (label, time.time() - t), flush=True)

    if "monaco_none.decals" in built:
        check_mapping(np, decalprep, built["monaco_none.decals"], "monaco_none.decals")
    if "golden.decals" in built:
        check_compressed_copies(np, decalprep, built["golden.decals"], "golden.decals")

    for path in broken:
        refused(decalprep, path, os.path.relpath(path, root), tool)
        stats["broken_seeds"] += 1
    rng = random.Random(20261129)
    for path in [built.get("golden.decals")] + valid:
        if path is not None:
            flipped_copies(decalprep, tool, path, tmp, rng, 12)
    fifo = os.path.join(tmp, "fifo.decals")
    os.mkfifo(fifo)
    refused(decalprep, fifo, "a FIFO")  # would block if it were opened for reading

    if "golden_tiles" in built:
        t = time.time()
        check_tileset(np, decalprep, tool, built["golden_tiles"], tmp)
        print("tileset: agrees with info and dump, hostile copies refused (%.1f s)" % (time.time() - t), flush=True)

    print("python package: %(packages)d packages (%(tiles)d of them tiles) with %(blobs)d blobs and "
          "%(elements)d elements equal to dump --json; %(mapped_blobs)d blobs views of the mapping; "
          "%(refused)d files refused (%(broken_seeds)d broken seeds, %(flips)d flipped/truncated/grown copies)"
          % stats + " in %.1f s" % (time.time() - t0))
    if failures:
        print("%d failure(s)" % len(failures))
        return 1
    return 0


def main():
    args = sys.argv[1:]
    if args[:1] == ["--inside"]:
        return inside(*args[1:4])
    if len(args) != 3:
        print("usage: package_reader_test.py DECALPREP SOURCE_ROOT WORK_DIR")
        return 2
    return driver(args[0], os.path.abspath(args[1]), os.path.abspath(args[2]))


if __name__ == "__main__":
    sys.exit(main())
