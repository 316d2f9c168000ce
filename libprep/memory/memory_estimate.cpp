// The --max-memory model (prep/memory_estimate.hpp). Coefficients are fitted
// from peak RSS measurements: see the table below and bench/memory/.
#include "prep/memory_estimate.hpp"

#include <cpl_vsi.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>
#include <thread>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

// ---- the model ------------------------------------------------------------
// Peak RSS of `decalprep build` (the maximum over its stages: the build
// stage, or write for polygon-heavy scenes) measured with bench/memory/
// measure.sh (/usr/bin/time; release, 2 threads) on generated FlatGeobuf
// inputs; rows in bench/memory/peak_rss.csv. Estimates in MiB after read /
// after clean / after the grid choice, measured 2026-11-25 once the model
// held its cell lists in the v1.3 layout and the writer freed its arrays as
// it went, when the polygon coefficient and the build base were refitted
// (they were 160 B per vertex over 120 MiB):
//
//   input (after read)              vertices   parts   peak   read   clean   grid
//   polygons 1e5 (star, 0-3 holes)     98594     563   80.9  108.4   103.6  112.7
//   polygons 3e5                      295890    1671  100.7  133.1   131.8  138.5
//   polygons 1e6                      985985    5655  166.1  225.7   230.6  216.6
//   polygons 1e7 (bench/run's set)   9859712   56312 1049.6 1489.2  1501.0 1254.0
//   lines 1e5 (width 4 m)             100000    2024  119.3  153.7   150.7  147.2
//   lines 3e5                         300000    6029  220.8  269.1   272.8  256.4
//   lines 1e6                        1000000   20077  570.7  681.6   700.9  620.8
//   squares 20000 (5 vertices)         80000   20000   70.6  110.8   113.4   91.6
//   squares 100000                    400000  100000  130.8  185.3   208.0  173.1
//   3-vertex lines 20000               60000   20000   88.3  135.2   139.1  119.4
//   3-vertex lines 100000             300000  100000  227.6  305.9   337.2  264.8
//   lines 3e5, width 40 m             300000    6029  349.4  269.1   616.7  420.8
//   Liechtenstein scene (OSM, 4 l.)    62425    6724  132.7  180.4   181.8  170.5
//   Monaco scene (OSM, DEM, 7 l.)     390829   51204  275.7  431.8   342.9  324.7
//
// Least squares on the polygon rows gives ~104 B per polygon vertex over a
// ~68 MiB build base (10^6 -> 10^7: 104 B); line vertices cost ~550 B;
// the per-part costs fit to about 0. The read and clean stages sit on a
// 54 MiB base (GDAL/PROJ/GEOS loaded, thread pools); the build stage on
// ~65-80 MiB: the adaptive decal grid (2e5..5e5 cells on these inputs;
// its cell count is only known inside build_model) adds ~10-25 MiB. The
// coefficients below (130 B per polygon vertex, 600 per line vertex, build
// base 96 MiB) keep the estimate above every measured peak by more than
// the run-to-run spread of the peak (~5-10 %): after clean 1.23x..1.77x of
// it, after read 1.19x..1.57x except very wide lines (next paragraph), after
// the grid choice 1.09x..1.39x. These assume the adaptive grid: a fixed fine
// --grid (2000x2000 on polygons 3e5: 271-301 MiB against 132 after clean)
// is seen only after the grid choice (about 560 MiB there), whose cell
// count the estimate then has.
//
// Line width matters: a segment widened to w covers more cells. Measured on
// lines 3e5 (mean segment 20 m, previous grid): width 1, 4, 10, 20, 40, 100 m
// -> 205, 212, 209, 232, 458, 2177 MiB, i.e. about +300 B x r^2 per line
// vertex with r = width / mean segment length. That term needs metres and
// widths, so it is in the estimate after clean only; the estimate after read
// assumes thin lines (r ~ 0.2) and the one after clean corrects it.
//
// A dry run (read -> clean) peaks in clean: 88 MiB for polygons 1e6, 96 for
// lines 1e6, 134 for 100000 squares: 40 B per vertex and 700 B per part.
//
// After read and after clean the stages before have run, so the build part
// is added to the resident set then (freed read memory, e.g. the OSM
// driver's cache, is not always handed back to the kernel).
//
// Before read only file sizes are known: one byte of memory per
// byte of GeoJSON or of .shp (geometry only, 16 B per vertex on disk,
// >= 330 B in the build) is a lower bound, so it stops only builds that
// cannot fit. What GDAL's GeoJSON driver itself holds depends on the file's
// structure, not its size (bench/memory/geojson.py, geojson_peak_rss.csv:
// 0.3-0.9 MiB after read per MB of a collection of small features, streamed
// a feature at a time; 22 MiB per MB of one large feature, its JSON object
// parsed whole), so no factor of the size bounds it: the read runs under
// RssWatch (memory_estimate.hpp), which stops the build at the limit. Other formats (GeoPackage,
// FlatGeobuf: possibly mostly attributes; zips) count only through the OSM term below.
constexpr double kMiB = 1024.0 * 1024.0;
constexpr double kBaseBytes = 60.0 * kMiB;       // read -> clean
constexpr double kBuildBaseBytes = 96.0 * kMiB;  // build -> write, with the decal grid
constexpr double kPerPolygonVertex = 130;
constexpr double kPerLineVertex = 600;
constexpr double kPerPolygonPart = 256;
constexpr double kPerLinePart = 256;
constexpr double kPerLineVertexWidthSquared = 300;  // x (width / mean segment length)^2
constexpr double kMaxWidthRatio = 20;               // r is capped: degenerate short lines
constexpr double kPerVertexDryRun = 40;
constexpr double kPerPartDryRun = 700;
constexpr double kPerSourceByte = 1.0;
// After the grid choice, on top of the resident set: the cell lists and
// BVHs to come, in the grid chooser's v1.2 count (with the entries' working
// copies: a line entry costs more than its count, 64 B against 40), and a
// tenth of the package for the writer (zstd state, frames in flight: it
// frees each array of the model as its frame is made).
constexpr double kAfterGridBytes = 8.0 * kMiB;
constexpr double kPerGridCellByte = 1.4;
constexpr double kPerPackageByteAfterGrid = 0.1;
constexpr double kPerDynamicVertexAfterGrid = 600;
// A tileset's tile (estimate_tile): the build part of the counts above, as
// a single build of the tile would add it over the read base, times the
// tiles built at once, on the resident set when the tiles began.
// bench/memory/tiles.py measures it (tile_peak_rss.csv, bench/REPORT.md):
// on generated polygons (10^5, 10^6 vertices), the generated mix of
// polygons and 3 m lines (10^6) and the Monaco scene, tiles of 500 m to
// 20 km, 1 and 2 jobs, the estimate was 1.07-1.87x the peak RSS (20 builds,
// 2026-11-25); the tightest is the 4 km mix tile with one job (126.5 MiB
// measured, 135.5 estimated). A tile's fixed part (its decal grid,
// thread-local state) measures 4-28 MiB against the build base's 36 MiB; a
// 28 MiB one left that tile at 1.00x. Small tiles are over-estimated by the
// fixed part times the jobs.
// OSM sources: GDAL's OSM driver keeps its node index in memory (up to
// OSM_MAX_TMPFILE_SIZE, 100 MB, then on disk), once per layer read, and
// layers are read side by side. One multipolygons layer, 1 thread, dry run:
// Liechtenstein (0.59 MB .pbf, 37k vertices) 83 MiB, Monaco (1.76 MB, 184k
// vertices) 125 MiB, i.e. about 27 MiB per MB of .pbf + 12 MiB over the
// base and the features. The full Liechtenstein scene (4 layers, 2
// threads) peaks at 129 MiB in read. This term is in the read stage only
// (the datasets are closed before project).
constexpr double kOsmPerSourceByte = 32;
constexpr double kOsmPerDataset = 20.0 * kMiB;
constexpr double kOsmCap = 150.0 * kMiB;

