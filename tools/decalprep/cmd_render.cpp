// decalprep render — draws a package over terrain headless (GL via EGL, or
// the CPU evaluator with --cpu) and writes a PNG. Thin: parsing and calls
// into prep_render (prep/render.hpp).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <span>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

#include "command.hpp"
#include "prep/dem.hpp"
#include "prep/files.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/project.hpp"
#include "prep/read.hpp"
#include "prep/render.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

#include "decal/reader.hpp"

namespace {

struct RenderArgs {
  std::string package, dem, output, raw, decals_png, extent, extent_crs, size = "640x360", eye,
                                                                         target;
  std::string aa = "none", binding = "ssbo", only, assume_crs, method = "decal";
  std::string gpu_budget, level = "auto";  // tilesets: --gpu-budget SIZE, --level auto|L
  std::string lod = "on";                  // --lod on|off (LOCALIS LOD of dynamic lines)
  double lod_tolerance = 0.5;              // --lod-tolerance PX
  std::string slope_widths = "auto";       // --slope-widths auto|on|off
  double texture_resolution = 0;           // 0: the renderer's default
  double fov = 45.0, pitch = 45.0;
  std::optional<double> z_scale, nodata_fill;  // none: the package's
  std::vector<std::string> ramps;              // --ramp LAYER=value:#rrggbb,...
  uint32_t frames = 1;
  bool cpu = false, stats = false, ortho = false, fit = false, flat = false;
  bool strict = false;  // --strict: a warning is an error (exit 10)
};

// The largest image render makes: each side at most kMaxSide pixels and at
// most kMaxPixels in all (8192 x 8192). A pixel costs about 40 bytes
// across the RGBA8 image, the float decal layer and the GL targets, so the
// largest image takes about 2.5 GiB.
constexpr uint64_t kMaxSide = 16384;
constexpr uint64_t kMaxPixels = uint64_t(8192) * 8192;

// --size WxH: two decimal integers, each side 1..kMaxSide, W * H at most
// kMaxPixels. Parsed in 64 bits with nothing left over, so a number beyond
// 32 bits is refused rather than wrapped (4294967396 is not 100).
std::pair<uint32_t, uint32_t> parse_size(const std::string& text) {
  auto bad = [&](const std::string& why) { return "--size '" + text + "': " + why; };
  const size_t x = text.find('x');
  if (x == std::string::npos)
    prep::fail<prep::usage_error>(prep::kRenderStage, bad("expected WxH, e.g. 640x360"));
  auto side = [&](std::string_view digits, const char* which) {
    uint64_t v = 0;
    if (digits.empty() || digits.size() > 12 ||
        digits.find_first_not_of("0123456789") != std::string_view::npos)
      prep::fail<prep::usage_error>(prep::kRenderStage,
                                    bad(std::string(which) + " must be a whole number of pixels"));
    for (char c : digits) v = v * 10 + uint64_t(c - '0');
    if (v < 1 || v > kMaxSide)
      prep::fail<prep::usage_error>(prep::kRenderStage,
                                    bad(std::string(which) + " " + std::string(digits) +
                                        " is not within 1.." + std::to_string(kMaxSide)));
    return v;
  };
  const std::string_view all(text);
  const uint64_t w = side(all.substr(0, x), "the width"), h = side(all.substr(x + 1), "the height");
  if (w * h > kMaxPixels)
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  bad(std::to_string(w * h) + " pixels exceed the maximum of " +
                                      std::to_string(kMaxPixels) + " (8192x8192)"));
  return {uint32_t(w), uint32_t(h)};
}

// A render warning: on stderr, or with --strict an error (exit 10).
void warn(bool strict, const std::string& what) {
  if (strict)
    prep::fail<prep::strict_error>(prep::kRenderStage,
                                   what + " (--strict makes this warning an error)");
  decalprep::print_stage(prep::kRenderStage, "warning: %s\n", what.c_str());
}

std::string box(const prep::Extent& e) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%.3f,%.3f,%.3f,%.3f", e.xmin, e.ymin, e.xmax, e.ymax);
  return buf;
}

prep::Extent shifted(prep::Extent e, double dx, double dy) {
  return {e.xmin + dx, e.ymin + dy, e.xmax + dx, e.ymax + dy};
}

bool contains(const prep::Extent& outer, const prep::Extent& inner) {
  // A micrometre of slack: the build clips to the same box, in doubles.
  const double eps = 1e-6;
  return inner.xmin >= outer.xmin - eps && inner.xmax <= outer.xmax + eps &&
         inner.ymin >= outer.ymin - eps && inner.ymax <= outer.ymax + eps;
}

bool meets(const prep::Extent& a, const prep::Extent& b) {
  return a.xmax >= b.xmin && a.xmin <= b.xmax && a.ymax >= b.ymin && a.ymin <= b.ymax;
}

[[maybe_unused]] std::vector<double> numbers(const std::string& s, size_t n, const char* what) {
  std::vector<double> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
      // NaN or infinity gives no camera and no view: a blank image.
      if (!std::isfinite(v.back())) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      prep::fail<prep::usage_error>(prep::kRenderStage, std::string(what) + " '" + s + "' is not " +
                                                            std::to_string(n) + " finite numbers");
    }
  }
  if (v.size() != n)
    prep::fail<prep::usage_error>(
        prep::kRenderStage,
        std::string(what) + " '" + s + "' needs " + std::to_string(n) + " comma-separated numbers");
  return v;
}

namespace R = prep::render;

