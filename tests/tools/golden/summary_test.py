#!/usr/bin/env python3
"""`decalprep dump --summary` of the golden scene against an independent read
of the package, and the golden can fail.

Builds tests/tools/golden/scene.toml uncompressed and checks that its summary
is golden.summary.txt. Then, reading the package bytes here (formats/SPEC.md
"File header", "Blob table"; uncompressed, so stored bytes = decoded bytes):
every blob's summary line has the table's count and the XXH64 of its bytes as
computed here (an independent implementation of XXH64, seed 0, after the
xxHash specification), and the manifest lines are the entries of the stored
JSON counted here per layer and action.

Then it rewrites copies of the package with (a) one digit of one manifest
entry's fid changed and (b) one coordinate of one line vertex moved by 1 mm,
both in the middle of their blob (not among the elements the summary shows),
with the blob, table and header checksums recomputed. Each summary must
differ from the golden in exactly the changed blob's line, whose xxh64 must
be that of the changed bytes: so check.sh fails on such a change.

Usage: summary_test.py DECALPREP REPO_ROOT WORK_DIR
"""
import json
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


def blobs_of(package):
    """name -> (count, stored bytes) of an uncompressed package, in table order."""
    h = HEADER.unpack_from(package, 0)
    out = {}
    for k in range(h[6]):
        e = ENTRY.unpack_from(package, h[9] + k * 96)
        assert e[3] == 0, "blob %d is compressed" % k
        out[e[9].rstrip(b"\0").decode()] = (e[4], package[e[5]:e[5] + e[6]])
    return out


ACTIONS = ["repaired", "part_dropped", "dropped", "clipped_away", "note"]  # formats/SPEC.md
STAGES = ["read", "project", "clean", "build"]


def expected_manifest(raw):
    """The summary's manifest lines, from the stored JSON."""
    entries = json.loads(raw.decode("utf-8"))
    layers = {}
    for e in entries:
        m = re.match(r"failed in (\w+): ", e["reason"]) if e["action"] == "dropped" else None
        key = (ACTIONS.index(e["action"]), STAGES.index(m.group(1)) if m else -1,
               e["action"] + (" (failed in %s)" % m.group(1) if m else ""))
        counts = layers.setdefault(e["layer"], {})
        counts[key] = counts.get(key, 0) + 1
    lines = ["  entries %d" % len(entries)]
    for layer, counts in layers.items():
        lines.append("  layer %s: " % json.dumps(layer, ensure_ascii=False) +
                     ", ".join("%s %d" % (k[2], n) for k, n in sorted(counts.items())))
    return lines


def check_independently(lines, package):
    """Problems of the summary `lines` against the package bytes read here."""
    blobs, problems, seen = blobs_of(package), [], []
    for i, line in enumerate(lines):
        m = re.match(r"blob (\S+) id=\d+ type=\w+ stride=\d+ count=(\d+) xxh64=([0-9a-f]{16})$", line)
        if not m:
            continue
        name, count, digest = m.group(1), int(m.group(2)), m.group(3)
        seen.append(name)
        if name not in blobs:
            problems.append("summary lists blob %s, the package has none" % name)
            continue
        want = (blobs[name][0], "%016x" % xxh64(blobs[name][1]))
        if (count, digest) != want:
            problems.append("%s: summary count %d xxh64 %s, package %d %s" % (name, count, digest, *want))
        if name == "manifest_entries":
            want_lines = expected_manifest(blobs[name][1])
            got = lines[i + 1:i + 1 + len(want_lines)]
            if got != want_lines:
                problems.append("manifest lines %s, counted here %s" % (got, want_lines))
    if seen != list(blobs):
        problems.append("summary lists blobs %s, package %s" % (seen, list(blobs)))
    return problems


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
    problems = check_independently(golden, package)
    for p in problems:
        print("FAIL: %s" % p)
    print("%s: every blob's count and xxh64 and the manifest counts agree with the package read here"
          % ("FAIL" if problems else "ok"))

    failures = len(problems)
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
