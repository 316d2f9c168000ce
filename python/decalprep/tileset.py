"""A tileset: its index `tileset.json` checked against formats/SPEC.md
"Tilesets" ("tileset.json", "Overview levels"), and its tiles' packages
opened only at the paths the index may name, checked against the index's
size and hash first and against the tile's entry after.
"""

import json
import math
import os
import re

import xxhash

from .package import Package, open_regular
from .spec_reader import FormatError

READER_MAJOR = 1
READER_MINOR = 1
INDEX_MAX = 128 * 1024 * 1024  # SPEC "tileset.json" Limits: 128 MiB
COUNT_MAX = 2 ** 53
COORD_MAX = 1e12
TILE_SIZE_MAX = 4000000.0
VERSION_RE = re.compile(r"(0|[1-9][0-9]{0,8})\.(0|[1-9][0-9]{0,8})")
HEX_RE = re.compile(r"[0-9a-f]{16}")
MANIFEST_COUNTS = ("read", "kept", "repaired", "clipped_away", "dropped", "parts", "vertices_in", "vertices_out")
LEVEL_COUNTS = ("parts_in", "parts", "dropped_small", "vertices_in", "vertices_out")


def _is_int(v):
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v):
    return (isinstance(v, (int, float)) and not isinstance(v, bool)) and math.isfinite(v)


class Tile:
    """One tile entry of the index: `x`, `y`, `level` (0 full detail),
    `square` [xmin, ymin, xmax, ymax] and `origin` [x, y] (absolute frame
    metres), `file` (relative to the tileset folder), `bytes`, `xxh64`,
    `counts` and `layers` as the index gives them."""

    def __init__(self, level, entry):
        self.level = level
        self.entry = entry
        for k in ("x", "y", "square", "origin", "file", "bytes", "xxh64", "counts", "layers"):
            setattr(self, k, entry[k])

    @property
    def key(self):
        return (self.x, self.y)

    def __repr__(self):
        return "Tile(level=%d, x=%d, y=%d, %r)" % (self.level, self.x, self.y, self.file)


class Level:
    """Overview level L ≥ 1 (SPEC "Overview levels"), or level 0 with the
    index's own tile size and resolution. `tiles` is a list of Tile."""

    def __init__(self, level, tile_size_m, resolution_m, tiles, entry=None):
        self.level = level
        self.tile_size_m = tile_size_m
        self.resolution_m = resolution_m
        self.tiles = tiles
        self.entry = entry or {}
        self.min_area_m2 = self.entry.get("min_area_m2", 0.0)
        self.min_length_m = self.entry.get("min_length_m", 0.0)
        self.layers = self.entry.get("layers", [])

    def __repr__(self):
        return "Level(%d, tile_size_m=%g, %d tiles)" % (self.level, self.tile_size_m, len(self.tiles))


