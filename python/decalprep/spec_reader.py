"""The validating reader of `.decals` packages, written from formats/SPEC.md
alone (no code of the project's own C++ reader was consulted or ported), so
that it is a second oracle for that reader and for `decalprep verify` /
`dump` (tests/formats/spec_reader_test.py holds the two to each other).

It checks everything in SPEC.md "Validation" in the order given there
(magic, version, header size and checksum, file size, flags and reserved
fields, blob table, metadata, every entry, every blob's checksum and codec),
decodes the element types and records of SPEC.md "Records" into numpy
arrays, and applies SPEC.md "Index constraints" (`check_indices`) and the
metadata checks of `verify` (`check_metadata`).

`read_package` reads any buffer: bytes, or an mmap (decalprep.package), in
which case the blobs stored with codec `none` stay views of the mapping and
are never copied.

Dependencies are Debian 12 packages only (scripts/deps): python3-xxhash for
XXH64 (xxHash 0.8, seed 0), python3-zstandard for Zstandard frames and
python3-numpy for the element arrays.
"""

import json
import math
import re
import struct
import sys
from array import array

try:
    import numpy as np
    import xxhash
    import zstandard
except ImportError as e:  # pragma: no cover - reported by the callers
    sys.stderr.write(
        "decalprep: %s; install the Debian packages python3-numpy, python3-xxhash and "
        "python3-zstandard (scripts/deps) and run with the system python3\n" % e)
    raise

# ----------------------------------------------------------------- constants --

MAGIC = bytes([0x89, 0x44, 0x43, 0x4C, 0x0D, 0x0A, 0x1A, 0x0A])  # SPEC "Magic number"
READER_MAJOR = 1
# The newest minor version this reader knows. 1.1 gave LineProps::reserved a
# meaning (clip_node); 1.2 changed only the meaning of the `order` fields, so
# the layout a 1.2 reader checks is that of 1.1. 1.3 added the compact
# blobs (SPEC "Compact layout (v1.3)").
READER_MINOR = 3
HEADER_SIZE_V1 = 96
ENTRY_SIZE_V1 = 96
ALIGN = 256
METADATA_MAX = 16 * 1024 * 1024  # SPEC "Metadata": 16 MiB
FLAG_ALL_UNCOMPRESSED = 1 << 16  # SPEC "Flags": the only defined flag
KNOWN_FLAGS = FLAG_ALL_UNCOMPRESSED
CODEC_NONE, CODEC_ZSTD = 0, 1
CODECS = {CODEC_NONE: "none", CODEC_ZSTD: "zstd"}
LOD_NONE = 0xFFFFFFFF  # kLodNone
U64_MAX = (1 << 64) - 1

# SPEC "Element types": value -> (name, struct format of one element, stride).
# The record stride is given by the blob id.
RECORD = 11
ELEMENT_TYPES = {
    1: ("u8", "B", 1),
    2: ("u32", "I", 4),
    3: ("i32", "i", 4),
    4: ("f32", "f", 4),
    5: ("ivec2", "2i", 8),
    6: ("uvec2", "2I", 8),
    7: ("ivec4", "4i", 16),
    8: ("uvec4", "4I", 16),
    9: ("vec2", "2f", 8),
    10: ("vec4", "4f", 16),
    RECORD: ("record", None, None),
}
TYPE_BY_NAME = {v[0]: k for k, v in ELEMENT_TYPES.items()}

# SPEC "Blob catalogue": id -> (name, element type name, stride, record name).
CATALOGUE = {
    1: ("line_vertices", "ivec2", 8, None),
    2: ("line_vertex_line", "u32", 4, None),
    3: ("line_props", "record", 32, "LineProps"),
    4: ("line_corners", "record", 24, "LineCorner"),
    5: ("cell_segment_range", "uvec2", 8, None),
    6: ("cell_segments", "uvec2", 8, None),
    7: ("cell_line_first", "uvec2", 8, None),
    10: ("poly_props", "record", 32, "PolyProps"),
    11: ("poly_root_node", "u32", 4, None),
    12: ("qt_node_box", "ivec4", 16, None),
    13: ("qt_node", "ivec2", 8, None),
    14: ("qt_leaf_range", "uvec2", 8, None),
    15: ("qt_leaf_segments", "uvec2", 8, None),
    16: ("qt_leaf_vertices", "ivec2", 8, None),
    17: ("cell_poly_range", "uvec2", 8, None),
    18: ("cell_polys", "uvec4", 16, None),
    19: ("cell_holes", "uvec2", 8, None),
    20: ("line_bvh_range", "uvec4", 16, None),
    21: ("line_bvh_box", "ivec4", 16, None),
    22: ("poly_bvh_range", "uvec4", 16, None),
    23: ("poly_bvh_box", "ivec4", 16, None),
    24: ("qt_leaf_loop_range", "uvec2", 8, None),
    25: ("qt_leaf_loops", "u32", 4, None),
    26: ("cell_poly_first", "uvec2", 8, None),
    27: ("line_bvh_box16", "uvec2", 8, None),
    28: ("poly_bvh_box16", "uvec2", 8, None),
    29: ("cell_poly_entries", "uvec2", 8, None),
    9: ("cell_poly_holes", "u32", 4, None),
    30: ("dyn_vertices", "ivec4", 16, None),
    31: ("dyn_prev_next", "ivec2", 8, None),
    32: ("dyn_line_start", "u32", 4, None),
    33: ("dyn_line_props", "record", 32, "LineProps"),
    40: ("lod_points", "record", 32, "LodPoint"),
    41: ("lod_segments", "record", 16, "LodSegment"),
    42: ("lod_line_range", "uvec2", 8, None),
    50: ("manifest_entries", "u8", 1, None),
}
ID_BY_NAME = {v[0]: k for k, v in CATALOGUE.items()}
# SPEC "Blob catalogue": the ids the v1.3 layout replaced; a v1.3 writer
# does not write them.
SUPERSEDED = {5, 14, 15, 17, 18, 20, 21, 22, 23}