// What is drawn: one package, or the tiles of a tileset that meet the view.
// Coordinates are metres relative to `frame`'s origin (the package's, or the
// tileset's scene origin); `extent` is the data's box in them.
struct Scene {
  prep::SceneFrame frame;
  prep::Extent extent;
  bool tileset = false;
  prep::TilesetIndex index;
  std::vector<decal::Package> packages;  // own what `tiles` view
  std::vector<R::TileSource> tiles;
  std::string metadata;        // a package's metadata (the recorded DEM)
  std::string metadata_file;   // that package (a recorded DEM is relative to its folder)
  R::TileSelection selection;  // a tileset: the tiles drawn (prep/tile.hpp)
};

// Whether a tile of the view has LOD segments (render --stats).
bool has_lod(const std::vector<R::TileSource>& tiles) {
  for (const R::TileSource& t : tiles)
    for (const auto& b : t.source.blobs)
      if (b.id == decal::BlobId::lod_segments && b.count > 0) return true;
  return false;
}

void open_package(const std::string& path, decal::Package& pkg) {
  if (decal::Status s = decal::Package::open(path, pkg); !s)
    prep::fail<prep::format_error>(prep::kNoStage, s.message);
}

Scene open_scene(const std::string& path) {
  Scene sc;
  if (!prep::is_tileset(path)) {
    sc.packages.resize(1);
    open_package(path, sc.packages[0]);
    R::DecalSource src = R::source_of(sc.packages[0]);
    sc.frame = src.frame;
    sc.extent = src.extent;
    sc.metadata = std::string(sc.packages[0].metadata_json());
    sc.metadata_file = path;
    sc.tiles.push_back({src, prep::Extent{-INFINITY, -INFINITY, INFINITY, INFINITY}, 0, 0});
    return sc;
  }
  sc.tileset = true;
  sc.index = prep::read_tileset_index(path);
  sc.frame = sc.index.frame;
  const prep::Extent& e = sc.index.extent;
  sc.extent = {e.xmin - sc.frame.origin_x, e.ymin - sc.frame.origin_y, e.xmax - sc.frame.origin_x,
               e.ymax - sc.frame.origin_y};
  // The build's DEM and surface settings are the same in every tile.
  if (!sc.index.tiles.empty()) {
    decal::Package first;
    open_package(path + "/" + sc.index.tiles.front().file, first);
    sc.metadata = std::string(first.metadata_json());
    sc.metadata_file = path + "/" + sc.index.tiles.front().file;
  }
  return sc;
}

// One --ramp: a layer of the package's layer table and the stops its
// features' stored values go through when drawing.
struct RampArg {
  std::string text, layer;
  std::vector<prep::ColorStop> stops;
};

// "LAYER=value:#rrggbb[aa],value:#rrggbb[aa],..." with values increasing.
RampArg parse_ramp(const std::string& text) {
  auto bad = [&](const std::string& why) {
    return "--ramp '" + text + "': " + why + " (expected LAYER=value:#rrggbb,value:#rrggbb,...)";
  };
  RampArg r;
  r.text = text;
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    prep::fail<prep::usage_error>(prep::kRenderStage, bad("no layer name before '='"));
  r.layer = text.substr(0, eq);
  std::stringstream ss(text.substr(eq + 1));
  std::string stop;
  while (std::getline(ss, stop, ',')) {
    const size_t colon = stop.find(':');
    if (colon == std::string::npos)
      prep::fail<prep::usage_error>(prep::kRenderStage, bad("stop '" + stop + "' has no ':'"));
    prep::ColorStop cs{};
    try {
      size_t used = 0;
      cs.value = std::stod(stop.substr(0, colon), &used);
      if (used != colon || !std::isfinite(cs.value)) throw std::invalid_argument(stop);
    } catch (const std::exception&) {
      prep::fail<prep::usage_error>(prep::kRenderStage,
                                    bad("stop '" + stop + "' does not start with a finite number"));
    }
    try {
      cs.rgba = prep::parse_color(stop.substr(colon + 1));
    } catch (const prep::error& e) {
      prep::fail<prep::usage_error>(prep::kRenderStage, bad(e.what()));
    }
    if (!r.stops.empty() && !(cs.value > r.stops.back().value))
      prep::fail<prep::usage_error>(prep::kRenderStage, bad("stop values must increase"));
    r.stops.push_back(cs);
  }
  if (r.stops.empty()) prep::fail<prep::usage_error>(prep::kRenderStage, bad("no stops"));
  return r;
}

// Restyles every loaded tile with the --ramp stops, by the layer names of
// its package's layer table; the recoloured props live in `held`.
uint64_t apply_ramps(const std::vector<RampArg>& ramps, std::span<const decal::Package> packages,
                     std::span<R::TileSource> tiles, std::vector<R::RestyledProps>& held) {
  held.resize(tiles.size());
  uint64_t recoloured = 0;
  for (size_t k = 0; k < tiles.size(); ++k) {
    const std::string metadata(packages[k].metadata_json());
    const std::vector<std::string> names = R::layer_names(metadata);
    R::LayerRamps by_layer(names.size());
    for (const RampArg& r : ramps) {
      const auto it = std::find(names.begin(), names.end(), r.layer);
      if (it == names.end()) {
        std::string known;
        for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
        prep::fail<prep::usage_error>(
            prep::kRenderStage, "--ramp '" + r.text + "': the package has no layer '" + r.layer +
                                    "' (its layers: " + (known.empty() ? "none" : known) + ")");
      }
      by_layer[size_t(it - names.begin())] = r.stops;
    }
    R::restyle(tiles[k].source, by_layer, held[k]);
    recoloured += held[k].recoloured;
  }
  return recoloured;
}

