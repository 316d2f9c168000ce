#!/usr/bin/env python3
"""SpecReader: the independent Python reader (python/decalprep/spec_reader.py,
written from formats/SPEC.md alone) against the real tool.

    spec_reader_test.py DECALPREP SOURCE_ROOT

1. The reader's tables (element types, blob catalogue, records, version)
   agree with the tables of formats/SPEC.md.
2. It builds tests/tools/golden/scene.toml and samples/monaco/scene.toml with
   DECALPREP and collects every *.decals file checked in under tests/,
   samples/ and fuzz/.
3. For each package the Python reader (with SPEC "Index constraints" and the
   metadata checks of `verify`) and `decalprep verify` must give the same
   verdict; a checked-in `valid_*` / `broken_*` file must be accepted /
   rejected by both.
4. For each valid package, the header and table agree field by field with
   `decalprep info --json`, and the metadata and every decoded element
   (records field by field, scene metres of position blobs) with
   `decalprep dump --json` (decoded values are compared, not text).
5. The freshly built packages follow the writer rules of SPEC.md (newest
   version, empty blobs stored as `none`, zstd content checksums, canonical
   metadata, catalogue order, counts, grid).
6. In a copy of each valid package one byte of a blob's stored bytes is
   flipped, and separately one byte of that blob's checksum field in the
   table (once as is, once with the table and header checksums recomputed so
   that only the blob checksum can catch it): the Python reader rejects each
   with the checksum mismatch named, and `decalprep verify` exits non-zero.
   Every valid package laid out again from SPEC (pack below) is
   byte-identical to the tool's.
7. Packages made here from SPEC alone (grown header and entries, unknown
   blobs, flags, reserved fields at the current and at a newer minor, zstd
   frame variants, metadata, names, placement, index constraints) get the
   verdict SPEC gives from both the Python reader and `decalprep verify`.
"""

import json
import os
import re
import struct
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
# The reader is the package python/decalprep, imported from the source tree.
sys.path.insert(0, os.path.join(HERE, "..", "..", "python"))
from decalprep import spec_reader as sr  # noqa: E402

sys.path.insert(0, os.path.join(HERE, "..", "support"))
from checks import check, failures, run  # noqa: E402


# ------------------------------------------------ 1. reader tables vs SPEC --

def spec_tables(spec_text):
    """Rows of every markdown table, grouped by the heading above them."""
    sections, heading = {}, None
    for line in spec_text.splitlines():
        if line.startswith("#"):
            heading = line.lstrip("#").strip()
        elif line.startswith("|") and heading is not None:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if all(re.fullmatch(r":?-+:?", c) for c in cells):
                continue
            sections.setdefault(heading, []).append(cells)
    return sections


# The words SPEC "Manifest entries" lists: {"action": {...}, "stage": {...}}.
MANIFEST_WORDS = {}


def check_reader_tables(spec_text):
    t = spec_tables(spec_text)
    for row in t.get("Manifest entries", []):
        if row[0] in ("action", "stage"):
            key = row[0]
        elif row[0].startswith("`"):
            MANIFEST_WORDS.setdefault(key, set()).add(row[0].strip("`"))
    check(len(MANIFEST_WORDS.get("action", ())) >= 4 and len(MANIFEST_WORDS.get("stage", ())) >= 4,
          "SPEC.md \"Manifest entries\" lists no action/stage words: %s" % MANIFEST_WORDS)
    unq = lambda s: s.strip("`")  # noqa: E731
    m = re.search(r"^Version (\d+)\.(\d+) \(major \d+, minor \d+\)", spec_text, re.M)
    check(m is not None, "SPEC.md has no 'Version X.Y' line")
    spec_major, spec_minor = int(m.group(1)), int(m.group(2))
    check(spec_major == sr.READER_MAJOR, "SPEC major %d != reader major %d" % (spec_major, sr.READER_MAJOR))
    check(sr.READER_MINOR >= spec_minor,
          "SPEC.md is at minor %d but spec_reader.READER_MINOR is %d: review the reader for the new minor"
          % (spec_minor, sr.READER_MINOR))
    types = {int(r[0]): (unq(r[1]), r[3]) for r in t["Element types"][1:]}
    mine = {k: (v[0], str(v[2]) if v[2] else None) for k, v in sr.ELEMENT_TYPES.items()}
    spec_types = {k: (n, s if n != "record" else None) for k, (n, s) in types.items()}
    check(spec_types == mine, "element types differ from SPEC: %s vs %s" % (spec_types, mine))
    cat = {}
    for r in t["Blob catalogue"][1:]:
        cat[int(r[0])] = (unq(r[1]), r[2], int(r[3]), unq(r[4]) or None)
    check(cat == sr.CATALOGUE, "blob catalogue differs from SPEC:\n  spec %s\n  mine %s" % (cat, sr.CATALOGUE))
    sizes = {"f32": ("f", 1), "u32": ("I", 1), "i32": ("i", 1), "f32[2]": ("f", 2), "u32[2]": ("I", 2)}
    for heading, rows in t.items():
        m = re.fullmatch(r"(\w+) \((\d+) bytes; .*\)", heading)
        if not m:
            continue
        name, nbytes = m.group(1), int(m.group(2))
        fields, off = [], 0
        for r in rows[1:]:
            check(int(r[0]) == off, "SPEC record %s: field %s at offset %s, expected %d" % (name, r[2], r[0], off))
            code, n = sizes[r[1]]
            fields.append((unq(r[2]), code, n))
            off += 4 * n
        check(off == nbytes, "SPEC record %s: fields end at %d, heading says %d bytes" % (name, off, nbytes))
        check(sr.RECORDS.get(name) == fields, "record %s differs from SPEC: %s vs %s"
              % (name, fields, sr.RECORDS.get(name)))
    return spec_minor