# SPEC "Records": (field, struct format, components). A field of one
# component decodes to a scalar, of more to a list.
RECORDS = {
    "LineProps": [("half_width", "f", 1), ("rgba", "I", 1), ("order", "I", 1), ("style", "I", 1),
                  ("value", "f", 1), ("layer", "I", 1), ("feature", "I", 1), ("clip_node", "I", 1)],
    "LineCorner": [("miter", "f", 2), ("bevel_in", "f", 2), ("bevel_out", "f", 2)],
    "PolyProps": [("rgba", "I", 1), ("order", "I", 1), ("exterior", "i", 1), ("value", "f", 1),
                  ("layer", "I", 1), ("feature", "I", 1), ("reserved", "I", 2)],
    "LodPoint": [("x", "i", 1), ("y", "i", 1), ("eval_x", "i", 1), ("eval_y", "i", 1),
                 ("e_star", "f", 1), ("d_star", "f", 1), ("line", "I", 1), ("flags", "I", 1)],
    "LodSegment": [("a", "I", 1), ("b", "I", 1), ("generator", "I", 1), ("splitter", "I", 1)],
}

# SPEC "File header": (offset, struct format, field).
HEADER_FIELDS = [
    (8, "H", "version_major"), (10, "H", "version_minor"), (12, "I", "flags"),
    (16, "I", "header_size"), (20, "I", "blob_entry_size"), (24, "I", "blob_count"),
    (28, "I", "reserved0"), (32, "Q", "file_size"), (40, "Q", "table_offset"),
    (48, "Q", "table_checksum"), (56, "Q", "metadata_offset"), (64, "Q", "metadata_size"),
    (72, "Q", "metadata_checksum"), (80, "Q", "reserved1"),
]
# SPEC "Blob table": (offset, struct format, field); name and reserved apart.
ENTRY_FIELDS = [
    (0, "I", "id"), (4, "I", "element_type"), (8, "I", "stride"), (12, "I", "codec"),
    (16, "Q", "count"), (24, "Q", "offset"), (32, "Q", "stored_size"), (40, "Q", "raw_size"),
    (48, "Q", "checksum"),
]
NAME_RE = re.compile(rb"[a-z0-9_]{1,31}")


class FormatError(ValueError):
    """The file is not a valid package (or tileset); the message names the
    field, its byte offset or blob, and the bad value (SPEC "Validation")."""


def xxh64(data):
    return xxhash.xxh64_intdigest(data, seed=0)


def align256(x):
    return (x + ALIGN - 1) // ALIGN * ALIGN


def u(data, off, fmt):
    return struct.unpack_from("<" + fmt, data, off)[0]


def element_dtype(element_type, record=None, stride=None):
    """The numpy dtype of one element (SPEC "Element types", "Records"),
    little-endian explicitly, and the element shape: () for one-component
    types and records, (n,) for vectors. A record this reader does not know
    is `stride` opaque bytes."""
    if element_type == RECORD:
        if record is None:
            return np.dtype((np.void, stride)), ()
        fields = [(name, "<" + {"f": "f4", "I": "u4", "i": "i4"}[t], (c,) if c > 1 else ())
                  for name, t, c in RECORDS[record]]
        return np.dtype(fields), ()
    fmt = ELEMENT_TYPES[element_type][1]
    n = int(fmt[0]) if fmt[0].isdigit() else 1
    base = {"B": "u1", "I": "<u4", "i": "<i4", "f": "<f4"}[fmt[-1]]
    return np.dtype(base), ((n,) if n > 1 else ())