// The bytes a package holds decoded: all its blobs, the unknown ids' too.
uint64_t decoded_bytes(const decal::Package& pkg) {
  uint64_t n = 0;
  for (const decal::BlobView& b : pkg.blobs()) n += b.bytes.size();
  return n;
}

// Loads the tiles of a tileset that the view draws (prep/tile.hpp:
// the level-0 tiles that meet the camera's ground footprint, or overview
// tiles where their resolution is below a pixel, within --gpu-budget), and
// only those. The budget counts each tile's blobs decoded, as its header
// and blob table give them (decal::read_package_sizes, no blob decoded);
// a loaded tile that holds another figure is refused.
void load_tiles(Scene& sc, const std::string& dir, const R::Camera& camera, uint32_t w, uint32_t h,
                double zmin, double zmax, R::TileSelectOptions select) {
  select.blob_bytes = [&dir](int, const prep::TileEntry& t) {
    decal::PackageSizes sizes;
    if (decal::Status s = decal::read_package_sizes(dir + "/" + t.file, sizes); !s)
      prep::fail<prep::format_error>(prep::kRenderStage, s.message);
    return sizes.raw_bytes;
  };
  sc.selection = R::select_tiles(sc.index, camera, w, h, zmin, zmax, select);
  const std::vector<R::SelectedTile>& hit = sc.selection.tiles;
  sc.packages.resize(hit.size());
  for (size_t k = 0; k < hit.size(); ++k) {
    const prep::TileEntry& t = *hit[k].entry;
    open_package(dir + "/" + t.file, sc.packages[k]);
    if (const uint64_t got = decoded_bytes(sc.packages[k]); got != hit[k].blob_bytes)
      prep::fail<prep::format_error>(prep::kRenderStage,
                                     dir + "/" + t.file + ": holds " + std::to_string(got) +
                                         " bytes of decoded blobs; its blob table said " +
                                         std::to_string(hit[k].blob_bytes) +
                                         " when the tiles were chosen (the file changed?)");
    R::DecalSource src = R::source_of(sc.packages[k]);
    if (src.frame.origin_x != t.origin_x || src.frame.origin_y != t.origin_y)
      prep::fail<prep::format_error>(
          prep::kNoStage, dir + "/" + t.file + ": origin differs from tileset.json's tile " +
                              prep::tile_name(t.key));
    const double ox = sc.frame.origin_x, oy = sc.frame.origin_y;
    sc.tiles.push_back(
        {src,
         {t.square.xmin - ox, t.square.ymin - oy, t.square.xmax - ox, t.square.ymax - oy},
         t.origin_x - ox,
         t.origin_y - oy});
  }
  if (sc.index.levels.empty()) {
    decalprep::print_stage(prep::kRenderStage, "%zu of %zu tiles meet the view\n", hit.size(),
                           sc.index.tiles.size());
    return;
  }
  std::string levels;
  for (size_t l = 0; l < sc.selection.per_level.size(); ++l)
    if (sc.selection.per_level[l])
      levels += (levels.empty() ? "" : ", ") + std::to_string(sc.selection.per_level[l]) +
                " of level " + std::to_string(l);
  decalprep::print_stage(prep::kRenderStage,
                         "%zu of %zu level-0 tiles meet the view; drawing %zu tiles (%s)%s\n",
                         sc.selection.full_detail_tiles, sc.index.tiles.size(), hit.size(),
                         levels.empty() ? "none" : levels.c_str(),
                         sc.selection.coarsened ? ", coarsened to fit --gpu-budget" : "");
}

// --level auto|L
std::optional<int> level_option(const std::string& s) {
  if (s == "auto") return std::nullopt;
  try {
    size_t used = 0;
    const int l = std::stoi(s, &used);
    if (used == s.size() && l >= 0) return l;
  } catch (const std::exception&) {
  }
  prep::fail<prep::usage_error>(
      prep::kRenderStage, "--level '" + s + "' must be auto or a level number (0: full detail)");
}