class Tileset:
    """A tileset folder, its index checked in full when it is opened.

    Attributes: `path` (the folder), `index` (the parsed tileset.json),
    `version` (major, minor), `frame`, `tiling`, `extent`, `manifest`,
    `tile_size_m`, `tiles` (level 0), `levels` (Level objects, index 0 =
    level 0, then the overview levels in order).
    """

    def __init__(self, path):
        path = os.fspath(path)
        if os.path.isdir(path):
            self.path, index = path, os.path.join(path, "tileset.json")
        else:
            self.path, index = os.path.dirname(path) or ".", path
        self.index_path = index
        fd = open_regular(index)
        with os.fdopen(fd, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size > INDEX_MAX:
                raise FormatError("%s: tileset.json is %d bytes, more than the limit of %d (128 MiB)"
                                  % (index, size, INDEX_MAX))
            text = f.read(INDEX_MAX + 1)
        if len(text) > INDEX_MAX:
            raise FormatError("%s: tileset.json grew past the limit of %d bytes (128 MiB)" % (index, INDEX_MAX))
        try:
            ix = json.loads(text.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as e:
            raise FormatError("%s: not a JSON document: %s" % (index, e)) from None
        self.index = ix
        self._check(ix)

    def close(self):
        """Nothing to release (the index is read whole; each tile's Package
        is closed by its user); here so that a Tileset and a Package are
        used alike, also as context managers."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def __repr__(self):
        return "decalprep.Tileset(%r, v%d.%d, %d tiles, %d levels)" % (
            self.path, self.version[0], self.version[1], len(self.tiles), len(self.levels))

    # -- checks (SPEC "tileset.json", "Overview levels") --

    def _fail(self, msg):
        raise FormatError("%s: %s" % (self.index_path, msg))

    def _obj(self, v, where):
        if not isinstance(v, dict):
            self._fail("%s is %s, not an object" % (where, json.dumps(v)[:80]))
        return v

    def _key(self, obj, key, where):
        if key not in obj:
            self._fail("%s has no key '%s'" % (where, key))
        return obj[key]

    def _num(self, v, where, lo=-COORD_MAX, hi=COORD_MAX):
        if not _is_num(v) or not lo <= v <= hi:
            self._fail("%s is %s; must be a finite number in [%g, %g]" % (where, json.dumps(v)[:80], lo, hi))
        return v

    def _count(self, v, where):
        if not _is_int(v) or not 0 <= v <= COUNT_MAX:
            self._fail("%s is %s; must be an integer in [0, 2^53]" % (where, json.dumps(v)[:80]))
        return v

    def _hex(self, v, where):
        if not isinstance(v, str) or not HEX_RE.fullmatch(v):
            self._fail("%s is %s; must be 16 lowercase hex digits" % (where, json.dumps(v)[:80]))
        return v

    def _check(self, ix):
        self._obj(ix, "the index")
        ver = self._key(ix, "tileset_version", "the index")
        m = VERSION_RE.fullmatch(ver) if isinstance(ver, str) else None
        if m is None:
            self._fail("tileset_version %s is not MAJOR.MINOR" % json.dumps(ver)[:80])
        self.version = (int(m.group(1)), int(m.group(2)))
        if self.version[0] != READER_MAJOR:
            self._fail("unsupported tileset major version %d (tileset_version \"%s\"); this reader reads "
                       "major version %d" % (self.version[0], ver, READER_MAJOR))
        for k in ("generator", "frame", "tiling", "extent", "manifest", "tiles"):
            self._key(ix, k, "the index")
        frame = self._obj(ix["frame"], "frame")
        for k in ("crs_wkt", "description"):
            if not isinstance(self._key(frame, k, "frame"), str):
                self._fail("frame.%s is not a string" % k)
        self._pair(self._key(frame, "origin", "frame"), "frame.origin")
        tiling = self._obj(ix["tiling"], "tiling")
        if self._key(tiling, "scheme", "tiling") != "grid":
            self._fail("tiling.scheme is %s, not \"grid\"" % json.dumps(tiling["scheme"])[:80])
        s = self._num(self._key(tiling, "tile_size_m", "tiling"), "tiling.tile_size_m", 1.0, TILE_SIZE_MAX)
        for k in ("margin_m", "dynamic_margin_m"):
            self._num(self._key(tiling, k, "tiling"), "tiling." + k, 0.0)
        ext = ix["extent"]
        if not isinstance(ext, list) or len(ext) != 4:
            self._fail("extent is %s, not [xmin, ymin, xmax, ymax]" % json.dumps(ext)[:80])
        for i, v in enumerate(ext):
            self._num(v, "extent[%d]" % i)
        if ext[0] > ext[2] or ext[1] > ext[3]:
            self._fail("extent %s is inverted" % json.dumps(ext))
        kept = self._check_manifest(self._obj(ix["manifest"], "manifest"))
        resolution = 0.0
        levels_in = []
        if self.version >= (1, 1):
            resolution = self._num(self._key(ix, "resolution_m", "the index"), "resolution_m", 0.0)
            levels_in = self._key(ix, "levels", "the index")
            if not isinstance(levels_in, list):
                self._fail("levels is not an array")
        tiles = self._check_tiles(ix["tiles"], "tiles", 0, s, kept)
        self.frame, self.tiling, self.extent, self.manifest = frame, tiling, ext, ix["manifest"]
        self.tile_size_m = s
        self.levels = [Level(0, s, resolution, tiles)]
        for i, lv in enumerate(levels_in):
            self.levels.append(self._check_level(self._obj(lv, "levels[%d]" % i), i, s, kept))
        self.tiles = tiles

    def _pair(self, v, where):
        if not isinstance(v, list) or len(v) != 2:
            self._fail("%s is %s, not [x, y]" % (where, json.dumps(v)[:80]))
        for i, c in enumerate(v):
            self._num(c, "%s[%d]" % (where, i))
        return v

    def _check_manifest(self, man):
        for k in ("layers", "notes", "entry_count", "file", "bytes", "xxh64"):
            self._key(man, k, "manifest")
        if man["file"] != "manifest.json":
            self._fail("manifest.file is %s, not \"manifest.json\"" % json.dumps(man["file"])[:80])
        self._count(man["entry_count"], "manifest.entry_count")
        self._count(man["bytes"], "manifest.bytes")
        self._hex(man["xxh64"], "manifest.xxh64")
        if not isinstance(man["layers"], list):
            self._fail("manifest.layers is not an array")
        kept = {}
        for i, ly in enumerate(man["layers"]):
            where = "manifest.layers[%d]" % i
            self._obj(ly, where)
            name = self._key(ly, "layer", where)
            if not isinstance(name, str) or name in kept:
                self._fail("%s.layer %s is not a string or repeats" % (where, json.dumps(name)[:80]))
            c = {k: self._count(self._key(ly, k, where), "%s.%s" % (where, k)) for k in MANIFEST_COUNTS}
            if c["read"] != c["kept"] + c["clipped_away"] + c["dropped"]:
                self._fail("%s ('%s'): read %d != kept %d + clipped_away %d + dropped %d"
                           % (where, name, c["read"], c["kept"], c["clipped_away"], c["dropped"]))
            if c["repaired"] > c["kept"]:
                self._fail("%s ('%s'): repaired %d > kept %d" % (where, name, c["repaired"], c["kept"]))
            kept[name] = c["kept"]
        return kept

    def _check_tiles(self, tiles, where, level, size, kept):
        if not isinstance(tiles, list):
            self._fail("%s is not an array" % where)
        out, prev = [], None
        total = {name: 0 for name in kept}
        for i, t in enumerate(tiles):
            w = "%s[%d]" % (where, i)
            self._obj(t, w)
            for k in ("x", "y", "square", "origin", "file", "bytes", "xxh64", "counts", "layers"):
                self._key(t, k, w)
            x, y = t["x"], t["y"]
            if not _is_int(x) or not _is_int(y) or abs(x) > COUNT_MAX or abs(y) > COUNT_MAX:
                self._fail("%s key (%s, %s) is not a pair of integers" % (w, json.dumps(x), json.dumps(y)))
            if prev is not None and (x, y) <= prev:
                self._fail("%s (%d, %d) is not after (%d, %d): tiles are sorted by x then y, each once"
                           % (w, x, y, prev[0], prev[1]))
            prev = (x, y)
            square = [x * size, y * size, (x + 1) * size, (y + 1) * size]
            if t["square"] != square:
                self._fail("%s.square %s is not %s, the square of key (%d, %d)"
                           % (w, json.dumps(t["square"])[:120], square, x, y))
            origin = [(x + 0.5) * size, (y + 0.5) * size]
            if t["origin"] != origin:
                self._fail("%s.origin %s is not %s, the centre of key (%d, %d)"
                           % (w, json.dumps(t["origin"])[:120], origin, x, y))
            want = ("tiles/L%d/x%d_y%d.decals" % (level, x, y)) if level else ("tiles/x%d_y%d.decals" % (x, y))
            if t["file"] != want:
                self._fail("%s.file %s is not \"%s\"" % (w, json.dumps(t["file"])[:120], want))
            self._count(t["bytes"], w + ".bytes")
            self._hex(t["xxh64"], w + ".xxh64")
            counts = self._obj(t["counts"], w + ".counts")
            for k in ("polygons", "lines", "dynamic_lines"):
                self._count(self._key(counts, k, w + ".counts"), "%s.counts.%s" % (w, k))
            if not isinstance(t["layers"], list):
                self._fail("%s.layers is not an array" % w)
            for j, ly in enumerate(t["layers"]):
                lw = "%s.layers[%d]" % (w, j)
                self._obj(ly, lw)
                name = self._key(ly, "layer", lw)
                if name not in kept:
                    self._fail("%s.layer %s is not a layer of manifest.layers" % (lw, json.dumps(name)[:80]))
                c = {k: self._count(ly.get(k, 0), "%s.%s" % (lw, k)) for k in MANIFEST_COUNTS}
                if c["read"] != c["kept"] or c["clipped_away"] or c["dropped"]:
                    self._fail("%s ('%s'): a tile's layer has read = kept and no clipped_away or dropped "
                               "(read %d, kept %d, clipped_away %d, dropped %d)"
                               % (lw, name, c["read"], c["kept"], c["clipped_away"], c["dropped"]))
                if c["kept"] > kept[name]:
                    self._fail("%s ('%s'): kept %d > the manifest's kept %d" % (lw, name, c["kept"], kept[name]))
                total[name] += c["kept"]
            out.append(Tile(level, t))
        if level == 0:
            for name, k in kept.items():
                if total[name] < k:
                    self._fail("tiles keep %d features of layer '%s' in all, fewer than the manifest's kept %d"
                               % (total[name], name, k))
        return out

    def _check_level(self, lv, i, s, kept):
        where = "levels[%d]" % i
        for k in ("level", "tile_size_m", "resolution_m", "min_area_m2", "min_length_m", "layers", "tiles"):
            self._key(lv, k, where)
        L = i + 1
        if not _is_int(lv["level"]) or lv["level"] != L:
            self._fail("%s.level is %s; the levels must be consecutive from 1 (expected %d)"
                       % (where, json.dumps(lv["level"])[:40], L))
        size = s * 2 ** L
        if size > TILE_SIZE_MAX or lv["tile_size_m"] != size:
            self._fail("%s.tile_size_m is %s; level %d needs tiling.tile_size_m * 2^%d = %r, at most %d"
                       % (where, json.dumps(lv["tile_size_m"])[:40], L, L, size, TILE_SIZE_MAX))
        r = size / 1024
        for k, v in (("resolution_m", r), ("min_area_m2", r * r), ("min_length_m", r)):
            if lv[k] != v:
                self._fail("%s.%s is %s, not %r" % (where, k, json.dumps(lv[k])[:40], v))
        if not isinstance(lv["layers"], list):
            self._fail("%s.layers is not an array" % where)
        for j, ly in enumerate(lv["layers"]):
            lw = "%s.layers[%d]" % (where, j)
            self._obj(ly, lw)
            if self._key(ly, "layer", lw) not in kept:
                self._fail("%s.layer %s is not a layer of manifest.layers" % (lw, json.dumps(ly["layer"])[:80]))
            c = {k: self._count(self._key(ly, k, lw), "%s.%s" % (lw, k)) for k in LEVEL_COUNTS}
            self._count(ly.get("holes_dropped_small", 0), lw + ".holes_dropped_small")
            if c["parts_in"] != c["parts"] + c["dropped_small"]:
                self._fail("%s: parts_in %d != parts %d + dropped_small %d"
                           % (lw, c["parts_in"], c["parts"], c["dropped_small"]))
        tiles = self._check_tiles(lv["tiles"], where + ".tiles", L, size, kept)
        return Level(L, size, r, tiles, lv)

    # -- tiles --

    def level(self, L):
        """Level L (0 = full detail)."""
        if not 0 <= L < len(self.levels):
            raise KeyError("%s: no level %d (levels 0..%d)" % (self.path, L, len(self.levels) - 1))
        return self.levels[L]

    def tile(self, x, y, level=0):
        """The Tile entry with key (x, y) on `level`; KeyError when not listed."""
        for t in self.level(level).tiles:
            if (t.x, t.y) == (x, y):
                return t
        raise KeyError("%s: level %d lists no tile (%d, %d)" % (self.path, level, x, y))

    def tile_at(self, x, y, level=0):
        """The Tile whose square holds the absolute frame point (x, y) on
        `level` (SPEC "Tiling scheme": one tile answers a point), or None
        when that tile is not listed (no decal there)."""
        size = self.level(level).tile_size_m
        try:
            return self.tile(math.floor(x / size), math.floor(y / size), level)
        except KeyError:
            return None

    def open_tile(self, tile, y=None, level=0, check_indices=True):
        """Opens a tile's package: `tile` is a Tile, or x with `y` (and
        `level`). Checks the file's size and XXH64 against the index before
        reading it as a package, then the package's metadata against its
        entry (`tile` x, y, square, tile_size_m, margin_m, level; `origin`;
        `crs_wkt`; `manifest.layers`; the poly_props, line_props and
        dyn_line_props counts), as `decalprep verify` does. Raises
        FormatError."""
        t = tile if isinstance(tile, Tile) else self.tile(tile, y, level)
        path = os.path.join(self.path, t.file)
        fd = open_regular(path)
        with os.fdopen(fd, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size != t.bytes:
                raise FormatError("%s: %d bytes, but the index says bytes %d" % (path, size, t.bytes))
            h = xxhash.xxh64(seed=0)
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        if h.hexdigest() != t.xxh64:
            raise FormatError("%s: xxh64 %s, but the index says %s" % (path, h.hexdigest(), t.xxh64))
        p = Package(path, check_indices=check_indices)
        try:
            self._check_tile_package(p, t, path)
        except BaseException:
            p.close()
            raise
        return p

    def _check_tile_package(self, p, t, path):
        m = p.metadata
        lv = self.levels[t.level]

        def bad(field, got, want):
            raise FormatError("%s: metadata %s is %s, but the index gives %s"
                              % (path, field, json.dumps(got)[:120], json.dumps(want)[:120]))

        tm = m.get("tile") if isinstance(m, dict) else None
        if not isinstance(tm, dict):
            bad("tile", tm, {"x": t.x, "y": t.y})
        for k, want in (("x", t.x), ("y", t.y), ("square", t.square), ("tile_size_m", lv.tile_size_m),
                        ("margin_m", self.tiling["margin_m"])):
            if tm.get(k) != want:
                bad("tile." + k, tm.get(k), want)
        if tm.get("level", 0) != t.level:
            bad("tile.level", tm.get("level", 0), t.level)
        origin = m.get("origin")
        if not isinstance(origin, dict) or [origin.get("x"), origin.get("y")] != list(t.origin):
            bad("origin", origin, t.origin)
        if m.get("crs_wkt") != self.frame["crs_wkt"]:
            bad("crs_wkt", m.get("crs_wkt"), self.frame["crs_wkt"])
        layers = m.get("manifest", {}).get("layers") if isinstance(m.get("manifest"), dict) else None
        if layers != t.layers:
            bad("manifest.layers", layers, t.layers)
        for blob, key in (("poly_props", "polygons"), ("line_props", "lines"), ("dyn_line_props", "dynamic_lines")):
            b = p.blob(blob)
            n = b.count if b is not None else 0
            if n != t.counts[key]:
                raise FormatError("%s: %s has %d elements, but the index's counts.%s is %d"
                                  % (path, blob, n, key, t.counts[key]))

    def manifest_entries(self):
        """DIR/manifest.json's entries, after checking its size and XXH64
        against the index's `manifest`."""
        path = os.path.join(self.path, "manifest.json")
        fd = open_regular(path)
        with os.fdopen(fd, "rb") as f:
            data = f.read(self.manifest["bytes"] + 1)
        if len(data) != self.manifest["bytes"]:
            got = ("%d" if len(data) <= self.manifest["bytes"] else "more than %d") % (len(data) - 1)
            raise FormatError("%s: %s bytes, but the index says bytes %d"
                              % (path, got if len(data) > self.manifest["bytes"] else len(data),
                                 self.manifest["bytes"]))
        got = xxhash.xxh64_hexdigest(data, seed=0)
        if got != self.manifest["xxh64"]:
            raise FormatError("%s: xxh64 %s, but the index says %s" % (path, got, self.manifest["xxh64"]))
        return json.loads(data.decode("utf-8"))["entries"]