class Blob:
    """One blob: its table entry fields (`id`, `element_type`, `stride`,
    `codec`, `count`, `offset`, `stored_size`, `raw_size`, `checksum`), its
    `name`, and its decoded bytes `data`: a view of the file's buffer for
    codec `none`, fresh bytes for `zstd`."""

    def __init__(self, index, entry):
        self.index = index
        self.__dict__.update(entry)
        self.data = b""  # decoded (raw) bytes, set by read_package

    def __repr__(self):
        return "Blob(%r, id=%d, type=%s, count=%d, codec=%s)" % (
            self.name, self.id, self.type_name, self.count, self.codec_name)

    @property
    def type_name(self):
        return ELEMENT_TYPES[self.element_type][0]

    type = type_name

    @property
    def codec_name(self):
        return CODECS[self.codec]

    @property
    def dtype(self):
        """numpy dtype of one element; vectors have shape (count, n)."""
        return element_dtype(self.element_type, self.record, self.stride)[0]

    def array(self):
        """The elements as a read-only numpy array over `data` (no copy):
        shape (count,) for scalars and records (a structured dtype), (count,
        n) for vectors."""
        dt, shape = element_dtype(self.element_type, self.record, self.stride)
        n = shape[0] if shape else 1
        a = np.frombuffer(self.data, dtype=dt, count=self.count * n)
        return a.reshape((self.count,) + shape) if shape else a

    @property
    def known(self):
        return self.id in CATALOGUE

    @property
    def record(self):
        return CATALOGUE[self.id][3] if self.known else None

    def entry(self):
        """The table entry as a dict, with the codec and type names."""
        d = {f: getattr(self, f) for _, _, f in ENTRY_FIELDS}
        d.update(name=self.name, codec_name=CODECS[self.codec], type_name=self.type_name)
        return d


class Package:
    def __init__(self):
        self.header = {}
        self.header_extra = b""
        self.blobs = []
        self.metadata_bytes = b""
        self.metadata = None  # parsed JSON, or None when it does not parse

    @property
    def major(self):
        return self.header["version_major"]

    @property
    def minor(self):
        return self.header["version_minor"]

    def blob(self, name):
        for b in self.blobs:
            if b.name == name:
                return b
        return None

    def count(self, name):
        b = self.blob(name)
        return b.count if b else 0


# ------------------------------------------------------------------ reading --