# ------------------------------------------------------ 3./4. comparisons --

# Blobs whose leading components are positions in quanta (SPEC "Blob
# catalogue" and "LodPoint"): how many.
POSITION_COMPONENTS = {"line_vertices": 2, "qt_leaf_vertices": 2, "lod_points": 2, "dyn_vertices": 3,
                       "qt_node_box": 4, "line_bvh_box": 4, "poly_bvh_box": 4}
FLOAT_TYPES = {"f32", "vec2", "vec4"}


def as_dump(b, elems):
    """The reader's elements in the conventions of `decalprep dump --json`:
    JSON has no NaN/inf (null) and kLodNone is null in LodSegment."""
    has_floats = b.type_name in FLOAT_TYPES or any(
        t == "f" for _, t, _ in sr.RECORDS.get(b.record or "", []))
    if has_floats:
        elems = sr._finite(elems)
    if b.record == "LodSegment":
        elems = [{k: (None if k in ("generator", "splitter") and v == sr.LOD_NONE else v)
                  for k, v in e.items()} for e in elems]
    return elems


def first_difference(a, b):
    if len(a) != len(b):
        return "length %d vs %d" % (len(a), len(b))
    for i, (x, y) in enumerate(zip(a, b)):
        if x != y:
            return "element %d: reader %r, tool %r" % (i, x, y)
    return None


def compare_with_tool(tool, path, p, stats):
    name = os.path.basename(path)
    # Header and table: `decalprep info --json`.
    r = run([tool, "info", "--json", path])
    if not check(r.returncode == 0, "%s: info failed: %s" % (name, r.stderr.decode())):
        return
    info = json.loads(r.stdout)
    h = p.header
    hx = lambda v: "%016x" % v  # noqa: E731
    mine = {"file_size": h["file_size"], "version": {"major": h["version_major"], "minor": h["version_minor"]},
            "flags": h["flags"],
            "header": {"header_size": h["header_size"], "blob_entry_size": h["blob_entry_size"],
                       "blob_count": h["blob_count"], "table_offset": h["table_offset"],
                       "table_xxh64": hx(h["table_checksum"]), "metadata_offset": h["metadata_offset"],
                       "metadata_size": h["metadata_size"], "metadata_xxh64": hx(h["metadata_checksum"]),
                       "header_xxh64": hx(h["header_checksum"])}}
    for k, v in mine.items():
        check(info[k] == v, "%s: header %s: reader %s, info %s" % (name, k, v, info[k]))
    check(info["metadata"] == p.metadata, "%s: metadata differs between reader and info" % name)
    check(len(info["blobs"]) == len(p.blobs),
          "%s: %d blobs in info, %d in reader" % (name, len(info["blobs"]), len(p.blobs)))
    for ib, b in zip(info["blobs"], p.blobs):
        want = {"index": b.index, "id": b.id, "name": b.name, "known": b.known, "type": b.type_name,
                "stride": b.stride, "count": b.count, "codec": sr.CODECS[b.codec], "offset": b.offset,
                "stored_size": b.stored_size, "raw_size": b.raw_size, "xxh64": hx(b.checksum)}
        check(ib == want, "%s: table entry %d: reader %s, info %s" % (name, b.index, want, ib))
    stats["entries"] += len(p.blobs)

    # Elements: `decalprep dump --json`, one blob at a time for big packages
    # (the whole Monaco dump is ~130 MB of JSON).
    per_blob = os.path.getsize(path) > (4 << 20) and p.blobs
    listed = 0
    for only in ([b.name for b in p.blobs] if per_blob else [None]):
        r = run([tool, "dump", "--json", path] + (["--blob", only] if only else []))
        if not check(r.returncode == 0, "%s: dump failed: %s" % (name, r.stderr.decode())):
            return
        d = json.loads(r.stdout)
        del r
        if only is None or only == p.blobs[0].name:
            check(d["version"] == {"major": p.major, "minor": p.minor},
                  "%s: dump version %s, header %d.%d" % (name, d["version"], p.major, p.minor))
            check(d["metadata"] == p.metadata, "%s: metadata differs between reader and dump" % name)
            q = p.metadata.get("quantum_m") if isinstance(p.metadata, dict) else None
            check(d["quantum_m"] == 0.001 and q in (None, 0.001),
                  "%s: quantum_m: dump %s, metadata %s, SPEC 0.001" % (name, d["quantum_m"], q))
        for db in d["blobs"]:
            if check(listed < len(p.blobs), "%s: dump lists more blobs than the reader" % name):
                compare_blob(name, p.blobs[listed], db, stats)
            listed += 1
    check(listed == len(p.blobs), "%s: dump lists %d blobs, reader %d" % (name, listed, len(p.blobs)))