void run(const RenderArgs& a) {
  R::TileSelectOptions select;
  select.level = level_option(a.level);
  if (!a.gpu_budget.empty()) {
    try {
      select.gpu_budget = prep::parse_memory_size(a.gpu_budget);
    } catch (const prep::usage_error&) {
      prep::fail<prep::usage_error>(prep::kRenderStage,
                                    "--gpu-budget: expected a size such as 512M, 2G or "
                                    "1073741824 (bytes), got \"" +
                                        a.gpu_budget + "\"");
    }
  }
  Scene sc = open_scene(a.package);
  if (!sc.tileset && (select.level || select.gpu_budget))
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--level and --gpu-budget choose among a tileset's tiles; '" +
                                      a.package + "' is one package");
  // The frame and the data's box, as one package's (the tileset's scene frame).
  struct {
    prep::SceneFrame frame;
    prep::Extent extent;
  } src{sc.frame, sc.extent};

  R::RenderOptions opt;
  const auto [w, h] = parse_size(a.size);
  // The camera's angles: NaN or infinity, or a pitch that looks up or
  // along the ground, gives no view (a blank image).
  if (!std::isfinite(a.fov) || !(a.fov > 0 && a.fov < 180))
    prep::fail<prep::usage_error>(
        prep::kRenderStage,
        "--fov " + std::to_string(a.fov) + " must be a number of degrees in (0, 180)");
  if (!std::isfinite(a.pitch) || !(a.pitch > 0 && a.pitch <= 90))
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--pitch " + std::to_string(a.pitch) +
                                      " must be a number of degrees in (0, 90] below the horizon");
  opt.width = w;
  opt.height = h;
  opt.frames = a.frames;
  if (a.aa == "none")
    opt.aa = R::AntiAliasing::none;
  else if (a.aa == "coverage")
    opt.aa = R::AntiAliasing::coverage;
  else if (a.aa == "msaa4")
    opt.aa = R::AntiAliasing::msaa4;
  else
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--aa '" + a.aa + "' must be none, coverage or msaa4");
  // The CPU evaluator answers per point: it draws aliased, so comparisons
  // with the GL path use --aa none.
  if (a.cpu && opt.aa != R::AntiAliasing::none)
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--cpu draws without anti-aliasing; use --aa none");
  if (a.method == "decal")
    opt.method = R::Method::decal;
  else if (a.method == "volume")
    opt.method = R::Method::volume;
  else if (a.method == "texture")
    opt.method = R::Method::texture;
  else
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--method '" + a.method + "' must be decal, volume or texture");
  if (a.cpu && opt.method != R::Method::decal)
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--cpu is the decal evaluator; --method " + a.method +
                                      " is drawn with GL only (leave out --cpu)");
  if (opt.method != R::Method::decal && opt.aa != R::AntiAliasing::none)
    prep::fail<prep::usage_error>(
        prep::kRenderStage, "--method " + a.method + " draws without anti-aliasing; use --aa none");
  if (a.texture_resolution != 0 && opt.method != R::Method::texture)
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--texture-resolution needs --method texture");
  if (a.texture_resolution < 0 || !std::isfinite(a.texture_resolution))
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--texture-resolution must be a positive number of metres");
  opt.texture_resolution = a.texture_resolution;
  if (a.slope_widths == "auto")
    opt.slope_widths = R::SlopeWidths::package;
  else if (a.slope_widths == "on")
    opt.slope_widths = R::SlopeWidths::on;
  else if (a.slope_widths == "off")
    opt.slope_widths = R::SlopeWidths::off;
  else
    prep::fail<prep::usage_error>(
        prep::kRenderStage, "--slope-widths '" + a.slope_widths + "' must be auto, on or off");
  if (opt.slope_widths == R::SlopeWidths::on && opt.method != R::Method::decal)
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--slope-widths on needs --method decal (--method " + a.method +
                                      " draws the features' plan geometry)");
  if (a.binding == "ssbo")
    opt.binding = R::Binding::ssbo;
  else if (a.binding == "texture")
    opt.binding = R::Binding::texture;
  else
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--binding '" + a.binding + "' must be ssbo or texture");

  if (!a.only.empty()) {
    opt.draw_polygons = opt.draw_lines = opt.draw_dynamic = false;
    std::stringstream ss(a.only);
    std::string kind;
    while (std::getline(ss, kind, ',')) {
      if (kind == "polygons")
        opt.draw_polygons = true;
      else if (kind == "lines")
        opt.draw_lines = true;
      else if (kind == "dynamic")
        opt.draw_dynamic = true;
      else
        prep::fail<prep::usage_error>(
            prep::kRenderStage, "--only '" + a.only + "': kinds are polygons, lines, dynamic");
    }
  }
  // --lod: dynamic lines of LOD layers from the LOD segments this view
  // selects (prep/render.hpp RenderOptions::lod); a package without LOD
  // data draws the same either way.
  if (a.lod != "on" && a.lod != "off")
    prep::fail<prep::usage_error>(prep::kRenderStage, "--lod '" + a.lod + "' must be on or off");
  if (!(a.lod_tolerance > 0) || !std::isfinite(a.lod_tolerance))
    prep::fail<prep::usage_error>(prep::kRenderStage,
                                  "--lod-tolerance must be a positive number of pixels");
  opt.lod = a.lod == "on";
  opt.lod_tolerance_px = a.lod_tolerance;
  // --extent is in absolute coordinates of the package's frame CRS (or in
  // --extent-crs), as `build --extent` and the world file written below;
  // the renderer works relative to the package origin.
  prep::Extent view_extent, abs_view;
  bool topdown = !a.extent.empty();
  if (!a.extent_crs.empty() && !topdown)
    prep::fail<prep::usage_error>(prep::kRenderStage, "--extent-crs needs --extent");
  if (topdown) {
    auto v = numbers(a.extent, 4, "--extent");
    prep::Extent given{v[0], v[1], v[2], v[3]};
    if (given.empty())
      prep::fail<prep::usage_error>(
          prep::kRenderStage,
          "--extent '" + a.extent + "' is empty (xmin,ymin,xmax,ymax with max > min)");
    if (!a.extent_crs.empty() && src.frame.crs_wkt.empty())
      prep::fail<prep::usage_error>(
          prep::kRenderStage,
          "the package records no frame CRS, so --extent-crs cannot be used; "
          "give --extent in the package's frame coordinates");
    // Degrees given as frame metres (no --extent-crs): a usage error.
    prep::check_extent_units(given, a.extent_crs, src.frame, src.extent, "render");
    abs_view = prep::extent_in_frame_crs(given, a.extent_crs, src.frame, "render");
    const prep::Extent abs_package{
        src.extent.xmin + src.frame.origin_x, src.extent.ymin + src.frame.origin_y,
        src.extent.xmax + src.frame.origin_x, src.extent.ymax + src.frame.origin_y};
    view_extent = {abs_view.xmin - src.frame.origin_x, abs_view.ymin - src.frame.origin_y,
                   abs_view.xmax - src.frame.origin_x, abs_view.ymax - src.frame.origin_y};
    if (view_extent.empty())
      prep::fail<prep::usage_error>(prep::kRenderStage,
                                    "--extent '" + a.extent + "' is empty in the frame CRS");
    const bool misses = abs_view.xmax < abs_package.xmin || abs_view.xmin > abs_package.xmax ||
                        abs_view.ymax < abs_package.ymin || abs_view.ymin > abs_package.ymax;
    if (misses)
      warn(a.strict, "the view " + box(abs_view) + " misses the package extent " +
                         box(abs_package) +
                         " (xmin,ymin,xmax,ymax in the frame CRS); --extent takes absolute "
                         "coordinates of the package's frame CRS unless --extent-crs names "
                         "another");
  }
  prep::Extent terrain_extent = src.extent;
  if (topdown) {
    terrain_extent.xmin = std::min(terrain_extent.xmin, view_extent.xmin);
    terrain_extent.ymin = std::min(terrain_extent.ymin, view_extent.ymin);
    terrain_extent.xmax = std::max(terrain_extent.xmax, view_extent.xmax);
    terrain_extent.ymax = std::max(terrain_extent.ymax, view_extent.ymax);
  }
  // Terrain: --dem, else the DEM the package was built with (its metadata's
  // build_options.dem) when it can still be read, else flat. --flat forces
  // flat. The surface settings the package was built with (z-scale, no-data
  // fill, assumed CRS) apply unless given here, so the terrain is the
  // surface the dynamic lines were matched to (prep/dem.hpp).
  if (a.flat && !a.dem.empty())
    prep::fail<prep::usage_error>(prep::kRenderStage, "--flat and --dem exclude each other");
  prep::DemSpec dem = R::recorded_dem(sc.metadata, sc.metadata_file);
  const bool dem_from_package = !a.flat && a.dem.empty() && !dem.path.empty();
  if (a.flat) {
    dem.path.clear();
  } else if (!a.dem.empty()) {
    // The user's own --dem: any GDAL path, a network one included.
    dem.path = a.dem;
    dem.named_by_package = false;
  }
  // The outputs: only a regular file or nothing, never the package or the
  // DEM, refused before anything is drawn.
  {
    std::vector<std::string> inputs{a.package};
    if (!dem.path.empty()) inputs.push_back(dem.path);
    prep::check_output_file(a.output, "PNG", inputs);
    if (!a.decals_png.empty()) prep::check_output_file(a.decals_png, "--decals PNG", inputs);
    if (!a.raw.empty()) prep::check_output_file(a.raw, "--raw output", inputs);
    if (topdown)
      for (const std::string& side : prep::world_file_paths(a.output))
        prep::check_output_file(side, "world file", inputs);
  }
  if (a.z_scale) {
    if (!(*a.z_scale > 0) || !std::isfinite(*a.z_scale))
      prep::fail<prep::usage_error>(prep::kRenderStage, "--z-scale must be a positive number");
    dem.z_scale = *a.z_scale;
  }
  if (a.nodata_fill) {
    if (!std::isfinite(*a.nodata_fill))
      prep::fail<prep::usage_error>(prep::kRenderStage, "--nodata-fill must be a finite height");
    dem.nodata_fill = *a.nodata_fill;
  }
  if (!a.assume_crs.empty()) dem.assume_crs = a.assume_crs;
  R::Heightfield terrain;
  if (dem.path.empty()) {
    terrain = R::flat_heightfield(terrain_extent);
  } else if (!dem_from_package) {
    terrain = R::load_heightfield(dem, src.frame, terrain_extent, R::kMeshSamples);
  } else {
    try {
      terrain = R::load_heightfield(dem, src.frame, terrain_extent, R::kMeshSamples);
      decalprep::print_stage(prep::kRenderStage,
                             "terrain from the package's build DEM %s (--flat to ignore it)\n",
                             dem.path.c_str());
    } catch (const prep::error& e) {
      // Also a DEM the package names that is not opened (a network path, a
      // FIFO, a VRT: prep/dem.hpp package_dem_refusal).
      warn(a.strict, "the package was built with DEM " + dem.path +
                         ", which cannot be read here (" + e.what() +
                         "); drawing flat terrain (pass --dem PATH)");
      terrain = R::flat_heightfield(terrain_extent);
      dem.path.clear();
    }
  }
  // The DEM must cover what is drawn: the view of a top-down --extent, else
  // the package (tileset) extent that --fit frames and the mesh spans.
  // Beyond its footprint the terrain takes the DEM's edge heights.
  if (!dem.path.empty()) {
    const prep::Extent need = topdown ? view_extent : src.extent;
    const prep::Extent have = prep::dem_extent_in_frame(dem, src.frame);
    const double ox = src.frame.origin_x, oy = src.frame.origin_y;
    if (!contains(have, need))
      warn(a.strict,
           "the DEM " + dem.path + " covers " + box(shifted(have, ox, oy)) + ", which " +
               (meets(have, need) ? "does not cover all of " : "misses ") +
               (topdown ? "the view " : "the package extent ") + box(shifted(need, ox, oy)) +
               " (xmin,ymin,xmax,ymax in the frame CRS); the terrain there takes the DEM's edge "
               "heights");
  }
  if (topdown) {
    opt.camera = R::topdown_camera(view_extent, terrain.zmin, terrain.zmax);
  } else if (!a.eye.empty() || !a.target.empty()) {
    if (a.eye.empty() || a.target.empty())
      prep::fail<prep::usage_error>(prep::kRenderStage, "--eye and --target go together");
    auto e = numbers(a.eye, 3, "--eye"), t = numbers(a.target, 3, "--target");
    opt.camera.eye = {e[0], e[1], e[2]};
    opt.camera.target = {t[0], t[1], t[2]};
    const double dx = t[0] - e[0], dy = t[1] - e[1], dz = t[2] - e[2];
    const double along = std::hypot(dx, dy, dz);
    // An eye on its target has no direction to look in.
    if (!(along > 1e-6) || !std::isfinite(along))
      prep::fail<prep::usage_error>(
          prep::kRenderStage, "--eye " + a.eye + " and --target " + a.target +
                                  " must be apart (the camera looks from the eye to the target)");
    // Looking straight up or down, "up" is north instead of the z axis.
    if (std::hypot(dx, dy) <= 1e-9 * along) opt.camera.up = {0, 1, 0};
    opt.camera.fov_y_deg = a.fov;
    opt.camera.projection = a.ortho ? R::Projection::orthographic : R::Projection::perspective;
    double dist = std::hypot(e[0] - t[0], e[1] - t[1], e[2] - t[2]);
    opt.camera.near = std::max(0.1, dist * 1e-3);
    opt.camera.ortho_h = 2 * dist * std::tan(a.fov * 3.14159265358979 / 360);
    opt.camera.ortho_w = opt.camera.ortho_h * w / h;
    opt.camera.depth_range = 4 * dist;
  } else {
    // --fit (the default): frame the package extent obliquely.
    opt.camera =
        R::fit_camera(src.extent, terrain.zmin, terrain.zmax, w, h,
                      a.ortho ? R::Projection::orthographic : R::Projection::perspective, a.pitch);
  }

  // An --eye camera that sees the ground only away from the decals.
  if (!topdown && !a.eye.empty()) {
    const std::optional<prep::Extent> seen =
        R::ground_footprint(opt.camera, w, h, terrain.zmin, terrain.zmax);
    if (seen && !meets(*seen, src.extent))
      warn(a.strict, "the camera sees the ground at " +
                         box(shifted(*seen, src.frame.origin_x, src.frame.origin_y)) +
                         ", which misses the package extent " +
                         box(shifted(src.extent, src.frame.origin_x, src.frame.origin_y)) +
                         " (xmin,ymin,xmax,ymax in the frame CRS)");
  }
  // A tileset: only the tiles the view draws (select_tiles meets them with
  // what the camera can see of the terrain).
  if (sc.tileset) load_tiles(sc, a.package, opt.camera, w, h, terrain.zmin, terrain.zmax, select);
  // --ramp: value-coloured layers restyled when drawing, from the values the
  // package stores; the package itself is not changed.
  std::vector<RampArg> ramps;
  for (const std::string& text : a.ramps) ramps.push_back(parse_ramp(text));
  std::vector<R::RestyledProps> restyled;
  const uint64_t recoloured =
      ramps.empty() ? 0 : apply_ramps(ramps, sc.packages, sc.tiles, restyled);
  if (opt.method != R::Method::decal && opt.slope_widths == R::SlopeWidths::package)
    for (const R::TileSource& t : sc.tiles)
      if (!R::slope_layers(t.source, opt.slope_widths).empty()) {
        warn(a.strict,
             "the package's slope_widths layers are drawn with their plan widths by "
             "--method " +
                 a.method + " (slope widths need --method decal)");
        break;
      }
  uint64_t blob_bytes = 0;  // the loaded packages' blobs decoded (--gpu-budget's measure)
  for (const decal::Package& p : sc.packages) blob_bytes += decoded_bytes(p);
  const auto frame_start = std::chrono::steady_clock::now();