struct Counts {
  double polygon_vertices = 0, line_vertices = 0, polygon_parts = 0, line_parts = 0;
  double line_width_term = 0;  // sum over line vertices of min(r, kMaxWidthRatio)^2
};

// Memory the read stage needs for OSM sources on top of the features.
double osm_read_bytes(const BuildSpec& scene) {
  auto is_osm = [](const std::string& p) {
    auto ends = [&](const char* sfx) {
      const std::string x(sfx);
      return p.size() >= x.size() && p.compare(p.size() - x.size(), x.size(), x) == 0;
    };
    return ends(".pbf") || ends(".osm") || ends(".PBF") || ends(".OSM") || ends(".osm.bz2");
  };
  std::vector<double> per_layer;
  for (const LayerSpec& l : scene.layers) {
    if (!is_osm(l.source)) continue;
    VSIStatBufL st;
    const double bytes = VSIStatL(l.source.c_str(), &st) == 0 ? double(st.st_size) : 0.0;
    per_layer.push_back(std::min(kOsmCap, kOsmPerDataset + kOsmPerSourceByte * bytes));
  }
  // Layers are read side by side, at most `threads` at once: the largest ones.
  unsigned threads =
      scene.model.threads > 0 ? scene.model.threads : std::thread::hardware_concurrency();
  threads = std::max(1u, threads);
  std::sort(per_layer.begin(), per_layer.end(), std::greater<>());
  double sum = 0;
  for (size_t i = 0; i < per_layer.size() && i < threads; ++i) sum += per_layer[i];
  return sum;
}