def compare_blob(name, b, db, stats):
    """One blob of the reader against its `dump --json` object."""
    where = "%s: blob %s" % (name, b.name)
    head = {"id": b.id, "name": b.name, "type": b.type_name, "stride": b.stride, "count": b.count}
    check({k: db[k] for k in head} == head, "%s: dump says %s, reader %s"
          % (where, {k: db[k] for k in head}, head))
    elems = sr.elements(b)
    if b.name != "manifest_entries":
        check(len(elems) == b.count, "%s: reader decoded %d elements, count %d" % (where, len(elems), b.count))
    diff = first_difference(as_dump(b, elems), db["elements"])
    check(diff is None, "%s: elements differ: %s" % (where, diff))
    stats["elements"] += len(elems)
    n = POSITION_COMPONENTS.get(b.name)
    if n and b.known:
        check("scene_m" in db, "%s: dump has no scene_m" % where)
        q = 0.001
        if b.record:
            scene = [[e["x"] * q, e["y"] * q] for e in elems]
        else:
            scene = [[c * q for c in e[:n]] for e in elems]
        diff = first_difference(scene, db.get("scene_m", []))
        check(diff is None, "%s: scene metres differ: %s" % (where, diff))
        stats["positions"] += len(scene)
    stats["blobs"] += 1


# ------------------------------------------------------------ 5. writer rules --

def check_writer_rules(path, p, spec_minor):
    name = os.path.basename(path)
    check(p.minor == spec_minor, "%s: written as v%d.%d, but the 'Version' line of SPEC.md says minor %d "
          "(writers write the newest version; bump one of them)" % (name, p.major, p.minor, spec_minor))
    ids = [b.id for b in p.blobs]
    written = [i for i in sr.CATALOGUE if i not in sr.SUPERSEDED]
    check(ids == written, "%s: blobs %s are not every written catalogue blob in catalogue order" % (name, ids))
    for b in p.blobs:
        if b.count == 0:
            check(b.codec == sr.CODEC_NONE and b.stored_size == 0,
                  "%s: empty blob %s stored with codec %d, %d bytes" % (name, b.name, b.codec, b.stored_size))
    with open(path, "rb") as f:
        data = f.read()
    for b in p.blobs:
        if b.codec == sr.CODEC_ZSTD:
            fp = sr.zstandard.get_frame_parameters(data[b.offset:b.offset + b.stored_size])
            check(fp.has_checksum, "%s: zstd frame of %s has no content checksum" % (name, b.name))
    # Canonical metadata: sorted keys, no insignificant whitespace.
    text = p.metadata_bytes.decode("utf-8")

    def pairs(kv):
        keys = [k for k, _ in kv]
        check(keys == sorted(keys), "%s: metadata keys not sorted: %s" % (name, keys[:8]))
        return dict(kv)
    json.loads(text, object_pairs_hook=pairs)
    outside = re.sub(r'"(?:[^"\\]|\\.)*"', '""', text)
    check(not re.search(r"\s", outside), "%s: metadata has whitespace outside strings" % name)
    m = p.metadata
    for key, typ in (("format", str), ("quantum_m", float), ("crs_wkt", str), ("frame", str), ("origin", dict),
                     ("extent", list), ("grid", dict), ("max_representation_error_m", float),
                     ("terrain", dict), ("counts", dict), ("manifest", dict)):
        check(isinstance(m.get(key), typ),
              "%s: metadata %s is %r, SPEC says %s" % (name, key, m.get(key), typ.__name__))
    check(m["format"] == "decals" and m["quantum_m"] == 0.001, "%s: format/quantum_m" % name)
    for b in p.blobs:
        check(m["counts"].get(b.name) == b.count, "%s: counts.%s = %s, blob has %d"
              % (name, b.name, m["counts"].get(b.name), b.count))
    for k in ("lines", "polygons", "dynamic_lines", "lod_lines"):
        check(isinstance(m["counts"].get(k), int), "%s: counts.%s missing" % (name, k))
    grid = m["grid"]
    cells = grid["dims"][0] * grid["dims"][1]
    for per_cell in ("cell_line_first", "cell_poly_first"):
        check(p.count(per_cell) in (0, cells + 1), "%s: %s has %d elements, the grid %d cells"
              % (name, per_cell, p.count(per_cell), cells))
    check_record_rules(name, p)
    man = m["manifest"]
    entries = sr.elements(p.blob("manifest_entries"))
    check(man["entry_count"] == len(entries), "%s: manifest entry_count %s, %d entries"
          % (name, man["entry_count"], len(entries)))
    for e in entries:
        check(e["action"] in MANIFEST_WORDS["action"], "%s: manifest action %r is not one SPEC lists"
              % (name, e["action"]))
        f = re.match(r"failed in (\w+): ", e["reason"])
        check(f is None or (e["action"] == "dropped" and f.group(1) in MANIFEST_WORDS["stage"]),
              "%s: manifest failure %r: not a dropped entry with a stage SPEC lists" % (name, e["reason"]))
    for layer in man["layers"]:
        check(layer["read"] == layer["kept"] + layer["clipped_away"] + layer["dropped"],
              "%s: manifest layer %s: read != kept + clipped_away + dropped" % (name, layer["layer"]))