#ifdef PREP_RENDER_WITH_GL
  R::Image img =
      a.cpu ? R::render_cpu(sc.tiles, terrain, opt) : R::render_gl(sc.tiles, terrain, opt);
#else
  if (!a.cpu)
    prep::fail<prep::render_error>(prep::kRenderStage,
                                   "this build has no GL renderer (DECALPREP_GL=OFF); use --cpu");
  R::Image img = R::render_cpu(sc.tiles, terrain, opt);
#endif
  const double frame_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - frame_start)
          .count();
  prep::write_png_rgba(a.output, img.width, img.height, img.rgba);
  // The world file carries the absolute extent as given (not origin + relative).
  if (topdown) prep::write_world_file(a.output, abs_view, w, h, src.frame.crs_wkt);
  if (!a.decals_png.empty())
    prep::write_png_rgba(a.decals_png, img.width, img.height, prep::to_rgba8(img.decals));
  if (!a.raw.empty()) {
    std::ofstream out(a.raw, std::ios::binary);
    out.write(reinterpret_cast<const char*>(img.decals.data()),
              std::streamsize(img.decals.size() * sizeof(float)));
    if (!out) prep::fail<prep::output_error>(prep::kRenderStage, "cannot write '" + a.raw + "'");
  }
  if (a.stats) {
    if (opt.method == R::Method::decal)
      std::printf("device: %s, %ux%u, binding %s, aa %s\n", img.device.c_str(), w, h,
                  a.binding.c_str(), a.aa.c_str());
    else
      std::printf("device: %s, %ux%u, method %s\n", img.device.c_str(), w, h, a.method.c_str());
    std::printf("%-48s %12s %12s\n", "pass", "gpu ms", "wall ms");
    for (const auto& t : img.times)
      std::printf("%-48s %12.3f %12.3f\n", t.pass.c_str(), t.ms, t.wall_ms);
    // "terrain:", "lod:": --stats labels, not a stage prefix.
    std::printf("terrain: %ux%u vertices, within %s of the DEM surface\n", terrain.nx, terrain.ny,
                std::isfinite(terrain.surface_error_bound)
                    ? (std::to_string(terrain.surface_error_bound * 1e3) + " mm").c_str()
                    : "an unbounded distance (mesh not on the DEM lattice)");
    if (!ramps.empty())
      std::printf("ramps: %llu features recoloured (%zu --ramp)\n",
                  static_cast<unsigned long long>(recoloured), ramps.size());
    if (opt.method == R::Method::volume)
      std::printf("volume: %llu prism triangles, %u stencil+cover groups (%u z-fail, %u z-pass)\n",
                  static_cast<unsigned long long>(img.prism_triangles), img.volume_groups,
                  img.zfail_groups, img.volume_groups - img.zfail_groups);
    if (opt.method == R::Method::texture)
      std::printf(
          "texture: %ux%u texels at %.3f m, %llu bytes with mipmaps (%.1f MiB), %llu triangles\n",
          img.texture_width, img.texture_height, img.texture_resolution,
          static_cast<unsigned long long>(img.texture_bytes), double(img.texture_bytes) / 1048576.0,
          static_cast<unsigned long long>(img.texture_triangles));
    if (sc.tileset) {
      const R::TileSelection& s = sc.selection;
      std::printf("tiles: %zu drawn (", s.tiles.size());
      for (size_t l = 0; l < s.per_level.size(); ++l)
        std::printf("%slevel %zu: %zu", l ? ", " : "", l, s.per_level[l]);
      std::printf("), %zu of %zu level-0 tiles meet the view\n", s.full_detail_tiles,
                  sc.index.tiles.size());
      std::printf(
          "bytes: %llu package bytes loaded, %.2f%% of the full-detail %llu of this view; %llu "
          "blob bytes uploaded\n",
          static_cast<unsigned long long>(s.package_bytes),
          s.full_detail_bytes ? 100.0 * double(s.package_bytes) / double(s.full_detail_bytes) : 0.0,
          static_cast<unsigned long long>(s.full_detail_bytes),
          static_cast<unsigned long long>(blob_bytes));
      if (select.gpu_budget)
        std::printf(
            "gpu budget: %llu bytes of decoded blobs (GPU memory, not package bytes), %llu "
            "used, %zu tile groups coarsened to fit\n",
            static_cast<unsigned long long>(select.gpu_budget),
            static_cast<unsigned long long>(s.blob_bytes), s.coarsened);
    }
    std::printf("frame: %.3f ms (the %s render call, %u frame%s; tile loading not included)\n",
                frame_ms, a.cpu ? "cpu" : "gl", a.frames, a.frames == 1 ? "" : "s");
    if (img.dyn_kept || img.dyn_segments)
      std::printf(
          "dynamic lines: %u vertices kept, %u segments drawn, %u list nodes, %u list regrowths, "
          "%u pixels composited short of their list (step bound)\n",
          img.dyn_kept, img.dyn_segments, img.dyn_nodes, img.list_grows, img.dyn_truncated);
    if (img.lod_lines)
      std::printf(
          // not a stage prefix: a --stats label
          "lod: on, %.3g px: %llu LOD segments drawn of %llu full-detail segments (%.2f%%) on "
          "%llu LOD lines; %llu selected, %llu outside the frustum\n",
          opt.lod_tolerance_px, static_cast<unsigned long long>(img.lod_drawn),
          static_cast<unsigned long long>(img.lod_full),
          img.lod_full ? 100.0 * double(img.lod_drawn) / double(img.lod_full) : 0.0,
          static_cast<unsigned long long>(img.lod_lines),
          static_cast<unsigned long long>(img.lod_selected),
          static_cast<unsigned long long>(img.lod_selected - img.lod_drawn));
    else if (!opt.lod && has_lod(sc.tiles))
      // not a stage prefix: a --stats label
      std::printf("lod: off (the package has LOD segments; dynamic lines drawn in full)\n");
  }
}