// `build_part` (if given) receives what the build stage adds over the read
// stage's base: the part to add to a measured resident set.
MemoryEstimate model(const char* point, const Counts& c, bool dry_run, double read_extra,
                     double* build_part = nullptr) {
  MemoryEstimate e;
  e.point = point;
  e.polygon_vertices = c.polygon_vertices;
  e.line_vertices = c.line_vertices;
  e.polygon_parts = c.polygon_parts;
  e.line_parts = c.line_parts;
  // Read -> clean: the features and the OSM driver (read only).
  const double early = kBaseBytes + read_extra +
                       kPerVertexDryRun * (c.polygon_vertices + c.line_vertices) +
                       kPerPartDryRun * (c.polygon_parts + c.line_parts);
  e.bytes = early;
  if (!dry_run) {
    const double build = kBuildBaseBytes + kPerPolygonVertex * c.polygon_vertices +
                         kPerLineVertex * c.line_vertices + kPerPolygonPart * c.polygon_parts +
                         kPerLinePart * c.line_parts +
                         kPerLineVertexWidthSquared * c.line_width_term;
    e.bytes = std::max(early, build);
    if (build_part) *build_part = build - kBaseBytes;
  }
  std::ostringstream m;
  m << uint64_t(c.polygon_vertices) << " polygon vertices, " << uint64_t(c.line_vertices)
    << " line vertices, " << uint64_t(c.polygon_parts + c.line_parts) << " parts";
  e.basis = m.str();
  return e;
}