def check_record_rules(name, p):
    """What SPEC "Records" and the catalogue say of the record values."""
    lines = sr.elements(p.blob("line_props"))
    nq = p.count("qt_node")
    for kind, recs in (("line_props", lines), ("dyn_line_props", sr.elements(p.blob("dyn_line_props")))):
        for i, r in enumerate(recs):
            st = r["style"]
            ok = (st & 3) != 3 and (st >> 2 & 3) != 3 and st >> 7 == 0
            ok = ok and (not st & 0x40 or st & 0x20)  # bit 6 only with bit 5
            if st & 0x20:  # clipped: a closed inset/offset ring with a tree
                ok = ok and kind == "line_props" and st & 0x10 and (st >> 2 & 3) in (1, 2) and r["clip_node"] < nq
            else:
                ok = ok and r["clip_node"] == 0
            if not check(ok, "%s: %s[%d]: style 0x%x / clip_node %d break SPEC LineProps"
                         % (name, kind, i, st, r["clip_node"])):
                break
        orders = [r["order"] for r in recs]
        check(len(set(orders)) == len(orders), "%s: %s orders are not unique" % (name, kind))
    polys = sr.elements(p.blob("poly_props"))
    for i, r in enumerate(polys):
        e = r["exterior"]
        ok = e == -1 or (polys[e]["exterior"] == -1 and r["rgba"] == 0)
        if not check(ok, "%s: poly_props[%d] %s: an interior must link an exterior and have rgba 0" % (name, i, r)):
            break
    exterior_orders = [r["order"] for r in polys if r["exterior"] == -1]
    check(len(set(exterior_orders)) == len(exterior_orders), "%s: exterior polygon orders are not unique" % name)
    if p.minor >= 2:  # v1.2: one rank space for static lines and exterior polygons
        both = [r["order"] for r in lines] + exterior_orders
        check(len(set(both)) == len(both), "%s: v1.2 ranks of static lines and exterior polygons collide" % name)
        for i, r in enumerate(polys):
            if r["exterior"] != -1 and not check(r["order"] == polys[r["exterior"]]["order"],
                                                 "%s: interior poly_props[%d] does not carry its exterior's rank"
                                                 % (name, i)):
                break
    # cell_segments: per cell, sorted by the line's drawing order, then segment.
    vline = sr.elements(p.blob("line_vertex_line"))
    segs = sr.elements(p.blob("cell_segments"))
    firsts = sr.elements(p.blob("cell_line_first")) if p.blob("cell_line_first") else []
    for c, (first, n) in enumerate((a[0], b[0] - a[0]) for a, b in zip(firsts, firsts[1:])):
        keys = [(lines[vline[a]]["order"], a) for a, _ in segs[first:first + n]]
        if not check(keys == sorted(keys), "%s: cell %d: cell_segments not sorted by (line order, segment): %s"
                     % (name, c, keys[:6])):
            break


# ------------------------------------------------------------------ 6. flips --

def flipped(data, pos):
    b = bytearray(data)
    b[pos] ^= 0xFF
    return b


def reseal(b, h):
    """Recomputes the table and header checksums of package bytes `b`."""
    hs, n, es = h["header_size"], h["blob_count"], h["blob_entry_size"]
    struct.pack_into("<Q", b, 48, sr.xxh64(bytes(b[hs:hs + n * es])))
    struct.pack_into("<Q", b, hs - 8, sr.xxh64(bytes(b[:hs - 8])))
    return b