const decalprep::CommandRegistrar kRegister(60, [](CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand(
      "render", "Draw a package over terrain (headless GL, or --cpu) into a PNG");
  cmd->footer(
      "Coordinates: --extent is in absolute coordinates of the package's frame CRS (the crs and\n"
      "origin of `decalprep info`), like build --extent; --extent-crs gives it in another CRS.\n"
      "The .pgw/.aux.xml world file of a top-down view uses the frame CRS's absolute coordinates.\n"
      "--eye and --target are metres relative to the package origin.\n"
      "Examples:\n"
      "  decalprep render city.decals --dem dem.tif --fit --pitch 50 --size 1280x720 -o city.png\n"
      "  decalprep render city.decals --extent 372000,4843200,373600,4844100 --size 800x450 -o "
      "top.png\n"
      "  decalprep render city.decals --extent 7.41,43.73,7.43,43.745 --extent-crs EPSG:4326 --cpu "
      "-o top.png");
  cmd->add_option("package", args->package, "Package (.decals) or tileset directory")->required();
  cmd->add_option("-o,--output", args->output, "Output PNG")->required();
  cmd->add_option("--dem", args->dem,
                  "DEM raster (any GDAL path); default: the DEM the package was built with, if it "
                  "is a local regular file (or a /vsizip/ path into one) in a self-contained "
                  "format, else flat with a warning");
  cmd->add_flag("--flat", args->flat, "Flat terrain, even if the package was built with a DEM");
  cmd->add_flag("--strict", args->strict,
                "Make every warning an error (exit 10): a view that misses the package, a DEM "
                "that does not cover the view, a build DEM that cannot be read or is not opened");
  cmd->add_option("--z-scale", args->z_scale,
                  "Height exaggeration (default: the package's build --z-scale, else 1)");
  cmd->add_option(
      "--nodata-fill", args->nodata_fill,
      "Height for DEM no-data, raw DEM units (default: the package's build --nodata-fill, else the "
      "nearest valid cell)");
  cmd->add_option("--assume-crs", args->assume_crs,
                  "CRS of a DEM that has none (default: the package's build --assume-crs; "
                  "otherwise such a DEM is an "
                  "error)");
  cmd->add_option("--extent", args->extent,
                  "Top-down orthographic view xmin,ymin,xmax,ymax in absolute coordinates of the "
                  "package's frame CRS "
                  "(as build --extent and the world file)");
  cmd->add_option("--extent-crs", args->extent_crs,
                  "CRS of --extent (e.g. EPSG:4326, lon/lat order; default: the frame)");
  cmd->add_option("--size", args->size,
                  "Image size WxH (default 640x360; each side 1..16384, at most 8192x8192 "
                  "pixels in all)");
  cmd->add_option("--eye", args->eye,
                  "Camera position x,y,z (metres relative to the package origin)");
  cmd->add_option("--target", args->target,
                  "Camera target x,y,z (metres relative to the package origin)");
  cmd->add_option("--fov", args->fov, "Vertical field of view, degrees, in (0, 180)");
  cmd->add_option("--pitch", args->pitch,
                  "--fit: camera pitch below the horizon, degrees, in (0, 90] (default 45)");
  cmd->add_flag("--ortho", args->ortho, "Orthographic projection");
  cmd->add_flag("--fit", args->fit, "Frame the package extent (default without --eye/--extent)");
  cmd->add_flag("--cpu", args->cpu, "Render with the CPU evaluator instead of GL");
  cmd->add_option("--aa", args->aa, "Anti-aliasing: none|coverage|msaa4");
  cmd->add_option("--binding", args->binding, "Blob binding: ssbo|texture");
  cmd->add_option("--method", args->method,
                  "Static decals drawn as: decal (screen-space decals, default), volume (stencil "
                  "shadow volumes) or texture (features rasterised into a mipmapped texture); GL "
                  "only, dynamic lines always as decals");
  cmd->add_option("--slope-widths", args->slope_widths,
                  "Static line widths along the terrain instead of in plan: auto (default: the "
                  "layers whose scene set slope_widths), on (every static line) or off; decal "
                  "method and --cpu");
  cmd->add_option("--texture-resolution", args->texture_resolution,
                  "--method texture: ground metres per texel (default 1, coarser where the "
                  "extent needs more than 8192 texels a side)");
  cmd->add_option("--level", args->level,
                  "Tileset: auto (default: per tile, the coarsest overview level whose "
                  "resolution is within a pixel) or L (that level everywhere; 0: full detail)");
  cmd->add_option("--gpu-budget", args->gpu_budget,
                  "Tileset: GPU memory the drawn tiles may take, as their blobs' decoded bytes "
                  "(not the smaller package bytes; e.g. 512M, 2G); coarser levels where the view "
                  "needs more, exit 6 when even the coarsest do (default: no limit)");
  cmd->add_option("--only", args->only, "Draw only these decal kinds: polygons,lines,dynamic");
  cmd->add_option("--lod", args->lod,
                  "LOCALIS LOD of dynamic lines built with lod = true: on (default; the segments "
                  "this view selects, chosen on the GPU, or on the CPU with --cpu) or off (every "
                  "vertex)");
  cmd->add_option("--lod-tolerance", args->lod_tolerance,
                  "--lod on: screen-space error in pixels a simplified line may have (default "
                  "0.5)");
  cmd->add_option("--ramp", args->ramps,
                  "Colour ramp for a value-coloured layer, applied when drawing (no rebuild): "
                  "LAYER=value:#rrggbb[aa],value:#rrggbb[aa],... (values increasing; linear per "
                  "channel between stops, clamped outside). Repeat for more layers")
      ->expected(1)
      ->take_all();
  cmd->add_option("--frames", args->frames,
                  "GL: render N frames, report the last one's pass times (warm)")
      ->check(CLI::Range(1u, 1000u));
  cmd->add_flag("--stats", args->stats,
                "Print per-pass times (GL timestamp queries and wall time), the frame time, "
                "LOD segments drawn against full detail; a "
                // not a stage prefix: help text
                "tileset: tiles drawn per level, package bytes loaded against full detail, "
                "decoded blob bytes, --gpu-budget; --method "
                "volume: prism triangles and groups; --method texture: texture size and bytes");
  cmd->add_option(
      "--raw", args->raw,
      "Write the static decal layer as float32 RGBA (straight alpha, row 0 at the top)");
  cmd->add_option("--decals", args->decals_png, "Write the decal layer alone as PNG");
  cmd->callback([args] {
    run(*args);
    decalprep::set_exit_code(prep::ExitCode::ok);
  });
});

}  // namespace
