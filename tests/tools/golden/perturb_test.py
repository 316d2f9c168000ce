#!/usr/bin/env python3
"""The golden summary can fail: one changed manifest entry or one changed blob
element changes `decalprep dump --summary`, so check.sh would fail.

Builds tests/tools/golden/scene.toml uncompressed, checks that its summary is
golden.summary.txt, then rewrites copies of the package with (a) one digit of
one manifest entry's fid changed and (b) one coordinate of one line vertex
moved by 1 mm, both in the middle of their blob (not among the elements the
summary shows), with the blob, table and header checksums recomputed
(formats/SPEC.md "File header", "Blob table"). Each summary must differ from
the golden in exactly the changed blob's line, whose xxh64 must be the XXH64
of the changed bytes as computed here (an independent implementation of
XXH64, seed 0, after the xxHash specification).

Usage: perturb_test.py DECALPREP REPO_ROOT WORK_DIR
"""
import os
import re
import struct
import subprocess
import sys

M = (1 << 64) - 1
P1, P2, P3, P4, P5 = (0x9E3779B185EBCA87, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
                      0x85EBCA77C2B2AE63, 0x27D4EB2F165667C5)


def rotl(x, r):
    return ((x << r) | (x >> (64 - r))) & M


def rnd(acc, lane):
    return rotl((acc + lane * P2) & M, 31) * P1 & M


def xxh64(data, seed=0):
    n, i = len(data), 0
    if n >= 32:
        v = [(seed + P1 + P2) & M, (seed + P2) & M, seed, (seed - P1) & M]
        end = n - n % 32
        v1, v2, v3, v4 = v
        for a, b, c, d in struct.iter_unpack("<4Q", memoryview(data)[:end]):
            v1, v2, v3, v4 = rnd(v1, a), rnd(v2, b), rnd(v3, c), rnd(v4, d)
        h = (rotl(v1, 1) + rotl(v2, 7) + rotl(v3, 12) + rotl(v4, 18)) & M
        for x in (v1, v2, v3, v4):
            h = ((h ^ rnd(0, x)) * P1 + P4) & M
        i = end
    else:
        h = (seed + P5) & M
    h = (h + n) & M
    while i + 8 <= n:
        h = (rotl(h ^ rnd(0, struct.unpack_from("<Q", data, i)[0]), 27) * P1 + P4) & M
        i += 8
    if i + 4 <= n:
        h = (rotl(h ^ (struct.unpack_from("<I", data, i)[0] * P1 & M), 23) * P2 + P3) & M
        i += 4
    while i < n:
        h = rotl(h ^ (data[i] * P5 & M), 11) * P1 & M
        i += 1
    h ^= h >> 33
    h = h * P2 & M
    h ^= h >> 29
    h = h * P3 & M
    return h ^ (h >> 32)


HEADER = struct.Struct("<8sHHIIIII8Q")      # FileHeader, 96 bytes
ENTRY = struct.Struct("<IIIIQQQQQ32sII")    # BlobTableEntry, 96 bytes
assert HEADER.size == 96 and ENTRY.size == 96 and xxh64(b"abc") == 0x44BC2CF5AD770999


def perturb(package, name, change):
    """A copy of the uncompressed `package` bytes with change(bytearray) applied
    to blob `name`'s bytes and every checksum recomputed; also the new bytes."""
    data = bytearray(package)
    h = list(HEADER.unpack_from(data, 0))
    count, table = h[6], h[9]
    for k in range(count):
        e = list(ENTRY.unpack_from(data, table + k * 96))
        if e[9].rstrip(b"\0").decode() != name:
            continue
        assert e[3] == 0, "%s is compressed" % name
        offset, size = e[5], e[6]
        blob = bytearray(data[offset:offset + size])
        change(blob)
        data[offset:offset + size] = blob
        e[8] = xxh64(bytes(blob))
        ENTRY.pack_into(data, table + k * 96, *e)
        h[10] = xxh64(bytes(data[table:table + count * 96]))   # table_checksum
        HEADER.pack_into(data, 0, *h)
        h[15] = xxh64(bytes(data[:88]))                         # header_checksum
        HEADER.pack_into(data, 0, *h)
        return bytes(data), bytes(blob)
    raise SystemExit("no blob %s" % name)


def change_fid(blob):
    """The last digit of the fid of the manifest entry in the middle."""
    fids = list(re.finditer(rb'"fid":(-?[0-9]+)', blob))
    last = fids[len(fids) // 2].end(1) - 1
    blob[last] = ord("0") + (blob[last] - ord("0") + 1) % 10


def move_vertex(blob):
    """x of line vertex count/2, one quantum (1 mm) further east."""
    k = len(blob) // 8 // 2
    x, = struct.unpack_from("<i", blob, k * 8)
    struct.pack_into("<i", blob, k * 8, x + 1)


def summary(tool, path):
    r = subprocess.run([tool, "dump", path, "--summary"], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit("dump --summary %s failed (%d): %s" % (path, r.returncode, r.stderr))
    return r.stdout.splitlines()


def main():
    tool, root, work = sys.argv[1], os.path.abspath(sys.argv[2]), sys.argv[3]
    os.makedirs(work, exist_ok=True)
    here = os.path.join(root, "tests", "tools", "golden")
    base = os.path.join(work, "raw.decals")
    subprocess.run([tool, "build", os.path.join(here, "scene.toml"), "-o", base, "-q",
                    "--threads", "1", "--no-compress"], check=True)
    with open(os.path.join(here, "golden.summary.txt")) as f:
        golden = f.read().replace("<ROOT>", root).splitlines()
    if summary(tool, base) != golden:
        raise SystemExit("the uncompressed build's summary is not golden.summary.txt (check.sh says where)")
    with open(base, "rb") as f:
        package = f.read()

    failures = 0
    for name, change, what in (("manifest_entries", change_fid, "one fid digit of the middle entry"),
                               ("line_vertices", move_vertex, "x of the middle vertex + 1 mm")):
        data, blob = perturb(package, name, change)
        path = os.path.join(work, "perturbed_%s.decals" % name)
        with open(path, "wb") as f:
            f.write(data)
        lines = summary(tool, path)
        diff = [(i, a, b) for i, (a, b) in enumerate(zip(golden, lines)) if a != b]
        expected = "xxh64=%016x" % xxh64(blob)
        ok = (len(lines) == len(golden) and len(diff) == 1 and diff[0][2].startswith("blob %s " % name)
              and diff[0][2].endswith(expected) and not diff[0][1].endswith(expected))
        print("%s: %s: %s" % ("ok" if ok else "FAIL", name, what))
        for i, a, b in diff[:5]:
            print("  line %d: golden   %s\n  line %d: perturbed %s" % (i + 1, a[:200], i + 1, b[:200]))
        if not ok:
            print("  expected exactly that blob's line to change, to %s (%d lines, golden %d)"
                  % (expected, len(lines), len(golden)))
            failures += 1
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