// The after-clean counts of a cleaned scene (or of one tile of it).
Counts counts_of(const SceneFeatures& scene) {
  Counts c;
  for (const ScenePolygon& p : scene.polygons) {
    c.polygon_parts += 1;
    c.polygon_vertices += double(p.shell.size());
    for (const Ring& h : p.holes) c.polygon_vertices += double(h.size());
  }
  for (const SceneLine& l : scene.lines) {
    c.line_parts += 1;
    const double n = double(l.points.size());
    c.line_vertices += n;
    // Width over the mean segment length (frame metres; l.width is already
    // scaled to the frame).
    double length = 0;
    for (size_t i = 1; i < l.points.size(); ++i)
      length += std::hypot(l.points[i].x - l.points[i - 1].x, l.points[i].y - l.points[i - 1].y);
    const double segments = l.closed ? n : n - 1;
    const double mean = segments > 0 ? length / segments : 0;
    const double r = mean > 0 ? std::min(l.width / mean, kMaxWidthRatio) : kMaxWidthRatio;
    c.line_width_term += n * r * r;
  }
  // Dynamic lines: widths are pixels; their build cost is the subdivided
  // 3D line, counted like a static line vertex.
  for (const SceneLine& l : scene.dynamic_lines) {
    c.line_parts += 1;
    c.line_vertices += double(l.points.size());
  }
  return c;
}

// Local file behind a GDAL path (/vsizip/x.zip/y -> x.zip); empty if none.
std::string local_file(const std::string& path) {
  std::string file = path;
  if (file.rfind("/vsizip/", 0) == 0) {
    file = file.substr(8);
    const auto zip = file.find(".zip");
    if (zip != std::string::npos) file = file.substr(0, zip + 4);
  } else if (file.rfind("/vsi", 0) == 0) {
    return "";
  }
  return file;
}

}  // namespace

uint64_t parse_memory_size(const std::string& text) {
  std::string t;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c)))
      t += char(std::toupper(static_cast<unsigned char>(c)));
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(t, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = t.substr(used);
  if (unit.size() > 1 && unit.back() == 'B') unit.pop_back();  // GB, GiB
  if (unit.size() > 1 && unit.back() == 'I') unit.pop_back();  // Gi
  double scale = 0;
  if (unit.empty())
    scale = 1;
  else if (unit == "K")
    scale = 1024.0;
  else if (unit == "M")
    scale = 1024.0 * 1024;
  else if (unit == "G")
    scale = 1024.0 * 1024 * 1024;
  else if (unit == "T")
    scale = 1024.0 * 1024 * 1024 * 1024;
  else if (unit == "B" && used > 0)
    scale = 1;
  if (used == 0 || scale == 0 || !(value > 0) || !std::isfinite(value * scale) ||
      value * scale >= 1.8e19) {
    fail<usage_error>(
        kNoStage, "--max-memory: expected a size such as 2G, 512M or 1073741824 (bytes), got \"" +
                      text + "\"");
  }
  return uint64_t(std::llround(value * scale));
}

uint64_t parse_memory_limit(const std::string& text) {
  const uint64_t bytes = parse_memory_size(text);
  // parse_memory_size took it, so it is a number with or without a unit.
  const auto last = text.find_last_not_of(" \t");
  if (last != std::string::npos && std::isdigit(static_cast<unsigned char>(text[last])) == 0 &&
      text[last] != '.')
    return bytes;
  std::string number = text;
  number.erase(0, number.find_first_not_of(" \t"));
  number.erase(number.find_last_not_of(" \t") + 1);
  fail<usage_error>(kNoStage, "--max-memory: \"" + text + "\" has no unit; give one, e.g. " +
                                  number + "M (MiB), " + number + "G (GiB), or " + number +
                                  "B if bytes are meant");
}

std::string format_memory_size(double bytes) {
  char buf[64];
  if (bytes >= 1024.0 * 1024 * 1024)
    std::snprintf(buf, sizeof buf, "%.2f GiB", bytes / (1024.0 * 1024 * 1024));
  else
    std::snprintf(buf, sizeof buf, "%.1f MiB", bytes / (1024.0 * 1024));
  return buf;
}

double current_rss_bytes() {
  // /proc/self/statm: size resident ... in pages.
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return peak_rss_mib() * 1024.0 * 1024.0;
  unsigned long size = 0, resident = 0;
  const int n = std::fscanf(f, "%lu %lu", &size, &resident);
  std::fclose(f);
  if (n != 2) return peak_rss_mib() * 1024.0 * 1024.0;
  return double(resident) * double(sysconf(_SC_PAGESIZE));
}

