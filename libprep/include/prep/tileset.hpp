// prep/tileset.hpp — a tileset directory: tileset.json (the index,
// formats/SPEC.md "Tilesets"), manifest.json (the scene's manifest entries)
// and tiles/<x>_<y>.decals, one package per non-empty tile; with overview
// levels also tiles/L<L>/x<X>_y<Y>.decals.
#pragma once

#include <algorithm>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "prep/scene.hpp"
#include "prep/tile.hpp"

namespace prep {

// The index's format version (major.minor; a reader accepts its own major).
constexpr int kTilesetMajor = 1;
constexpr int kTilesetMinor = 0;
// The minor version of an index with overview levels ("1.1"); an index
// without levels is written as 1.0, byte for byte as before them.
constexpr int kTilesetMinorLevels = 1;
// A level is made to be drawn at no more than this many pixels across a
// tile: its resolution is tile_size / kLevelTilePixels.
constexpr double kLevelTilePixels = 1024;
// An overview level's decal grid has cells at least this many of its
// resolutions wide (ModelOptions::min_cell_m).
constexpr double kLevelMinCellPixels = 2;
constexpr const char* kTilesetIndexName = "tileset.json";
// The largest tileset.json a reader parses and a writer writes
// (formats/SPEC.md "tileset.json"): about 1.9·10^5 tiles of one layer
// (700 bytes a tile of one layer, 230 more per further layer). Parsing takes about 25 times the
// text in memory, so an index at the limit costs ~3 GB; a bigger one is
// refused before it is read.
constexpr uint64_t kMaxTilesetIndexBytes = uint64_t(128) << 20;
// Every count of an index (features, parts, vertices, bytes) is at most
// 2^53: exact as a JSON number in any reader, and sums of a few thousand
// cannot wrap 64 bits.
constexpr uint64_t kMaxTilesetCount = uint64_t(1) << 53;
// Every coordinate, extent, origin and margin of an index lies within
// +-1e12 frame metres (the tile keys' bound times a 1 m tile).
constexpr double kMaxTilesetCoordinate = 1e12;
constexpr const char* kTilesetManifestName = "manifest.json";

struct TileEntry {
  TileKey key;
  Extent square;                      // absolute frame coordinates
  double origin_x = 0, origin_y = 0;  // the package's origin (the square's centre)
  std::string file;                   // relative to the tileset: "tiles/x0_y0.decals"
  uint64_t bytes = 0;
  uint64_t xxh64 = 0;                                   // of the whole file
  uint64_t polygons = 0, lines = 0, dynamic_lines = 0;  // parts in the package
  std::vector<LayerCounts> layers;  // this tile's counts (prep/tile.hpp tile_scene)
};

// One overview level of a tileset (formats/SPEC.md "Overview levels"):
// level L >= 1 has square tiles of tile_size = TilesetIndex::tile_size * 2^L
// on the same grid anchored at the frame CRS's zero, so tile (X, Y) of level
// L covers tiles (2X..2X+1, 2Y..2Y+1) of level L-1. Its parts are simplified
// to `resolution` ground metres, and polygons below `min_area` and lines
// below `min_length` are dropped and counted in `layers`, never silently.
struct TileLevel {
  int level = 0;                    // 1, 2, ...; level 0 (full detail) is TilesetIndex::tiles
  double tile_size = 0;             // metres
  double resolution = 0;            // ground metres per pixel this level is made for
  double min_area = 0;              // m^2: polygons smaller than this are dropped here
  double min_length = 0;            // m: lines shorter than this are dropped here
  std::vector<LayerCounts> layers;  // the level's per-layer counts, drops included
  std::vector<TileEntry> tiles;     // in key order; file "tiles/L<level>/x<X>_y<Y>.decals"
};

struct TilesetIndex {
  int major = kTilesetMajor, minor = kTilesetMinor;
  std::string generator;
  SceneFrame frame;  // origin: the scene's (tiles have their own)
  double tile_size = 0, margin = 0, dynamic_margin = 0;
  Extent extent;  // absolute frame coordinates of every tile's data
  // The scene's manifest: per-layer counts (each feature once, however many
  // tiles it reaches) and notes; the entries are in manifest.json.
  Manifest manifest;
  uint64_t entry_count = 0;
  uint64_t manifest_bytes = 0, manifest_xxh64 = 0;
  std::vector<TileEntry> tiles;   // in key order: x, then y (level 0, full detail)
  double resolution = 0;          // level 0's ground resolution (the build's; 0: exact)
  std::vector<TileLevel> levels;  // overview levels 1, 2, ... in order; empty: none
};

// Bytes and XXH64 (seed 0) of a file, read in 64 KiB pieces; nullopt when it
// cannot be opened.
struct FileDigest {
  uint64_t bytes = 0, xxh64 = 0;
};
// The file is opened as the package reader opens one (decal::open_regular_file):
// a FIFO, a device or a socket is refused before a byte is read; `why`,
// when given, then says why (the path and what it is).
std::optional<FileDigest> file_digest(const std::string& path, std::string* why = nullptr);

// "%016llx"
std::string hex64(uint64_t v);

// The index as JSON text (2-space indent, trailing newline; the same index
// gives the same bytes). Throws output_error, before any byte is written,
// when the index would not read back: tileset_index_problem() finds a
// problem, or the text is above kMaxTilesetIndexBytes.
std::string tileset_index_json(const TilesetIndex& index);

// The first range or consistency problem of the index `ix` as "field: what" (the
// field as tileset.json spells it, "manifest.layers[0].read"), or empty.
// read_tileset_index and tileset_index_json both apply it, so a writer
// never writes an index its readers refuse. Checks: the version; the frame
// CRS WKT reads (GDAL/PROJ); origin, extent (not inverted), margins and
// resolution finite and within +-kMaxTilesetCoordinate; the tile size;
// every count at most kMaxTilesetCount; per layer read = kept +
// clipped_away + dropped and repaired <= kept (a tile's layers: read =
// kept); layer names unique; each level's parts_in = parts + dropped_small;
// every layer a level-0 tile names is the manifest's, no tile keeps more of
// a layer than the manifest, and the level-0 tiles together hold at least
// every feature the manifest says was kept.
std::string tileset_index_problem(const TilesetIndex& ix);

// "MAJOR.MINOR", strictly (formats/SPEC.md "tileset.json"): two decimal
// integers of 1 to 9 digits without sign, space or leading zero.
bool parse_tileset_version(const std::string& text, int& major, int& minor);

// True when `path` is a directory holding tileset.json.
bool is_tileset(const std::string& path);

// Reads and checks `dir`/tileset.json as untrusted input: a regular file
// (no FIFO or device) of at most kMaxTilesetIndexBytes, refused before it
// is parsed; types, strict version, every tile's file name
// (tiles/<name>.decals, no other path), keys unique, squares matching keys
// and size, then tileset_index_problem(). Throws format_error naming the
// file and the field at fault; error(ExitCode::input) when it cannot be
// read.
TilesetIndex read_tileset_index(const std::string& dir);

// The tiles whose squares meet `view` (absolute frame coordinates), in index order.
std::vector<const TileEntry*> tiles_in(const TilesetIndex& index, const Extent& view);
// The same for one overview level's tiles.
std::vector<const TileEntry*> tiles_in(const TileLevel& level, const Extent& view);

// Level `level` (>= 1) of a tileset whose level-0 tiles are `tile_size`
// metres, its rule (formats/SPEC.md "Overview levels"): tile_size * 2^level,
// resolution = that / kLevelTilePixels, min_area = resolution^2,
// min_length = resolution; no tiles, no counts.
TileLevel level_parameters(double tile_size, int level);

// The simplification tolerance of a level: an eighth of its resolution, so
// that every point of a simplified part lies within an eighth of a pixel of
// the part (TopologyPreserveSimplify keeps the Douglas-Peucker bound) at
// the finest view the level serves. Half a pixel, the bound the level's
// resolution alone would suggest, moves edges across enough pixel centres
// to show: on 6.4·10^5 generated vertices at 88 m pixels (bench/overview.py's
// data), r/2 changed 8.4% of the pixels of a level-5 view, r/8 4.6%, and
// with the level's coarser grid (kLevelMinCellPixels) r/8 costs the bytes
// r/2 cost without it.
constexpr double kLevelToleranceShare = 1.0 / 8;
inline double level_tolerance(const TileLevel& level) {
  return level.resolution * kLevelToleranceShare;
}

// A static line's tolerance on a level: an eighth of the smaller of the
// level's resolution and the line's width (ground metres). A line narrower
// than a pixel shows as the pixel centres within half its width of it, so
// moving it by a pixel fraction larger than its width moves all of them: on
// the same data, 3 m lines simplified at r/8 = 7.8 m changed 5.0% of the
// pixels of the level-5 view, at an eighth of their width 0.8% (the package
// bytes of the level doubled; its decoded bytes stayed under 4% of the
// full-detail view's). Dynamic lines (width in pixels; pass 0) and
// polygons take level_tolerance.
inline double level_line_tolerance(const TileLevel& level, double width_m) {
  const double t = level_tolerance(level);
  return width_m > 0 ? std::min(t, width_m * kLevelToleranceShare) : t;
}

// "tiles/L<level>/x<X>_y<Y>.decals" (level >= 1), "tiles/x<X>_y<Y>.decals" (0).
std::string tile_file(int level, const TileKey& key);

}  // namespace prep
