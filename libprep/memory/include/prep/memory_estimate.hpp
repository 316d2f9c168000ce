// prep/memory_estimate.hpp — `decalprep build --max-memory SIZE`: a
// measured model of the build's peak resident memory, checked at the
// earliest points where its inputs are known, so that a build that will not
// fit stops early with a clear error (resource_error, exit code 6) instead of
// being killed by the kernel's OOM killer half-way.
//
// The model (coefficients and their fit: libprep/memory/memory_estimate.cpp
// and bench/memory/) is linear in what each point knows:
//   before read   the sizes of GeoJSON and .shp sources and the OSM driver's
//                 cache for .pbf/.osm sources (a lower bound);
//   after read    vertices of polygon parts, of line parts, and parts;
//   after clean   the same counts after repair, clipping and simplification,
//                 and line widths; added to the memory resident now (read and
//                 clean have run, so their peak is measured, not estimated);
//   after grid    the chosen decal grid's cell count and the bytes of its
//                 per-cell lists and BVHs, counted before they are made, and
//                 the dynamic lines' vertices; added to the memory resident
//                 then.
//   tile          (tileset builds) a tile's counts once its window is read,
//                 times the tiles built at once (--jobs), added to the memory
//                 resident when the tiles began.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <thread>

#include "prep/model.hpp"

namespace prep {

struct MemoryLimit {
  uint64_t bytes = 0;  // 0: no limit
  explicit operator bool() const { return bytes > 0; }
};

// One estimate of the build's peak RSS, with what it was computed from.
struct MemoryEstimate {
  const char* point = "";  // "before read", "after read", "after clean"
  double bytes = 0;
  std::string basis;  // e.g. "1204332 polygon vertices, 98211 line vertices, 5120 parts"
  // What it was computed from (after read / after clean; source bytes before read).
  double polygon_vertices = 0, line_vertices = 0, polygon_parts = 0, line_parts = 0;
  double source_bytes = 0;
  // After grid: the resident set then, the grid's cells and the bytes its
  // per-cell structures and the static geometry count.
  double resident_bytes = 0, grid_cells = 0, grid_cell_bytes = 0, geometry_bytes = 0;
  // A tile's estimate: the tile ("L0/x3_y-2.decals") and the tiles built at once.
  std::string tile;
  unsigned jobs = 0;
  // What check_memory tells the user to do; empty: the single-package advice.
  std::string advice;
};

// Parses a size: a number of bytes with an optional binary suffix K, M, G, T
// (also KB/KiB, MB/MiB, GB/GiB, TB/TiB; case-insensitive), e.g. "2G", "512M",
// "1.5G", "1073741824". Throws usage_error for anything else or for 0.
uint64_t parse_memory_size(const std::string& text);

// --max-memory SIZE: as parse_memory_size, but the unit is required (K, M,
// G, T, or B for bytes): a bare "200" is a usage_error that suggests "200M",
// since a limit of 200 bytes is never what was meant.
uint64_t parse_memory_limit(const std::string& text);

// "1.50 GiB", "512.0 MiB".
std::string format_memory_size(double bytes);

// The process's peak resident set so far, MiB (getrusage ru_maxrss).
double peak_rss_mib();
// The process's resident set now, bytes (/proc/self/statm).
double current_rss_bytes();

// The estimates. `dry_run`: the build stops after clean (no build/write).
MemoryEstimate estimate_before_read(const BuildSpec& scene, bool dry_run);
MemoryEstimate estimate_after_read(const BuildSpec& scene, const FeatureSet& features,
                                   bool dry_run);
MemoryEstimate estimate_after_clean(const BuildSpec& spec, const SceneFeatures& scene);
// Once the build stage has chosen the decal grid (ModelOptions::on_grid),
// before it makes the per-cell lists: what is resident then, plus the cell
// structures the grid's count says are coming, plus the dynamic lines of
// `scene` still to be built.
MemoryEstimate estimate_after_grid(const GridFootprint& grid, const SceneFeatures& scene);
// A tileset's tile, once its window of the work folder is cut (`tile`):
// `resident_bytes` (measured when the tiles began) plus `jobs` times the
// build part the after-clean model gives for the tile's counts. Each tile is
// checked with the same `jobs`, so the tiles in flight together never count
// more than `jobs` times the largest of them. `name` is the tile's file.
MemoryEstimate estimate_tile(const SceneFeatures& tile, double resident_bytes, unsigned jobs,
                             const std::string& name);

// Watches the process's resident set while it lives, from a thread of its
// own that reads /proc/self/statm every kRssWatchPollMs: for a stage whose
// memory no estimate made before it can bound. GDAL's GeoJSON driver parses
// each feature's JSON object whole, at up to 0.9 MiB of resident set per MB of
// a collection of small features but 22 MiB per MB of one large feature
// (bench/memory/geojson_peak_rss.csv), so a file's size does not say what
// reading it costs. Once the resident set exceeds `limit`, `on_exceed` is
// called once, on the watching thread, with the resident bytes seen; it must
// end the process (the stage cannot be interrupted inside GDAL). The
// resident set can pass the limit by what the stage allocates in one poll
// interval (a few MiB at the driver's rate, ~150 MiB/s). No limit: no thread.
inline constexpr int kRssWatchPollMs = 5;
class RssWatch {
 public:
  RssWatch(const MemoryLimit& limit, std::function<void(double rss_bytes)> on_exceed);
  ~RssWatch();
  RssWatch(const RssWatch&) = delete;
  RssWatch& operator=(const RssWatch&) = delete;

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// Throws resource_error when `estimate` exceeds `limit`; the message gives
// the estimate, the limit, its basis and what to do (raise --max-memory, set
// --resolution or --extent, split the scene).
void check_memory(const MemoryLimit& limit, const MemoryEstimate& estimate);

}  // namespace prep