double peak_rss_mib() {
  struct rusage ru {};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_maxrss) / 1024.0;  // Linux: KiB
}

MemoryEstimate estimate_before_read(const BuildSpec& scene, bool dry_run) {
  double bytes = 0;
  std::vector<std::string> seen;
  // Only files whose size bounds what the read holds: GeoJSON (GDAL parses
  // the whole text into memory; GeoJSONSeq streams, so it is not one) and the
  // .shp of a Shapefile (geometry only).
  // A GeoPackage or FlatGeobuf may be mostly attributes; a zip is compressed.
  auto bounds_memory = [](const std::string& f) {
    std::string lower;
    for (char ch : f) lower += char(std::tolower(static_cast<unsigned char>(ch)));
    for (const char* ext : {".geojson", ".json", ".shp"}) {
      const std::string x(ext);
      if (lower.size() >= x.size() && lower.compare(lower.size() - x.size(), x.size(), x) == 0)
        return true;
    }
    return false;
  };
  for (const LayerSpec& l : scene.layers) {
    const std::string file = local_file(l.source);
    if (file.empty() || file != l.source || !bounds_memory(file) ||
        std::find(seen.begin(), seen.end(), file) != seen.end())
      continue;
    seen.push_back(file);
    VSIStatBufL st;
    if (VSIStatL(file.c_str(), &st) == 0 && VSI_ISREG(st.st_mode)) bytes += double(st.st_size);
  }
  MemoryEstimate e;
  e.point = "before read";
  e.source_bytes = bytes;
  (void)dry_run;
  const double osm = osm_read_bytes(scene);
  e.bytes = kBaseBytes + std::max(kPerSourceByte * bytes, osm);
  std::ostringstream m;
  m << uint64_t(bytes) << " bytes of GeoJSON/Shapefile geometry sources";
  if (osm > 0) m << ", the OSM driver's cache " << format_memory_size(osm);
  e.basis = m.str();
  return e;
}

MemoryEstimate estimate_after_read(const BuildSpec& scene, const FeatureSet& features,
                                   bool dry_run) {
  Counts c;
  for (const SourceLayer& layer : features.layers) {
    const bool polygons = layer.spec.kind == DecalKind::polygon;
    for (const SourceFeature& f : layer.features) {
      if (!f.drop_reason.empty()) continue;
      double v = 0;
      for (const Ring& r : f.rings) v += double(r.size());
      // Polygons of outline layers (and rings in line layers) become lines.
      if (f.is_polygon && polygons) {
        c.polygon_vertices += v;
        c.polygon_parts += 1;
      } else {
        c.line_vertices += v;
        c.line_parts += double(f.rings.size());
      }
    }
  }
  double build_part = 0;
  MemoryEstimate e = model("after read", c, dry_run, osm_read_bytes(scene), &build_part);
  // The read stage has run: freed read memory (the OSM driver's cache) is not
  // always handed back, so the build adds to what is resident now (the full
  // Liechtenstein scene: 120 MiB after read, 154 MiB peak in write).
  const double now = current_rss_bytes();
  if (!dry_run && now + build_part > e.bytes) {
    e.bytes = now + build_part;
    e.basis += ", on top of " + format_memory_size(now) + " resident after read";
  }
  return e;
}

MemoryEstimate estimate_after_clean(const BuildSpec& spec, const SceneFeatures& scene) {
  const Counts c = counts_of(scene);
  // Read and clean have run: their peak is measured, not estimated, and the
  // build adds its part to what is resident now (freed read memory is not
  // always handed back to the kernel: the Monaco scene stays at 208 MiB
  // after read and peaks at 239 MiB in write).
  (void)spec;
  double build_part = 0;
  MemoryEstimate e = model("after clean", c, false, 0.0, &build_part);
  e.bytes = std::max(peak_rss_mib() * kMiB, current_rss_bytes() + build_part);
  e.basis += ", on top of " + format_memory_size(current_rss_bytes()) + " resident now";
  return e;
}