def check_flips(tool, path, p, tmp, stats):
    name = os.path.basename(path)
    with open(path, "rb") as f:
        data = f.read()
    nonempty = [b for b in p.blobs if b.stored_size]
    if not nonempty:
        return
    h = p.header
    picks = {max(nonempty, key=lambda b: b.stored_size).index}
    picks |= {b.index for b in nonempty if b.codec == sr.CODEC_NONE}
    for i in sorted(picks)[:2]:
        b = p.blobs[i]
        entry_checksum = h["table_offset"] + b.index * h["blob_entry_size"] + 48
        cases = [
            ("byte %d of blob %s's stored bytes" % (b.stored_size // 2, b.name),
             flipped(data, b.offset + b.stored_size // 2), "blob %d '%s': checksum" % (b.index, b.name)),
            ("byte 3 of blob %s's checksum field" % b.name, flipped(data, entry_checksum + 3),
             "table_checksum (offset 48) mismatch"),
            ("byte 3 of blob %s's checksum field, table and header resealed" % b.name,
             reseal(flipped(data, entry_checksum + 3), h), "blob %d '%s': checksum" % (b.index, b.name)),
        ]
        for what, bad, expect in cases:
            bad_path = os.path.join(tmp, "flipped.decals")
            with open(bad_path, "wb") as f:
                f.write(bad)
            try:
                sr.read_package(bytes(bad), name)
                check(False, "%s: reader accepted a file with %s flipped" % (name, what))
            except sr.FormatError as e:
                check(expect in str(e) and "mismatch" in str(e),
                      "%s, %s flipped: reader says '%s', expected '%s ... mismatch'" % (name, what, e, expect))
            r = run([tool, "verify", bad_path])
            check(r.returncode != 0, "%s: decalprep verify accepted a file with %s flipped" % (name, what))
            stats["flips"] += 1


# ------------------------------------------------- 7. packages made here --

def pack(blobs, metadata, minor, flags=0, header_size=96, entry_size=96, header_extra=b"",
         entry_extra=b"", reserved0=0, reserved1=0, major=1, trailing=b""):
    """A package laid out as SPEC "File structure" says. `blobs`: dicts with
    id, element_type, stride, codec, count, raw_size, stored, name and
    optional reserved (u32 pair) and pad (extra zero bytes before the blob)."""
    n = len(blobs)
    meta_off = header_size + n * entry_size
    pos, offsets = meta_off + len(metadata), []
    for b in blobs:
        pos = sr.align256(pos) + b.get("pad", 0)
        offsets.append(pos)
        pos += len(b["stored"])
    file_size = pos + len(trailing)
    table = bytearray()
    for b, off in zip(blobs, offsets):
        name = b["name"].encode() if isinstance(b["name"], str) else b["name"]
        table += struct.pack("<4I5Q", b["id"], b["element_type"], b["stride"], b["codec"], b["count"], off,
                             len(b["stored"]), b["raw_size"], sr.xxh64(b["stored"]))
        table += name.ljust(32, b"\0")[:32] + struct.pack("<2I", *b.get("reserved", (0, 0)))
        table += entry_extra.ljust(entry_size - 96, b"\0")
    head = bytearray(sr.MAGIC + struct.pack("<2H5I", major, minor, flags, header_size, entry_size, n, reserved0))
    head += struct.pack("<7Q", file_size, header_size, sr.xxh64(bytes(table)), meta_off, len(metadata),
                        sr.xxh64(metadata), reserved1)
    head += header_extra.ljust(header_size - 96, b"\0")
    head += struct.pack("<Q", sr.xxh64(bytes(head)))
    out = bytearray(head + table + metadata)
    for b, off in zip(blobs, offsets):
        out += bytes(off - len(out)) + b["stored"]
    return bytes(out + trailing)


def blob_dicts(p, data):
    return [dict(id=b.id, element_type=b.element_type, stride=b.stride, codec=b.codec, count=b.count,
                 raw_size=b.raw_size, stored=data[b.offset:b.offset + b.stored_size], name=b.name)
            for b in p.blobs]


def zframe(raw, content_size=True):
    return sr.zstandard.ZstdCompressor(write_checksum=True, write_content_size=content_size).compress(raw)


def check_made_packages(tool, base_path, tmp, cur_minor, stats):
    """Variants of a valid package, each built from SPEC alone, with the
    verdict SPEC gives; the reader and `decalprep verify` must both give it."""
    with open(base_path, "rb") as f:
        data = f.read()
    p = sr.read_file(base_path)
    meta = p.metadata_bytes
    newer = 9  # a minor version newer than any reader's
    bl = lambda: blob_dicts(p, data)  # noqa: E731

    def with_blob(i, **kw):
        b = bl()
        b[i].update(kw)
        return b

    def first(pred):
        return [i for i, b in enumerate(p.blobs) if pred(b)][0]
    z = first(lambda b: b.codec == sr.CODEC_ZSTD and b.count > 1)
    zb = p.blobs[z]
    unknown_rec = dict(id=99, element_type=sr.RECORD, stride=12, codec=0, count=3, raw_size=36,
                       stored=bytes(range(36)), name="blob_99")
    unknown_u32 = dict(id=77, element_type=2, stride=4, codec=1, count=4, raw_size=16,
                       stored=zframe(struct.pack("<4I", 1, 2, 3, 0xFFFFFFFF)), name="future_thing")
    none_blobs = [dict(b, codec=0, stored=bb.data) for b, bb in zip(bl(), p.blobs)]
    split = zb.raw_size // 2

    def patched(name, *edits):
        """The blobs with fields (offset, struct format, value) of blob
        `name`'s raw bytes changed (stored as codec none)."""
        i = first(lambda b: b.name == name)
        raw = bytearray(p.blobs[i].data)
        for offset, fmt, value in edits:
            struct.pack_into("<" + fmt, raw, offset, value)
        return with_blob(i, codec=0, stored=bytes(raw))
    lp = first(lambda b: b.name == "line_props")
    unclipped = [k for k, r in enumerate(sr.elements(p.blobs[lp])) if not r["style"] & 0x20][0]
    nq = p.count("qt_node")
    cases = [
        ("identity", pack(bl(), meta, p.minor), True),
        ("header grown to 104 bytes, zero", pack(bl(), meta, cur_minor, header_size=104), True),
        ("header grown, non-zero, current minor", pack(bl(), meta, cur_minor, header_size=104,
                                                       header_extra=b"\1"), False),
        ("header grown, non-zero, newer minor", pack(bl(), meta, newer, header_size=104, header_extra=b"\1"), True),
        ("header_size 100", pack(bl(), meta, cur_minor, header_size=100), False),
        ("entries grown to 112 bytes, zero", pack(bl(), meta, cur_minor, entry_size=112), True),
        ("entries grown, non-zero, current minor", pack(bl(), meta, cur_minor, entry_size=112,
                                                        entry_extra=b"\0\0\5"), False),
        ("entries grown, non-zero, newer minor", pack(bl(), meta, newer, entry_size=112,
                                                      entry_extra=b"\0\0\5"), True),
        ("unknown record blob 99", pack(bl() + [unknown_rec], meta, cur_minor), True),
        ("unknown zstd u32 blob 77 named future_thing", pack(bl() + [unknown_u32], meta, cur_minor), True),
        ("unknown blob with a record stride of 10", pack(bl() + [dict(unknown_rec, stride=10, count=3, raw_size=30,
                                                                        stored=bytes(30))], meta, cur_minor), False),
        ("unknown blob of element type 12", pack(bl() + [dict(unknown_rec, element_type=12)], meta, cur_minor), False),
        ("optional flag 17, current minor", pack(bl(), meta, cur_minor, flags=1 << 17), False),
        ("optional flag 17, newer minor", pack(bl(), meta, newer, flags=1 << 17), True),
        ("required flag 3, newer minor", pack(bl(), meta, newer, flags=1 << 3), False),
        ("all_uncompressed, all none", pack(none_blobs, meta, cur_minor, flags=sr.FLAG_ALL_UNCOMPRESSED), True),
        ("all_uncompressed with a zstd blob", pack(bl(), meta, cur_minor, flags=sr.FLAG_ALL_UNCOMPRESSED), False),
        ("reserved0, current minor", pack(bl(), meta, cur_minor, reserved0=1), False),
        ("reserved0, newer minor", pack(bl(), meta, newer, reserved0=1), True),
        ("reserved1, current minor", pack(bl(), meta, cur_minor, reserved1=1 << 40), False),
        ("reserved1, newer minor", pack(bl(), meta, newer, reserved1=1 << 40), True),
        ("entry reserved, current minor", pack(with_blob(0, reserved=(0, 7)), meta, cur_minor), False),
        ("entry reserved, newer minor", pack(with_blob(0, reserved=(0, 7)), meta, newer), True),
        ("major 2", pack(bl(), meta, 0, major=2), False),
        ("major 0", pack(bl(), meta, 1, major=0), False),
        ("zstd frame without content size", pack(with_blob(z, stored=zframe(zb.data, False)), meta, cur_minor), False),
        ("zstd frame and a trailing byte", pack(with_blob(z, stored=zframe(zb.data) + b"\0"), meta, cur_minor), False),
        ("two zstd frames", pack(with_blob(z, stored=zframe(zb.data[:split]) + zframe(zb.data[split:])), meta,
                                 cur_minor), False),
        ("zstd frame of other content size", pack(with_blob(z, stored=zframe(zb.data + b"\0" * zb.stride)), meta,
                                                  cur_minor), False),
        ("zstd frame re-made (other level)", pack(with_blob(z, stored=zframe(zb.data)), meta, cur_minor), True),
        ("codec none with stored != raw", pack(with_blob(z, codec=0, stored=zb.data + b"\0"), meta, cur_minor), False),
        ("codec 2", pack(with_blob(z, codec=2), meta, cur_minor), False),
        ("empty blob stored as a zstd frame", pack(bl() + [dict(unknown_u32, count=0, raw_size=0, stored=zframe(b""))],
                                                   meta, cur_minor), True),
        ("metadata with a NUL", pack(bl(), meta[:-1] + b',"x":"\0"}', cur_minor), False),
        ("metadata with a leading space", pack(bl(), b" " + meta, cur_minor), False),
        ("metadata not JSON", pack(bl(), b"{oops}", cur_minor), False),
        ("metadata counts disagree", pack(bl(), meta.replace(b'"line_vertices":%d' % p.count("line_vertices"),
                                                             b'"line_vertices":%d' % (p.count("line_vertices") + 1)),
                                          cur_minor), False),
        ("metadata format other", pack(bl(), meta.replace(b'"format":"decals"', b'"format":"decal"'), cur_minor),
         False),
        ("metadata {} only", pack(bl(), b"{}", cur_minor), True),
        ("name in capitals", pack(with_blob(z, name="BLOB_99"), meta, cur_minor), False),
        ("known id with another name", pack(with_blob(z, name="something_else"), meta, cur_minor), False),
        ("name of 32 characters", pack(bl() + [dict(unknown_rec, name="a" * 32)], meta, cur_minor), False),
        ("name with a byte after its NUL", pack(bl() + [dict(unknown_rec, name=b"blob_99\0x")], meta, cur_minor),
         False),
        ("empty name", pack(bl() + [dict(unknown_rec, name="")], meta, cur_minor), False),
        ("duplicate id", pack(bl() + [dict(bl()[z])], meta, cur_minor), False),
        ("stride of a known id changed", pack(with_blob(z, stride=zb.stride * 2, count=zb.count // 2), meta,
                                              cur_minor), False),
        ("raw_size != count x stride", pack(with_blob(z, count=zb.count - 1), meta, cur_minor), False),
        ("256 more bytes of padding", pack(with_blob(z, pad=256), meta, cur_minor), False),
        ("a trailing byte", pack(bl(), meta, cur_minor, trailing=b"\0"), False),
        ("zstd codec with stored_size 0", pack(bl() + [dict(unknown_u32, count=0, raw_size=0, stored=b"")], meta,
                                               cur_minor), False),
        ("PolyProps reserved, current minor", pack(patched("poly_props", (28, "I", 5)), meta, cur_minor), False),
        ("PolyProps reserved, newer minor", pack(patched("poly_props", (28, "I", 5)), meta, newer), True),
        ("LineProps clip_node without bit 5, current minor",
         pack(patched("line_props", (unclipped * 32 + 28, "I", 1)), meta, cur_minor), False),
        ("LineProps clip_node without bit 5, newer minor",
         pack(patched("line_props", (unclipped * 32 + 28, "I", 1)), meta, newer), True),
        ("LineProps clip_node in range with bit 5",
         pack(patched("line_props", (unclipped * 32 + 12, "I", 0x35), (unclipped * 32 + 28, "I", nq - 1)), meta,
              cur_minor), True),
        ("LineProps clip_node past qt_node with bit 5, newer minor",
         pack(patched("line_props", (unclipped * 32 + 12, "I", 0x35), (unclipped * 32 + 28, "I", nq)), meta,
              newer), False),
        ("dyn_line_props clip_node, current minor", pack(patched("dyn_line_props", (28, "I", 1)), meta, cur_minor),
         False),
        ("dyn_line_props clip_node, newer minor", pack(patched("dyn_line_props", (28, "I", 1)), meta, newer), True),
        ("LodPoint flags bit 1, newer minor", pack(patched("lod_points", (28, "I", 2)), meta, newer), False),
        ("LodSegment splitter kLodNone", pack(patched("lod_segments", (12, "I", sr.LOD_NONE)), meta, cur_minor),
         True),
        ("LodSegment a = kLodNone", pack(patched("lod_segments", (0, "I", sr.LOD_NONE)), meta, cur_minor), False),
        ("cell_poly_holes past cell_holes", pack(patched("cell_poly_holes", (4, "I", p.count("cell_holes") + 1)),
                                                 meta, cur_minor), False),
        ("qt_leaf_loops past qt_leaf_vertices", pack(patched("qt_leaf_loops", (0, "I", p.count("qt_leaf_vertices")
                                                                               + 1)), meta, cur_minor), False),
        ("cell_line_first not a full tree", pack(patched("cell_line_first", (12, "I", 2)), meta, cur_minor), False),
        ("line_bvh_box16 any u16 box", pack(patched("line_bvh_box16", (0, "I", 0x12345678)), meta, cur_minor), True),
        ("qt_node type 4", pack(patched("qt_node", (0, "i", 4)), meta, cur_minor), False),
        ("dyn_prev_next -2", pack(patched("dyn_prev_next", (0, "i", -2)), meta, cur_minor), False),
        ("dyn_vertices line -1", pack(patched("dyn_vertices", (12, "i", -1)), meta, cur_minor), False),
        ("no blobs", pack([], meta, cur_minor), True),
        ("no blobs, metadata {}", pack([], b"{}", cur_minor), True),
    ]
    path = os.path.join(tmp, "made.decals")
    for what, made, want in cases:
        with open(path, "wb") as f:
            f.write(made)
        ok, q, msg = python_verdict(path)
        r = run([tool, "verify", path])
        tool_ok = r.returncode == 0
        check(ok == want and tool_ok == want,
              "made package '%s': SPEC says %s, reader %s (%s), decalprep verify %s (rc %d: %s)"
              % (what, "valid" if want else "invalid", "accepts" if ok else "rejects", msg,
                 "accepts" if tool_ok else "rejects", r.returncode, (r.stdout + r.stderr).decode().strip()[-300:]))
        if what == "identity":
            check(made == data, "%s: the package re-laid out from SPEC is not byte-identical" % base_path)
        if ok and tool_ok and q is not None and what.startswith("unknown"):
            compare_with_tool(tool, path, q, stats)
        stats["made"] += 1


# -------------------------------------------------------------------- main --

def python_verdict(path):
    """(accepted, Package or None, message)."""
    try:
        p = sr.read_file(path)
    except sr.FormatError as e:
        return False, None, str(e)
    errs = sr.check_indices(p) + sr.check_metadata(p)
    return not errs, p, "; ".join(errs)


def main():
    if len(sys.argv) != 3:
        print("usage: spec_reader_test.py DECALPREP SOURCE_ROOT")
        return 2
    tool, root = sys.argv[1], os.path.abspath(sys.argv[2])
    t0 = time.time()
    # Known-answer values of XXH64 (xxHash 0.8, seed 0) and a zstd round trip,
    # so that a broken module cannot make both sides agree on nothing.
    check(sr.xxh64(b"") == 0xEF46DB3751D8E999, "XXH64('') is wrong")
    check(sr.xxh64(b"abc") == 0x44BC2CF5AD770999, "XXH64('abc') is wrong")
    with open(os.path.join(root, "formats", "SPEC.md"), encoding="utf-8") as f:
        spec_minor = check_reader_tables(f.read())

    stats = dict(made=0, packages=0, valid=0, rejected=0, entries=0, blobs=0, elements=0, positions=0, flips=0)
    with tempfile.TemporaryDirectory(prefix="spec_reader_") as tmp:
        built = []
        for scene, out in (("tests/tools/golden/scene.toml", "golden.decals"),
                           ("samples/monaco/scene.toml", "monaco.decals")):
            path = os.path.join(tmp, out)
            t = time.time()
            r = run([tool, "build", os.path.join(root, scene), "-o", path, "-q"])
            if not check(r.returncode == 0, "build of %s failed: %s" % (scene, r.stderr.decode()[-2000:])):
                continue
            print("built %s in %.1f s" % (scene, time.time() - t), flush=True)
            built.append(path)
        checked_in = []
        for top in ("tests", "samples", "fuzz"):
            for d, _, files in os.walk(os.path.join(root, top)):
                checked_in += [os.path.join(d, f) for f in files if f.endswith(".decals")]
        checked_in.sort()
        check(checked_in, "no checked-in *.decals found under tests/, samples/, fuzz/")

        for path in built + checked_in:
            name = os.path.relpath(path, root) if path.startswith(root) else os.path.basename(path)
            ok, p, msg = python_verdict(path)
            r = run([tool, "verify", path])
            tool_ok = r.returncode == 0
            check(ok == tool_ok, "%s: reader %s (%s) but decalprep verify %s (rc %d: %s)"
                  % (name, "accepts" if ok else "rejects", msg, "accepts" if tool_ok else "rejects",
                     r.returncode, (r.stdout + r.stderr).decode().strip()))
            base = os.path.basename(path)
            if base.startswith("broken_"):
                check(not ok, "%s: the reader accepts a broken seed" % name)
            if base.startswith("valid_") or path in built:
                check(ok, "%s: the reader rejects a valid package: %s" % (name, msg))
            print("%-60s reader %-8s verify %s%s" % (name, "ok" if ok else "rejects", "ok" if tool_ok else "rejects",
                                                     "" if ok else "  [" + msg[-110:] + "]"), flush=True)
            stats["packages"] += 1
            t = time.time()
            if not ok:
                stats["rejected"] += 1
                continue
            stats["valid"] += 1
            compare_with_tool(tool, path, p, stats)
            if path in built:
                check_writer_rules(path, p, spec_minor)
            check_flips(tool, path, p, tmp, stats)
            print("  compared with info/dump, writer rules, flips: %.1f s" % (time.time() - t), flush=True)
            with open(path, "rb") as f:
                data = f.read()
            check(pack(blob_dicts(p, data), p.metadata_bytes, p.minor, flags=p.header["flags"]) == data,
                  "%s: the package re-laid out from SPEC is not byte-identical" % name)
        seed = os.path.join(root, "fuzz", "corpus", "read", "valid_small_zstd.decals")
        if check(os.path.exists(seed), "%s is missing" % seed):
            t = time.time()
            check_made_packages(tool, seed, tmp, spec_minor, stats)
            print("%d packages made from SPEC: %.1f s" % (stats["made"], time.time() - t), flush=True)

    print("spec_reader: %(packages)d packages (%(valid)d valid, %(rejected)d rejected by both), "
          "%(entries)d table entries and %(blobs)d blobs compared, %(elements)d elements and "
          "%(positions)d scene positions compared, %(flips)d flipped copies rejected, "
          "%(made)d packages made from SPEC judged alike" % stats
          + " in %.1f s" % (time.time() - t0))
    if failures:
        print("%d failure(s)" % len(failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