def read_package(data, name="package"):
    """Validates `data` (the bytes of a file, or any buffer such as a
    read-only mmap) in SPEC "Validation" order and returns a Package with
    every blob decoded. `name` starts every message. Raises FormatError."""

    def fail(msg):
        raise FormatError("%s: %s" % (name, msg))

    # A blob stored with codec none stays a view of `data` (no copy) unless
    # `data` is bytes, whose slices are bytes as callers of read_file expect.
    as_bytes = isinstance(data, bytes)
    data = memoryview(data).cast("B")
    size = len(data)
    # 1. magic, full header.
    if size == 0:
        fail("empty file")
    if size < len(MAGIC) or data[:8] != MAGIC:
        fail("bad magic number at offset 0: %s" % bytes(data[:8]).hex())
    if size < HEADER_SIZE_V1:
        fail("file of %d bytes is shorter than the %d-byte header" % (size, HEADER_SIZE_V1))
    p = Package()
    h = p.header
    for off, fmt, field in HEADER_FIELDS:
        h[field] = u(data, off, fmt)
    # 2. major version, before any checksum.
    if h["version_major"] != READER_MAJOR:
        fail("unsupported package major version %d (minor %d); this reader reads major version %d"
             % (h["version_major"], h["version_minor"], READER_MAJOR))
    not_newer = h["version_minor"] <= READER_MINOR
    # 3. header_size, then header_checksum (the last 8 bytes of the header).
    hs = h["header_size"]
    if hs < HEADER_SIZE_V1 or hs % 8:
        fail("header_size (offset 16) is %d; must be >= %d and a multiple of 8" % (hs, HEADER_SIZE_V1))
    if hs > size:
        fail("header_size (offset 16) %d exceeds the file size %d" % (hs, size))
    h["header_checksum"] = u(data, hs - 8, "Q")
    got = xxh64(data[:hs - 8])
    if got != h["header_checksum"]:
        fail("header_checksum (offset %d) mismatch: stored %016x, computed %016x"
             % (hs - 8, h["header_checksum"], got))
    p.header_extra = bytes(data[88:hs - 8])
    # 4. file_size.
    if h["file_size"] != size:
        fail("file_size (offset 32) is %d but the file has %d bytes" % (h["file_size"], size))
    # 5. flags and reserved fields.
    required = h["flags"] & 0xFFFF
    if required:
        fail("flags (offset 12) 0x%08x: unknown required flag bits 0x%04x" % (h["flags"], required))
    if not_newer:
        unknown = h["flags"] & ~KNOWN_FLAGS & 0xFFFFFFFF
        if unknown:
            fail("flags (offset 12) 0x%08x: reserved optional flag bits 0x%08x set in a v%d.%d file"
                 % (h["flags"], unknown, h["version_major"], h["version_minor"]))
        if h["reserved0"]:
            fail("reserved0 (offset 28) is %d, must be zero" % h["reserved0"])
        if h["reserved1"]:
            fail("reserved1 (offset 80) is %d, must be zero" % h["reserved1"])
        if any(p.header_extra):
            fail("header bytes [88, %d) are not zero in a v%d.%d file"
                 % (hs - 8, h["version_major"], h["version_minor"]))
    # 6. blob table.
    es, n = h["blob_entry_size"], h["blob_count"]
    if es < ENTRY_SIZE_V1 or es % 8:
        fail("blob_entry_size (offset 20) is %d; must be >= %d and a multiple of 8" % (es, ENTRY_SIZE_V1))
    if h["table_offset"] != hs:
        fail("table_offset (offset 40) is %d, must equal header_size %d" % (h["table_offset"], hs))
    table_end = hs + n * es
    if table_end > size:
        fail("blob table of %d entries x %d bytes at %d ends at %d, past the end of the file (%d)"
             % (n, es, hs, table_end, size))
    got = xxh64(data[hs:table_end])
    if got != h["table_checksum"]:
        fail("table_checksum (offset 48) mismatch: stored %016x, computed %016x" % (h["table_checksum"], got))
    # 7. metadata.
    mo, ms = h["metadata_offset"], h["metadata_size"]
    if mo != table_end:
        fail("metadata_offset (offset 56) is %d, must be table_offset + blob_count x blob_entry_size = %d"
             % (mo, table_end))
    if ms < 2:
        fail("metadata_size (offset 64) is %d, must be >= 2" % ms)
    if mo + ms > size:
        fail("metadata [%d, %d) lies past the end of the file (%d)" % (mo, mo + ms, size))
    if ms > METADATA_MAX:
        fail("metadata_size (offset 64) is %d, more than the limit of %d bytes (16 MiB)" % (ms, METADATA_MAX))
    meta = bytes(data[mo:mo + ms])
    got = xxh64(meta)
    if got != h["metadata_checksum"]:
        fail("metadata_checksum (offset 72) mismatch: stored %016x, computed %016x"
             % (h["metadata_checksum"], got))
    if meta[:1] != b"{" or meta[-1:] != b"}":
        fail("metadata at %d must start with '{' and end with '}' (got %r ... %r)" % (mo, meta[:1], meta[-1:]))
    if b"\0" in meta:
        fail("metadata contains a NUL byte at offset %d" % (mo + meta.index(b"\0")))
    p.metadata_bytes = meta
    # 8. entries.
    prev_end = mo + ms
    seen = {}
    for i in range(n):
        e0 = hs + i * es
        ent = {field: u(data, e0 + off, fmt) for off, fmt, field in ENTRY_FIELDS}
        where = "blob table entry %d (offset %d, id %d)" % (i, e0, ent["id"])
        raw_name = bytes(data[e0 + 56:e0 + 88])
        nul = raw_name.find(b"\0")
        text = raw_name if nul < 0 else raw_name[:nul]
        if nul < 0 or not NAME_RE.fullmatch(text) or any(raw_name[nul:]):
            fail("%s: name (offset %d) %r is not 1-31 of [a-z0-9_] then NUL bytes" % (where, e0 + 56, raw_name))
        ent["name"] = text.decode("ascii")
        where = "blob %d '%s' (table entry at offset %d)" % (i, ent["name"], e0)
        if ent["id"] in CATALOGUE and ent["name"] != CATALOGUE[ent["id"]][0]:
            fail("%s: name differs from the catalogue name '%s' of id %d"
                 % (where, CATALOGUE[ent["id"]][0], ent["id"]))
        if not_newer:
            reserved = struct.unpack_from("<2I", data, e0 + 88)
            if any(reserved):
                fail("%s: reserved (offset %d) is %s, must be zero" % (where, e0 + 88, list(reserved)))
            if any(data[e0 + ENTRY_SIZE_V1:e0 + es]):
                fail("%s: entry bytes [96, %d) are not zero in a v%d.%d file"
                     % (where, es, h["version_major"], h["version_minor"]))
        et, stride = ent["element_type"], ent["stride"]
        if et not in ELEMENT_TYPES:
            fail("%s: element_type (offset %d) %d is invalid" % (where, e0 + 4, et))
        if et == RECORD:
            if stride == 0 or stride % 4:
                fail("%s: record stride (offset %d) %d is not a positive multiple of 4" % (where, e0 + 8, stride))
        elif stride != ELEMENT_TYPES[et][2]:
            fail("%s: stride (offset %d) %d, element type %s needs %d"
                 % (where, e0 + 8, stride, ELEMENT_TYPES[et][0], ELEMENT_TYPES[et][2]))
        if ent["id"] in CATALOGUE:
            cname, ctype, cstride, _ = CATALOGUE[ent["id"]]
            if ELEMENT_TYPES[et][0] != ctype or stride != cstride:
                fail("%s: element type %s / stride %d differ from the catalogue (%s / %d)"
                     % (where, ELEMENT_TYPES[et][0], stride, ctype, cstride))
        if ent["id"] in seen:
            fail("%s: id %d repeats entry %d" % (where, ent["id"], seen[ent["id"]]))
        seen[ent["id"]] = i
        product = ent["count"] * stride
        if product > U64_MAX:
            fail("%s: count %d x stride %d overflows u64" % (where, ent["count"], stride))
        if product != ent["raw_size"]:
            fail("%s: raw_size (offset %d) %d != count %d x stride %d"
                 % (where, e0 + 40, ent["raw_size"], ent["count"], stride))
        codec, stored, raw = ent["codec"], ent["stored_size"], ent["raw_size"]
        if codec not in CODECS:
            fail("%s: codec (offset %d) %d is invalid" % (where, e0 + 12, codec))
        if codec == CODEC_NONE and stored != raw:
            fail("%s: codec none but stored_size %d != raw_size %d" % (where, stored, raw))
        if codec == CODEC_ZSTD:
            if h["flags"] & FLAG_ALL_UNCOMPRESSED:
                fail("%s: codec zstd in a package flagged all_uncompressed" % where)
            if stored == 0:
                fail("%s: codec zstd with stored_size 0 (no frame)" % where)
            if raw > stored * 32768 + 131072:  # SPEC "Codecs": the inflation limit
                fail("%s: raw_size %d exceeds the zstd inflation limit for stored_size %d" % (where, raw, stored))
        off = ent["offset"]
        if off % ALIGN:
            fail("%s: offset (offset %d) %d is not a multiple of 256" % (where, e0 + 24, off))
        if off + stored > size:
            fail("%s: stored bytes [%d, %d) lie past the end of the file (%d)" % (where, off, off + stored, size))
        if off < prev_end:
            fail("%s: offset %d overlaps the previous region ending at %d" % (where, off, prev_end))
        if off != align256(prev_end):
            fail("%s: offset %d is not align256(%d) = %d" % (where, off, prev_end, align256(prev_end)))
        if any(data[prev_end:off]):
            fail("%s: padding [%d, %d) is not zero" % (where, prev_end, off))
        prev_end = off + stored
        p.blobs.append(Blob(i, ent))
    if prev_end != size:
        fail("the file has %d bytes after its last region (which ends at %d)" % (size - prev_end, prev_end))
    # 9. blob checksums, then decoding.
    for b in p.blobs:
        stored = data[b.offset:b.offset + b.stored_size]
        if as_bytes:
            stored = bytes(stored)
        got = xxh64(stored)
        if got != b.checksum:
            fail("blob %d '%s': checksum (table offset %d) mismatch: stored %016x, computed %016x"
                 % (b.index, b.name, hs + b.index * es + 48, b.checksum, got))
        b.data = stored if b.codec == CODEC_NONE else _unzstd(stored, b, fail)
    try:
        p.metadata = json.loads(meta.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        p.metadata = None  # step 7 does not require valid JSON; verify_metadata does
    return p


def _unzstd(stored, b, fail):
    where = "blob %d '%s'" % (b.index, b.name)
    try:
        params = zstandard.get_frame_parameters(stored)
    except zstandard.ZstdError as e:
        fail("%s: not a zstd frame: %s" % (where, e))
    if params.content_size == zstandard.CONTENTSIZE_UNKNOWN:
        fail("%s: zstd frame has no Frame_Content_Size" % where)
    if params.content_size != b.raw_size:
        fail("%s: zstd Frame_Content_Size %d != raw_size %d" % (where, params.content_size, b.raw_size))
    d = zstandard.ZstdDecompressor().decompressobj()
    try:
        out = d.decompress(stored)
    except zstandard.ZstdError as e:
        fail("%s: zstd decoding failed: %s" % (where, e))
    if not d.eof:
        fail("%s: zstd frame is truncated" % where)
    if d.unused_data:
        fail("%s: %d bytes after the zstd frame" % (where, len(d.unused_data)))
    if len(out) != b.raw_size:
        fail("%s: decoded %d bytes, raw_size is %d" % (where, len(out), b.raw_size))
    return out


def read_file(path):
    """Reads and validates the file at `path` (a copy in memory; see
    decalprep.open for a memory-mapped read). Raises FormatError."""
    with open(path, "rb") as f:
        return read_package(f.read(), path)


# ----------------------------------------------------------------- elements --

def elements(b):
    """The decoded elements of blob `b`: a scalar per element for one-component
    types, a list for vector types, a dict per record (SPEC "Records"), the
    parsed JSON array for manifest_entries, a hex string per element of a
    record this reader does not know."""
    if b.id == ID_BY_NAME["manifest_entries"]:
        return json.loads(bytes(b.data).decode("utf-8"))
    a = b.array()
    if b.element_type != RECORD:
        return a.tolist()
    if b.record is None:
        return [bytes(e).hex() for e in a]
    # Column by column: tolist() of a structured array gives tuples holding
    # numpy sub-arrays, of a column plain Python numbers and lists.
    cols = [(name, a[name].tolist()) for name, _, _ in RECORDS[b.record]]
    return [{name: col[i] for name, col in cols} for i in range(len(a))]


# ------------------------------------------------------- index constraints --

def _flat(p, name, fmt="I"):
    """The 4-byte components of blob `name` as one flat array ("I" unsigned,
    "i" signed); empty when the blob is absent."""
    out = array(fmt)
    b = p.blob(name)
    if b is not None:
        out.frombytes(b.data)
        if sys.byteorder != "little":
            out.byteswap()
    return out


def check_indices(p):
    """SPEC "Index constraints", from the blobs alone. Returns a list of
    violations (empty when the package satisfies them). Works on flat arrays
    of components (component k of element i is at i * n + k) to stay fast
    and small on city-sized packages."""
    errs = []
    cnt = p.count

    def bad(name, n, i, what):
        errs.append("%s[%d] = %s: %s" % (name, i // n if n else i, list(v_of(name, n, i // n)), what))

    def v_of(name, n, i):
        f = _flat(p, name, "i" if name in ("qt_node", "dyn_prev_next", "dyn_vertices") else "I")
        return f[i * n:i * n + n]

    def all_below(name, n, k, limit, what):
        """Component k of every element of `name` (n components) < limit."""
        f = _flat(p, name)[k::n]
        if f and max(f) >= limit:
            bad(name, n, [i for i, v in enumerate(f) if v >= limit][0] * n, what)

    def same_count(name, ref):
        if cnt(name) != cnt(ref):
            errs.append("%s has %d elements, must have #%s = %d" % (name, cnt(name), ref, cnt(ref)))

    def sums_within(name, n, ks, limit, what):
        """The sum of components `ks` of every element of `name` <= limit."""
        f = _flat(p, name)
        cols = [f[k::n] for k in ks]
        for i, parts in enumerate(zip(*cols)):
            if sum(parts) > limit:
                bad(name, n, i * n, what)
                return

    nv = cnt("line_vertices")
    same_count("line_vertex_line", "line_vertices")
    same_count("line_corners", "line_vertices")
    all_below("line_vertex_line", 1, 0, cnt("line_props"), ">= #line_props = %d" % cnt("line_props"))
    for i, hw in enumerate(_flat(p, "line_props", "f")[0::8]):
        if not 0.0 <= hw < 1e7:
            errs.append("line_props[%d].half_width = %r: not in [0, 1e7)" % (i, hw))
            break
    for rng, target in (("cell_segment_range", "cell_segments"), ("qt_leaf_range", "qt_leaf_segments"),
                        ("cell_poly_range", "cell_polys"), ("lod_line_range", "lod_segments"),
                        ("qt_leaf_loop_range", "qt_leaf_loops")):
        sums_within(rng, 2, (0, 1), cnt(target), "first + count > #%s = %d" % (target, cnt(target)))
    nh = cnt("cell_holes")
    sums_within("cell_polys", 4, (2, 3), nh, "first hole + hole count > #cell_holes = %d" % nh)
    for k in (0, 1):
        all_below("cell_segments", 2, k, nv, "vertex >= #line_vertices = %d" % nv)
        all_below("qt_leaf_segments", 2, k, cnt("qt_leaf_vertices"),
                  "vertex >= #qt_leaf_vertices = %d" % cnt("qt_leaf_vertices"))
    # SPEC "Compact layout (v1.3)": leaf loops, their ends non-decreasing and
    # within the leaf vertices; partial leaves then index the loop ranges.
    loops = _flat(p, "qt_leaf_loops")
    loop_layout = cnt("qt_leaf_loop_range") > 0 or cnt("qt_leaf_loops") > 0
    if loop_layout and (cnt("qt_leaf_range") > 0 or cnt("qt_leaf_segments") > 0):
        errs.append("qt_leaf_range/qt_leaf_segments and qt_leaf_loop_range/qt_leaf_loops are both present")
    if any(b < a for a, b in zip([0] + list(loops), loops)) or (loops and max(loops) > cnt("qt_leaf_vertices")):
        errs.append("qt_leaf_loops: ends decrease or exceed #qt_leaf_vertices = %d" % cnt("qt_leaf_vertices"))
    nq, npp = cnt("qt_node"), cnt("poly_props")
    nlr = cnt("qt_leaf_loop_range") if loop_layout else cnt("qt_leaf_range")
    same_count("poly_root_node", "poly_props")
    all_below("poly_root_node", 1, 0, nq, ">= #qt_node = %d" % nq)
    same_count("qt_node_box", "qt_node")
    ext = _flat(p, "poly_props", "i")[2::8]  # PolyProps::exterior
    for i, e in enumerate(ext):
        if e != -1 and not 0 <= e < npp:
            errs.append("poly_props[%d].exterior = %d: not -1 or < #poly_props = %d" % (i, e, npp))
            break
    node = _flat(p, "qt_node", "i")
    for i, (t, o) in enumerate(zip(node[0::2], node[1::2])):
        if not (0 <= t <= 3 and o >= 0 and (t != 0 or i < o and o + 4 <= nq) and (t != 3 or o < nlr)):
            errs.append("qt_node[%d] = [%d, %d]: bad type, or offset out of range (#qt_node %d, #qt_leaf_range %d)"
                        % (i, t, o, nq, nlr))
            break
    entries, hf = cnt("cell_poly_entries"), list(_flat(p, "cell_poly_holes"))
    if entries or hf:
        if cnt("cell_polys"):
            errs.append("cell_polys and cell_poly_entries are both present")
        if len(hf) != entries + 1 or hf[0] != 0 or hf[-1] != nh or any(b < a for a, b in zip(hf, hf[1:])):
            errs.append("cell_poly_holes: not %d + 1 hole firsts from 0 to #cell_holes = %d, never decreasing"
                        % (entries, nh))
    for name, n in (("cell_polys", 4), ("cell_holes", 2), ("cell_poly_entries", 2)):
        all_below(name, n, 0, npp, "polygon >= #poly_props = %d" % npp)
        all_below(name, n, 1, nq, "culling node >= #qt_node = %d" % nq)
    grid = p.metadata.get("grid") if isinstance(p.metadata, dict) else None
    cells = None
    try:
        (ox, oy), (cw, ch), (nx, ny) = grid["origin"], grid["cell"], grid["dims"]
        cells = nx * ny
        lim = 2 ** 31
        if cw <= 0 or ch <= 0:
            errs.append("grid cell %sx%s is not positive" % (cw, ch))
        elif not (-lim < ox < lim and -lim < oy < lim and cw < lim and ch < lim and ox + cw * nx < lim
                  and oy + ch * ny < lim):
            errs.append("grid exceeds the int32 quantum range")
    except (TypeError, KeyError, ValueError):
        pass  # no grid: the per-cell counts are checked without it
    for first_name, lst, box16, old in (("cell_line_first", "cell_segments", "line_bvh_box16",
                                         ("cell_segment_range", "line_bvh_range", "line_bvh_box")),
                                        ("cell_poly_first", "cell_poly_entries", "poly_bvh_box16",
                                         ("cell_poly_range", "poly_bvh_range", "poly_bvh_box"))):
        if cnt(first_name) == 0:
            if cnt(box16):
                errs.append("%s present without %s" % (box16, first_name))
            continue
        if any(cnt(o) for o in old):
            errs.append("%s and the v1.2 blobs %s are both present" % (first_name, "/".join(old)))
        if cells is not None and cnt(first_name) != cells + 1:
            errs.append("%s has %d elements for the %d grid cells" % (first_name, cnt(first_name), cells))
        f = _flat(p, first_name)
        xs, ys = f[0::2], f[1::2]
        if xs[0] != 0 or ys[0] != 0 or xs[-1] != cnt(lst) or ys[-1] != cnt(box16):
            errs.append("%s does not run from (0, 0) to (#%s, #%s)" % (first_name, lst, box16))
        for i in range(len(xs) - 1):
            n, d = xs[i + 1] - xs[i], ys[i + 1] - ys[i]
            leaves = (d + 1) // 2
            if n < 0 or d < 0 or (d != 0 if n == 0 else (d % 2 != 1 or leaves & (leaves - 1) or leaves < n)):
                errs.append("%s[%d]: %d nodes are not a full binary tree over %d entries" % (first_name, i, d, n))
                break
    for rng, lst, bvh, box, first_name in (
            ("cell_segment_range", "cell_segments", "line_bvh_range", "line_bvh_box", "cell_line_first"),
            ("cell_poly_range", "cell_polys", "poly_bvh_range", "poly_bvh_box", "cell_poly_first")):
        if cnt(rng) == 0 and cnt(bvh) == 0 and (cnt(lst) == 0 or cnt(first_name) > 0):
            continue
        same_count(bvh, rng)
        if cells is not None and cnt(rng) != cells:
            errs.append("%s has %d elements for the %d grid cells" % (rng, cnt(rng), cells))
        entries = _flat(p, rng)[1::2]
        b = _flat(p, bvh)
        nbox = cnt(box)
        for i, (first, slots, internal) in enumerate(zip(b[0::4], b[1::4], b[2::4])):
            n = entries[i] if i < len(entries) else 0
            if (slots & (slots - 1)) or slots < n or internal != max(slots - 1, 0) or first + slots + internal > nbox:
                errs.append("%s[%d] = (%d, %d, %d): not a full binary tree over %d entries inside #%s = %d"
                            % (bvh, i, first, slots, internal, n, box, nbox))
                break
    nd = cnt("dyn_vertices")
    same_count("dyn_prev_next", "dyn_vertices")
    pn = _flat(p, "dyn_prev_next", "i")
    if pn and (min(pn) < -1 or max(pn) >= nd):
        i = [k for k, x in enumerate(pn) if x < -1 or x >= nd][0]
        bad("dyn_prev_next", 2, i, "not -1 or < #dyn_vertices = %d" % nd)
    all_below("dyn_line_start", 1, 0, nd, ">= #dyn_vertices = %d" % nd)
    ndl = cnt("dyn_line_props")
    dv = _flat(p, "dyn_vertices", "i")
    if dv and (min(dv[3::4]) < 0 or max(dv[3::4]) >= ndl):
        errs.append("dyn_vertices: a line index not in [0, #dyn_line_props = %d)" % ndl)
    if nd > 0:
        starts = list(_flat(p, "dyn_line_start"))
        if len(starts) != ndl:
            errs.append("dyn_line_start has %d elements, must have #dyn_line_props = %d" % (len(starts), ndl))
        elif not starts or starts[0] != 0:
            errs.append("dyn_line_start[0] must be 0 when dynamic vertices exist")
        else:
            ends = starts[1:] + [nd]
            for l, (a, e) in enumerate(zip(starts, ends)):
                if e <= a:
                    errs.append("dyn_line_start[%d]: starts do not increase" % (l + 1))
                    break
                if any(x != l for x in dv[4 * a + 3:4 * e:4]):
                    errs.append("dyn_vertices in the run of line %d name another line" % l)
                    break
    nlp = cnt("lod_points")
    for k, field in enumerate(("a", "b", "generator", "splitter")):
        f = _flat(p, "lod_segments")[k::4]
        if any(v >= nlp and (k < 2 or v != LOD_NONE) for v in f):
            errs.append("lod_segments: a %s index >= #lod_points = %d" % (field, nlp))
    all_below("lod_points", 8, 6, ndl, "line >= #dyn_line_props = %d" % ndl)
    if any(f & ~1 for f in _flat(p, "lod_points")[7::8]):
        errs.append("lod_points: flags with bits other than bit 0")
    # The "is zero" rules hold only for files whose minor version is not
    # newer than the reader's; the clip_node range with bit 5 always holds.
    zero_rules = p.minor <= READER_MINOR
    lp = _flat(p, "line_props")
    for i, (style, clip) in enumerate(zip(lp[3::8], lp[7::8])):
        if (clip >= nq) if style & 0x20 else (zero_rules and clip != 0):
            errs.append("line_props[%d]: clip_node %d with style 0x%x (#qt_node %d)" % (i, clip, style, nq))
            break
    if zero_rules and any(_flat(p, "dyn_line_props")[7::8]):
        errs.append("dyn_line_props: clip_node is not zero")
    pp = _flat(p, "poly_props")
    if zero_rules and (any(pp[6::8]) or any(pp[7::8])):
        errs.append("poly_props: reserved is not zero")
    return errs


def check_metadata(p):
    """The metadata checks of `decalprep verify` as SPEC "Validation" lists
    them: valid JSON object, `format` = "decals" when present, `counts`
    agree with the blobs. Returns a list of violations."""
    m = p.metadata
    if not isinstance(m, dict):
        return ["metadata is not a JSON object"]
    errs = []
    if "format" in m and m["format"] != "decals":
        errs.append("metadata format is %r, not \"decals\"" % (m["format"],))
    counts = m.get("counts", {})
    if isinstance(counts, dict):
        for b in p.blobs:
            if b.name in counts and counts[b.name] != b.count:
                errs.append("metadata counts.%s = %s but the blob has %d elements" % (b.name, counts[b.name], b.count))
    return errs


# --------------------------------------------------------------------- main --

def _finite(v):
    """JSON has no NaN or infinity: such floats become null."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_finite(x) for x in v]
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    return v


def to_json(p, only=None):
    blobs = []
    for b in p.blobs:
        if only and b.name != only:
            continue
        d = b.entry()
        d["elements"] = _finite(elements(b))
        blobs.append(d)
    header = dict(p.header)
    header["magic"] = MAGIC.hex()
    return {"header": header, "version": {"major": p.major, "minor": p.minor},
            "metadata": p.metadata, "blobs": blobs}