MemoryEstimate estimate_after_grid(const GridFootprint& grid, const SceneFeatures& scene) {
  MemoryEstimate e;
  e.point = "after grid";
  double dynamic_vertices = 0;
  for (const SceneLine& l : scene.dynamic_lines) dynamic_vertices += double(l.points.size());
  e.line_vertices = dynamic_vertices;
  const double resident = current_rss_bytes();
  e.resident_bytes = resident;
  e.grid_cells = double(grid.cells);
  e.grid_cell_bytes = grid.cell_bytes;
  e.geometry_bytes = grid.geometry_bytes;
  e.bytes = resident + kAfterGridBytes + kPerGridCellByte * grid.cell_bytes +
            kPerPackageByteAfterGrid * (grid.geometry_bytes + grid.cell_bytes) +
            kPerDynamicVertexAfterGrid * dynamic_vertices;
  std::ostringstream m;
  m << grid.cells << " grid cells whose lists and BVHs count "
    << format_memory_size(grid.cell_bytes) << ", " << format_memory_size(grid.geometry_bytes)
    << " of static geometry, " << uint64_t(dynamic_vertices) << " dynamic line vertices, on top of "
    << format_memory_size(resident) << " resident now";
  e.basis = m.str();
  return e;
}

MemoryEstimate estimate_tile(const SceneFeatures& tile, double resident_bytes, unsigned jobs,
                             const std::string& name) {
  jobs = std::max(1u, jobs);
  double build_part = 0;
  MemoryEstimate e = model("tile", counts_of(tile), false, 0.0, &build_part);
  e.tile = name;
  e.jobs = jobs;
  e.resident_bytes = resident_bytes;
  e.bytes = resident_bytes + double(jobs) * build_part;
  std::ostringstream m;
  m << "tile " << name << ": " << e.basis << ", times " << jobs << (jobs == 1 ? " tile" : " tiles")
    << " built at once, on top of " << format_memory_size(resident_bytes)
    << " resident when the tiles began";
  e.basis = m.str();
  e.advice =
      "Raise --max-memory or build fewer tiles at once (--jobs): the tiles already written are "
      "kept, and the next run builds only the others; or choose smaller tiles (--tile-size), a "
      "new tiling that builds every tile again";
  return e;
}

RssWatch::RssWatch(const MemoryLimit& limit, std::function<void(double)> on_exceed) {
  if (!limit) return;
  thread_ = std::thread([this, bytes = double(limit.bytes), on_exceed = std::move(on_exceed)] {
    while (!stop_.load(std::memory_order_relaxed)) {
      const double rss = current_rss_bytes();
      if (rss > bytes) {
        on_exceed(rss);
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(kRssWatchPollMs));
    }
  });
}

RssWatch::~RssWatch() {
  stop_.store(true, std::memory_order_relaxed);
  if (thread_.joinable()) thread_.join();
}

void check_memory(const MemoryLimit& limit, const MemoryEstimate& estimate) {
  if (!limit || estimate.bytes <= double(limit.bytes)) return;
  fail<resource_error>(
      kMemoryStage,
      std::string("the build needs an estimated ") + format_memory_size(estimate.bytes) +
          " at its peak (estimate " + estimate.point + ", from " + estimate.basis +
          "), over --max-memory " + format_memory_size(double(limit.bytes)) +
          // Say "before" only when it is true: a stage no estimate foresaw
          // may already have passed the limit.
          (peak_rss_mib() * kMiB > double(limit.bytes)
               ? "; stopped, though the resident set has already peaked at " +
                     format_memory_size(peak_rss_mib() * kMiB) + ". "
               : std::string("; stopped before running out. ")) +
          (estimate.advice.empty()
               ? std::string("Raise --max-memory, thin the input (--resolution to simplify, "
                             "--extent or --where to keep less), or split the scene into tiles")
               : estimate.advice));
}

}  // namespace prep
