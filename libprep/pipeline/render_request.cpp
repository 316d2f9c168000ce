// `decalprep render` as one request (prep/pipeline.hpp): every option
// checked once, here, then the scene opened, the terrain loaded, the camera
// placed, the tiles of a tileset chosen, drawn and written.
#include "prep/pipeline.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <span>
#include <sstream>
#include <string_view>
#include <utility>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "decal/reader.hpp"
#include "prep/dem.hpp"
#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/files.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/project.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

namespace prep::render {

// The helpers of render(), in a namespace of their own (the unity build
// shares one translation unit across the stage's files).
namespace request {
namespace {

[[noreturn]] void bad_option(const std::string& what) {
  fail<usage_error>(kRenderStage, what);
}

// -o and --decals write PNG: a name that promises another image format
// (.jpg, .tif, ...) is refused before anything is drawn, rather than given
// PNG bytes under that name.
void check_png_name(const char* option, const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  for (const char* other : {".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".gif", ".bmp", ".jp2"})
    if (ext == other)
      bad_option(std::string(option) + " '" + path + "': render writes PNG images; name the file " +
                 std::filesystem::path(path).replace_extension(".png").string() +
                 " (convert it afterwards, e.g. with gdal_translate, for " + ext + ")");
}

// --size WxH: two decimal integers, each side 1..kMaxImageSide, W * H at
// most kMaxImagePixels; W or Wx gives height 0, set from a top-down
// --extent's aspect (square_pixels). Parsed in 64 bits with nothing left over, so a
// number beyond 32 bits is refused rather than wrapped (4294967396 is not
// 100).
std::pair<uint32_t, uint32_t> parse_size(const std::string& text) {
  auto bad = [&](const std::string& why) { bad_option("--size '" + text + "': " + why); };
  auto side = [&](std::string_view digits, const char* which) {
    uint64_t v = 0;
    if (digits.empty() || digits.size() > 12 ||
        digits.find_first_not_of("0123456789") != std::string_view::npos)
      bad(std::string(which) + " must be a whole number of pixels");
    for (char c : digits) v = v * 10 + uint64_t(c - '0');
    if (v < 1 || v > kMaxImageSide)
      bad(std::string(which) + " " + std::string(digits) + " is not within 1.." +
          std::to_string(kMaxImageSide));
    return v;
  };
  const std::string_view all(text);
  const size_t x = text.find('x');
  // W or Wx: the height comes from the --extent's aspect (square_pixels).
  if (x == std::string::npos || x + 1 == text.size())
    return {uint32_t(side(all.substr(0, x), "the width")), 0};
  const uint64_t w = side(all.substr(0, x), "the width"), h = side(all.substr(x + 1), "the height");
  if (w * h > kMaxImagePixels)
    bad(std::to_string(w * h) + " pixels exceed the maximum of " + std::to_string(kMaxImagePixels) +
        " (8192x8192)");
  return {uint32_t(w), uint32_t(h)};
}

// `n` comma-separated finite numbers (--extent, --eye, --target).
std::vector<double> numbers(const std::string& s, size_t n, const char* what) {
  const std::optional<std::vector<double>> v = parse_number_list(s);
  if (!v)
    bad_option(std::string(what) + " '" + s + "' is not " + std::to_string(n) + " finite numbers");
  if (v->size() != n)
    bad_option(std::string(what) + " '" + s + "' needs " + std::to_string(n) +
               " comma-separated numbers");
  return *v;
}

// "LAYER=value:#rrggbb[aa],value:#rrggbb[aa],..." with values increasing.
RampRequest parse_ramp(const std::string& text) {
  auto bad = [&](const std::string& why) {
    bad_option("--ramp '" + text + "': " + why +
               " (expected LAYER=value:#rrggbb,value:#rrggbb,...)");
  };
  RampRequest r;
  r.text = text;
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0) bad("no layer name before '='");
  r.layer = text.substr(0, eq);
  try {
    r.stops = parse_color_stops(text.substr(eq + 1));
  } catch (const error& e) {
    bad(e.what());
  }
  return r;
}

// --level auto|L
std::optional<int> parse_level(const std::string& s) {
  if (s == "auto") return std::nullopt;
  try {
    size_t used = 0;
    const int l = std::stoi(s, &used);
    if (used == s.size() && l >= 0) return l;
  } catch (const std::exception&) {
  }
  bad_option("--level '" + s + "' must be auto or a level number (0: full detail)");
}

// --gpu-budget SIZE (prep/memory_estimate.hpp's sizes, in this option's words).
uint64_t parse_gpu_budget(const std::string& s) {
  try {
    return parse_memory_size(s);
  } catch (const usage_error&) {
    bad_option("--gpu-budget: expected a size such as 512M, 2G or 1073741824 (bytes), got \"" + s +
               "\"");
  }
}

// --aa, --method, --slope-widths, --binding, --decal-light: each one of its words.
template <class E>
E one_of(const std::string& option, const std::string& given,
         std::initializer_list<std::pair<const char*, E>> words, const char* must) {
  for (const auto& [word, value] : words)
    if (given == word) return value;
  bad_option(option + " '" + given + "' must be " + must);
}

// --size, --fov, --pitch, the drawing options and their pairings.
void check_drawing(const RenderRequest& a, RenderOptions& opt) {
  const auto [w, h] = parse_size(a.size);
  // The camera's angles: NaN or infinity, or a pitch that looks up or
  // along the ground, gives no view (a blank image).
  if (!std::isfinite(a.fov) || !(a.fov > 0 && a.fov < 180))
    bad_option("--fov " + std::to_string(a.fov) + " must be a number of degrees in (0, 180)");
  if (!std::isfinite(a.pitch) || !(a.pitch > 0 && a.pitch <= 90))
    bad_option("--pitch " + std::to_string(a.pitch) +
               " must be a number of degrees in (0, 90] below the horizon");
  opt.width = w;
  opt.height = h;
  opt.frames = a.frames;
  opt.method = one_of<Method>(
      "--method", a.method,
      {{"decal", Method::decal}, {"volume", Method::volume}, {"texture", Method::texture}},
      "decal, volume or texture");
  // The default: MSAA where the renderer has it. Of none, coverage and
  // msaa4 it came closest to a supersampled CPU render of the Monaco sample
  // in every view bench/aa_default.py draws (bench/REPORT.md
  // "Anti-aliasing").
  const bool aliased = a.cpu || opt.method != Method::decal;
  opt.aa = a.aa.empty() ? (aliased ? AntiAliasing::none : AntiAliasing::msaa4)
                        : one_of<AntiAliasing>("--aa", a.aa,
                                               {{"none", AntiAliasing::none},
                                                {"coverage", AntiAliasing::coverage},
                                                {"msaa4", AntiAliasing::msaa4}},
                                               "none, coverage or msaa4");
  // The CPU evaluator answers per point: it draws aliased, so comparisons
  // with the GL path use --aa none.
  if (a.cpu && opt.aa != AntiAliasing::none)
    bad_option("--cpu draws without anti-aliasing; use --aa none");
  if (a.cpu && opt.method != Method::decal)
    bad_option("--cpu is the decal evaluator; --method " + a.method +
               " is drawn with GL only (leave out --cpu)");
  if (a.texture_resolution != 0 && opt.method != Method::texture)
    bad_option("--texture-resolution needs --method texture");
  opt.texture_resolution = a.texture_resolution;
  opt.slope_widths = one_of<SlopeWidths>(
      "--slope-widths", a.slope_widths,
      {{"auto", SlopeWidths::package}, {"on", SlopeWidths::on}, {"off", SlopeWidths::off}},
      "auto, on or off");
  opt.decal_light =
      one_of<bool>("--decal-light", a.decal_light, {{"on", true}, {"off", false}}, "on or off");
  // --size W: the height comes with the extent (square_pixels); the other
  // rules are checked now.
  RenderOptions probe = opt;
  probe.height = std::max<uint32_t>(probe.height, 1);
  check_render_options(probe);
  opt.binding =
      one_of<Binding>("--binding", a.binding,
                      {{"ssbo", Binding::ssbo}, {"texture", Binding::texture}}, "ssbo or texture");
}

// --only, --lod, --lod-tolerance.
void check_kinds_and_lod(const RenderRequest& a, RenderOptions& opt) {
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
        bad_option("--only '" + a.only + "': kinds are polygons, lines, dynamic");
    }
  }
  // --lod: dynamic lines of LOD layers from the LOD segments this view
  // selects (RenderOptions::lod); a package without LOD data draws the same
  // either way.
  if (a.lod != "on" && a.lod != "off") bad_option("--lod '" + a.lod + "' must be on or off");
  if (!(a.lod_tolerance > 0) || !std::isfinite(a.lod_tolerance))
    bad_option("--lod-tolerance must be a positive number of pixels");
  opt.lod = a.lod == "on";
  opt.lod_tolerance_px = a.lod_tolerance;
}

// --extent, --extent-crs, --eye, --target and the terrain options.
void check_view(const RenderRequest& a, CheckedRender& c) {
  const bool topdown = !a.extent.empty();
  if (!a.extent_crs.empty() && !topdown) bad_option("--extent-crs needs --extent");
  if (!topdown && c.options.height == 0)
    bad_option("--size '" + a.size +
               "' gives no height: only a top-down --extent has an aspect to take it from; "
               "give WxH");
  if (topdown) {
    const std::vector<double> v = numbers(a.extent, 4, "--extent");
    c.extent = Extent{v[0], v[1], v[2], v[3]};
    if (c.extent->empty())
      bad_option("--extent '" + a.extent + "' is empty (xmin,ymin,xmax,ymax with max > min)");
  }
  if (a.flat && !a.dem.empty()) bad_option("--flat and --dem exclude each other");
  if (a.z_scale && (!(*a.z_scale > 0) || !std::isfinite(*a.z_scale)))
    bad_option("--z-scale must be a positive number");
  if (a.nodata_fill && !std::isfinite(*a.nodata_fill))
    bad_option("--nodata-fill must be a finite height");
  // A top-down --extent places the camera itself: --eye and --target are
  // not read then.
  if (topdown || (a.eye.empty() && a.target.empty())) return;
  if (a.eye.empty() || a.target.empty()) bad_option("--eye and --target go together");
  const std::vector<double> e = numbers(a.eye, 3, "--eye"), t = numbers(a.target, 3, "--target");
  c.eye = Vec3{e[0], e[1], e[2]};
  c.target = Vec3{t[0], t[1], t[2]};
  const double along = std::hypot(t[0] - e[0], t[1] - e[1], t[2] - e[2]);
  // An eye on its target has no direction to look in.
  if (!(along > 1e-6) || !std::isfinite(along))
    bad_option("--eye " + a.eye + " and --target " + a.target +
               " must be apart (the camera looks from the eye to the target)");
}

}  // namespace
}  // namespace request

namespace request {
namespace {

// A line for the user (RenderRequest::note).
void note(const RenderRequest& a, const std::string& line) {
  if (a.note)
    a.note(line);
  else
    std::fprintf(stderr, "%s\n", line.c_str());
}

// A render warning: a note, or with --strict an error (exit 10).
void warn(const RenderRequest& a, const std::string& what) {
  if (a.strict)
    fail<strict_error>(kRenderStage, "" + what + " (--strict makes this warning an error)");
  note(a, stage_message(kRenderStage, "warning: " + what));
}

std::string box(const Extent& e) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%.3f,%.3f,%.3f,%.3f", e.xmin, e.ymin, e.xmax, e.ymax);
  return buf;
}

Extent shifted(Extent e, double dx, double dy) {
  return {e.xmin + dx, e.ymin + dy, e.xmax + dx, e.ymax + dy};
}

bool contains(const Extent& outer, const Extent& inner) {
  // A micrometre of slack: the build clips to the same box, in doubles.
  const double eps = 1e-6;
  return inner.xmin >= outer.xmin - eps && inner.xmax <= outer.xmax + eps &&
         inner.ymin >= outer.ymin - eps && inner.ymax <= outer.ymax + eps;
}

bool meets(const Extent& a, const Extent& b) {
  return a.xmax >= b.xmin && a.xmin <= b.xmax && a.ymax >= b.ymin && a.ymin <= b.ymax;
}

// What is drawn: one package, or the tiles of a tileset that meet the view.
// Coordinates are metres relative to `frame`'s origin (the package's, or the
// tileset's scene origin); `extent` is the data's box in them.
struct Scene {
  SceneFrame frame;
  Extent extent;
  bool tileset = false;
  TilesetIndex index;
  // One package: the package and its source (a tileset's tiles are opened
  // one at a time as they are drawn: `list`).
  std::vector<decal::Package> packages;
  std::vector<TileSource> tiles;
  std::string metadata;             // a package's metadata (the recorded DEM)
  std::string metadata_file;        // that package (a recorded DEM is relative to its folder)
  bool slope_flagged = false;       // its layer table flags a layer slope_widths = true
  bool unlit_flagged = false;       // ... or a layer light = false
  bool min_widths_flagged = false;  // ... or a layer min_width_px
  TileSelection selection;          // a tileset: the tiles drawn (prep/tile.hpp)
  TileList list;                    // a tileset: those tiles, as the renderers open them
};

// What opening a tileset's tiles found, as they were drawn: the features
// the ramps recoloured (each tile counted once, however often it is opened)
// and whether a tile had LOD segments.
struct OpenedStats {
  std::vector<char> counted;
  uint64_t recoloured = 0;
  bool lod = false;
};

// Whether a source has LOD segments (RenderOutcome::lod_data_unused).
bool has_lod(const DecalSource& source) {
  for (const auto& b : source.blobs)
    if (b.id == decal::BlobId::lod_segments && b.count > 0) return true;
  return false;
}

void open_package(const std::string& path, decal::Package& pkg) {
  if (decal::Status s = decal::Package::open(path, pkg); !s)
    fail<format_error>(kNoStage, s.message);
}

Scene open_scene(const std::string& path) {
  Scene sc;
  if (!is_tileset(path)) {
    sc.packages.resize(1);
    open_package(path, sc.packages[0]);
    DecalSource src = source_of(sc.packages[0]);
    sc.frame = src.frame;
    sc.extent = src.extent;
    sc.metadata = std::string(sc.packages[0].metadata_json());
    sc.metadata_file = path;
    sc.slope_flagged = !src.slope_layers.empty();
    sc.unlit_flagged = !src.unlit_layers.empty();
    sc.tiles.push_back({src, Extent{-INFINITY, -INFINITY, INFINITY, INFINITY}, 0, 0});
    return sc;
  }
  sc.tileset = true;
  sc.index = read_tileset_index(path);
  sc.frame = sc.index.frame;
  const Extent& e = sc.index.extent;
  sc.extent = {e.xmin - sc.frame.origin_x, e.ymin - sc.frame.origin_y, e.xmax - sc.frame.origin_x,
               e.ymax - sc.frame.origin_y};
  // The build's DEM and surface settings are the same in every tile.
  if (!sc.index.tiles.empty()) {
    decal::Package first;
    open_package(path + "/" + sc.index.tiles.front().file, first);
    sc.metadata = std::string(first.metadata_json());
    sc.metadata_file = path + "/" + sc.index.tiles.front().file;
    const DecalSource src = source_of(first);
    sc.slope_flagged = !src.slope_layers.empty();
    sc.unlit_flagged = !src.unlit_layers.empty();
    sc.min_widths_flagged = !src.min_width_px.empty();
  }
  return sc;
}

// The bytes a package holds decoded: all its blobs, the unknown ids' too.
uint64_t decoded_bytes(const decal::Package& pkg) {
  uint64_t n = 0;
  for (const decal::BlobView& b : pkg.blobs()) n += b.bytes.size();
  return n;
}

// The note of the tiles a view draws.
void note_tiles(const RenderRequest& a, const Scene& sc) {
  const size_t drawn = sc.selection.tiles.size();
  if (sc.index.levels.empty()) {
    note(a, stage_message(kRenderStage, "" + std::to_string(drawn) + " of " +
                                            std::to_string(sc.index.tiles.size()) +
                                            " tiles meet the view"));
    return;
  }
  std::string levels;
  for (size_t l = 0; l < sc.selection.per_level.size(); ++l)
    if (sc.selection.per_level[l])
      levels += (levels.empty() ? "" : ", ") + std::to_string(sc.selection.per_level[l]) +
                " of level " + std::to_string(l);
  note(a, stage_message(kRenderStage,
                        "" + std::to_string(sc.selection.full_detail_tiles) + " of " +
                            std::to_string(sc.index.tiles.size()) +
                            " level-0 tiles meet the view; drawing " + std::to_string(drawn) +
                            " tiles (" + (levels.empty() ? "none" : levels) + ")" +
                            (sc.selection.coarsened ? ", coarsened to fit --gpu-budget" : "")));
}

LayerRamps ramps_by_layer(const std::vector<RampRequest>& ramps, const std::string& metadata);

// Chooses the tiles of a tileset that the view draws (prep/tile.hpp: the
// level-0 tiles that meet the camera's ground footprint, or overview tiles
// where their resolution is below a pixel, within --gpu-budget), and makes
// sc.list open them, one at a time, as the renderer draws them. The budget
// counts each tile's blobs decoded, as its header and blob table give them
// (decal::read_package_sizes, no blob decoded); an opened tile that holds
// another figure is refused. An opened tile is restyled by `ramps`.
void load_tiles(const RenderRequest& a, Scene& sc, const RenderOptions& opt,
                const Heightfield& terrain, TileSelectOptions select,
                const std::vector<RampRequest>& ramps, std::shared_ptr<OpenedStats> stats) {
  const std::string& dir = a.package;
  select.blob_bytes = [&dir](int, const TileEntry& t) {
    decal::PackageSizes sizes;
    if (decal::Status s = decal::read_package_sizes(dir + "/" + t.file, sizes); !s)
      fail<format_error>(kRenderStage, "" + s.message);
    return sizes.raw_bytes;
  };
  sc.selection =
      select_tiles(sc.index, opt.camera, opt.width, opt.height, terrain.zmin, terrain.zmax, select);
  const std::vector<SelectedTile>& hit = sc.selection.tiles;
  struct Want {
    std::string path, name;
    uint64_t blob_bytes;
    double origin_x, origin_y;
  };
  auto wants = std::make_shared<std::vector<Want>>();
  const double ox = sc.frame.origin_x, oy = sc.frame.origin_y;
  bool lines = false;
  for (const SelectedTile& h : hit) {
    const TileEntry& t = *h.entry;
    wants->push_back({dir + "/" + t.file, tile_name(t.key), h.blob_bytes, t.origin_x, t.origin_y});
    sc.list.places.push_back(
        {{t.square.xmin - ox, t.square.ymin - oy, t.square.xmax - ox, t.square.ymax - oy},
         t.origin_x - ox,
         t.origin_y - oy});
    lines = lines || t.lines > 0;
  }
  // The layer table is the scene's in every tile: the first tile's tells.
  sc.list.slope =
      opt.draw_lines && (opt.slope_widths == SlopeWidths::on
                             ? lines
                             : opt.slope_widths == SlopeWidths::package && sc.slope_flagged);
  sc.list.unlit = sc.unlit_flagged;
  sc.list.min_widths = sc.min_widths_flagged;
  stats->counted.assign(hit.size(), 0);
  struct Held {
    decal::Package package;
    RestyledProps restyled;
  };
  sc.list.open = [wants, ramps, stats, places = sc.list.places](size_t k) {
    const Want& w = (*wants)[k];
#ifdef __GLIBC__
    // The renderers let the last tile go before they open the next. The
    // heap's free holes, each a little too small for the next tile's
    // blobs, would grow with the tiles drawn (0.07 MiB a tile on 10^7
    // generated vertices in 2 km tiles); past kTrimSlack free bytes their
    // pages go back to the system. Not at every tile: pages given back
    // are faulted in again. There (1,122 tiles, GL, 2000x1000) trimming at
    // every tile took 31 s and peaked at 366 MiB, at 160 MiB of slack
    // 15 s and 392-416 MiB, never trimming 15 s and 504 MiB.
    constexpr size_t kTrimSlack = size_t(160) << 20;
    if (mallinfo2().fordblks > kTrimSlack) malloc_trim(0);
#endif
    auto held = std::make_shared<Held>();
    open_package(w.path, held->package);
    if (const uint64_t got = decoded_bytes(held->package); got != w.blob_bytes)
      fail<format_error>(kRenderStage, "" + w.path + ": holds " + std::to_string(got) +
                                           " bytes of decoded blobs; its blob table said " +
                                           std::to_string(w.blob_bytes) +
                                           " when the tiles were chosen (the file changed?)");
    OpenedTile out{{source_of(held->package), places[k].square, places[k].dx, places[k].dy}, {}};
    if (out.tile.source.frame.origin_x != w.origin_x ||
        out.tile.source.frame.origin_y != w.origin_y)
      fail<format_error>(kNoStage, w.path + ": origin differs from tileset.json's tile " + w.name);
    if (!ramps.empty())
      restyle(out.tile.source, ramps_by_layer(ramps, std::string(held->package.metadata_json())),
              held->restyled);
    if (!stats->counted[k]) {
      stats->counted[k] = 1;
      stats->recoloured += held->restyled.recoloured;
      stats->lod = stats->lod || has_lod(out.tile.source);
    }
    out.keep = std::move(held);
    return out;
  };
  note_tiles(a, sc);
}

// The --ramp stops by the index of their layer in a package's layer table
// (its metadata); a layer the table lacks is a usage error.
LayerRamps ramps_by_layer(const std::vector<RampRequest>& ramps, const std::string& metadata) {
  const std::vector<std::string> names = layer_names(metadata);
  const std::vector<std::string> attributes = layer_strings(metadata, "color_attribute");
  LayerRamps by_layer(names.size());
  for (const RampRequest& r : ramps) {
    const auto it = std::find(names.begin(), names.end(), r.layer);
    if (it == names.end()) {
      std::string known;
      for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
      bad_option("--ramp '" + r.text + "': the package has no layer '" + r.layer +
                 "' (its layers: " + (known.empty() ? "none" : known) + ")");
    }
    // A layer built without color_attribute stores no value (NaN) for its
    // features, which a ramp leaves as they are (formats/SPEC.md): it would
    // change nothing while --stats counted them recoloured.
    const size_t k = size_t(it - names.begin());
    if (k >= attributes.size() || attributes[k].empty())
      bad_option("--ramp '" + r.text + "': layer '" + r.layer +
                 "' was built without color_attribute, so its features carry no value to "
                 "colour by; set color_attribute (and color_ramp) for it in the scene file and "
                 "build again");
    by_layer[k] = r.stops;
  }
  return by_layer;
}

// A top-down --extent in the frame: absolute (as given, for the world file)
// and relative to the origin (for the camera).
struct View {
  bool topdown = false;
  Extent absolute, relative;
};

// --extent is in absolute coordinates of the package's frame CRS (or in
// --extent-crs), as `build --extent` and the world file; the renderer works
// relative to the package origin.
View place_extent(const RenderRequest& a, const CheckedRender& c, const Scene& sc) {
  View v;
  if (!c.extent) return v;
  v.topdown = true;
  const Extent& given = *c.extent;
  if (!a.extent_crs.empty() && sc.frame.crs_wkt.empty())
    bad_option(
        "the package records no frame CRS, so --extent-crs cannot be used; give --extent in the "
        "package's frame coordinates");
  // Degrees given as frame metres (no --extent-crs): a usage error.
  check_extent_units(given, a.extent_crs, sc.frame, sc.extent, "render");
  v.absolute = extent_in_frame_crs(given, a.extent_crs, sc.frame, "render");
  const double ox = sc.frame.origin_x, oy = sc.frame.origin_y;
  const Extent abs_package = shifted(sc.extent, ox, oy);
  v.relative = shifted(v.absolute, -ox, -oy);
  if (v.relative.empty()) bad_option("--extent '" + a.extent + "' is empty in the frame CRS");
  const Extent& w = v.absolute;
  if (w.xmax < abs_package.xmin || w.xmin > abs_package.xmax || w.ymax < abs_package.ymin ||
      w.ymin > abs_package.ymax)
    warn(a, "the view " + box(w) + " misses the package extent " + box(abs_package) +
                " (xmin,ymin,xmax,ymax in the frame CRS); --extent takes absolute coordinates "
                "of the package's frame CRS unless --extent-crs names another");
  return v;
}

// Square pixels for a top-down view. --size W (or Wx): the height is the
// extent's aspect times W, rounded, and the extent then widened about its
// centre by the rounding (under half a pixel, not stated). --size WxH of
// another aspect: the extent widened about its centre along the axis whose
// pixels would be smaller, so every pixel is (dx/W) x (dx/W) or
// (dy/H) x (dy/H), and the widened extent stated. --stretch keeps the
// extent as given (pixels dx/W by dy/H, as the world file then says).
void square_pixels(const RenderRequest& a, RenderOptions& opt, View& v, const Scene& sc) {
  Extent& e = v.absolute;
  const double dx = e.xmax - e.xmin, dy = e.ymax - e.ymin;
  const bool auto_height = opt.height == 0;
  if (auto_height) {
    const double h = std::max(1.0, std::round(double(opt.width) * dy / dx));
    if (h > double(kMaxImageSide) || h * double(opt.width) > double(kMaxImagePixels))
      bad_option("--size '" + a.size + "': the extent's aspect (" + std::to_string(dx) + " x " +
                 std::to_string(dy) + ") gives a height of " + std::to_string(uint64_t(h)) +
                 " pixels, beyond the limits (each side 1.." + std::to_string(kMaxImageSide) +
                 ", 8192x8192 pixels in all)");
    opt.height = uint32_t(h);
  }
  if (a.stretch) return;
  const double px = dx / double(opt.width), py = dy / double(opt.height);
  if (std::abs(px - py) <= 1e-12 * std::max(px, py)) return;
  const double cx = 0.5 * (e.xmin + e.xmax), cy = 0.5 * (e.ymin + e.ymax);
  if (px > py) {
    const double half = 0.5 * px * double(opt.height);
    e.ymin = cy - half;
    e.ymax = cy + half;
  } else {
    const double half = 0.5 * py * double(opt.width);
    e.xmin = cx - half;
    e.xmax = cx + half;
  }
  v.relative = shifted(e, -sc.frame.origin_x, -sc.frame.origin_y);
  if (!auto_height) {
    char m[512];
    std::snprintf(m, sizeof m,
                  "--extent widened to %.3f,%.3f,%.3f,%.3f for square pixels of %.6g m at %ux%u "
                  "(as given, they were %.6g x %.6g m); --stretch keeps the extent as given",
                  e.xmin, e.ymin, e.xmax, e.ymax, std::max(px, py), opt.width, opt.height, px, py);
    note(a, stage_message(kRenderStage, m));
  }
}

// Terrain: --dem, else the DEM the package was built with (its metadata's
// build_options.dem) when it can still be read, else flat. --flat forces
// flat. The surface settings the package was built with (z-scale, no-data
// fill, assumed CRS) apply unless given here, so the terrain is the surface
// the dynamic lines were matched to (prep/dem.hpp).
DemSpec choose_dem(const RenderRequest& a, const Scene& sc, bool& from_package) {
  DemSpec dem = recorded_dem(sc.metadata, sc.metadata_file);
  from_package = !a.flat && a.dem.empty() && !dem.path.empty();
  if (a.flat) {
    dem.path.clear();
    dem.more_paths.clear();
  } else if (!a.dem.empty()) {
    // The user's own --dem: any GDAL path, a network one included.
    dem.path = a.dem[0];
    dem.more_paths.assign(a.dem.begin() + 1, a.dem.end());
    dem.named_by_package = false;
  }
  if (a.z_scale) dem.z_scale = *a.z_scale;
  if (a.nodata_fill) dem.nodata_fill = *a.nodata_fill;
  if (!a.assume_crs.empty()) dem.assume_crs = a.assume_crs;
  return dem;
}

// The outputs: only a regular file or nothing, never the package or the
// DEM, refused before anything is drawn.
void check_outputs(const RenderRequest& a, const DemSpec& dem, bool topdown) {
  std::vector<std::string> inputs{a.package};
  if (!dem.path.empty()) {
    inputs.push_back(dem.path);
    inputs.insert(inputs.end(), dem.more_paths.begin(), dem.more_paths.end());
  }
  if (!a.terrain_file.empty()) inputs.push_back(a.terrain_file);
  check_output_file(a.output, "PNG", inputs);
  if (!a.decals_png.empty()) check_output_file(a.decals_png, "--decals PNG", inputs);
  if (!a.raw.empty()) check_output_file(a.raw, "--raw output", inputs);
  if (topdown)
    for (const std::string& side : world_file_paths(a.output))
      check_output_file(side, "world file", inputs);
}

// The terrain mesh under `extent`; a build DEM that cannot be read gives
// flat terrain with a warning (and `dem.path` cleared).
Heightfield load_terrain(const RenderRequest& a, DemSpec& dem, bool from_package,
                         const SceneFrame& frame, const Extent& extent) {
  if (dem.path.empty()) return flat_heightfield(extent);
  if (!from_package) return load_heightfield(dem, frame, extent, kMeshSamples);
  try {
    Heightfield h = load_heightfield(dem, frame, extent, kMeshSamples);
    note(a, stage_message(kRenderStage, "terrain from the package's build DEM " +
                                            dem_text(dem.path, dem.more_paths) +
                                            " (--flat to ignore it)"));
    return h;
  } catch (const error& e) {
    // Also a DEM the package names that is not opened (a network path, a
    // FIFO, a VRT: prep/dem.hpp package_dem_refusal).
    warn(a, "the package was built with DEM " + dem_text(dem.path, dem.more_paths) +
                ", which cannot be read here (" + e.what() +
                "); drawing flat terrain (pass --dem PATH)");
    dem.path.clear();
    dem.more_paths.clear();
    return flat_heightfield(extent);
  }
}

// RenderRequest::terrain_file's mesh (read_terrain_file: read as hostile);
// it must be made for this package's frame (the same origin).
Heightfield read_terrain_file(const RenderRequest& a, const Scene& sc) {
  const std::string& path = a.terrain_file;
  TerrainFile t = prep::render::read_terrain_file(path);
  if (t.origin_x != sc.frame.origin_x || t.origin_y != sc.frame.origin_y)
    fail<input_error>(kRenderStage, path + ": made for a frame whose origin is (" +
                                        std::to_string(t.origin_x) + ", " +
                                        std::to_string(t.origin_y) + "), but " + a.package +
                                        " has (" + std::to_string(sc.frame.origin_x) + ", " +
                                        std::to_string(sc.frame.origin_y) +
                                        "); write it again with decalprep terrain");
  // A file left from an earlier build of the package (SPEC: a reader may
  // compare source_xxh64): drawn all the same, as the page draws it.
  if (t.source_xxh64 != 0 && !sc.tileset) {
    const std::optional<FileDigest> d = file_digest(a.package);
    if (d && d->xxh64 != t.source_xxh64)
      warn(a, path + " was made from another build of " + a.package + " (its source_xxh64 " +
                  hex64(t.source_xxh64) + ", the package's XXH64 " + hex64(d->xxh64) +
                  "); drawing it all the same: write it again with `decalprep terrain " +
                  a.package + "`");
  }
  note(a, stage_message(kRenderStage, "terrain from the terrain file " + path));
  return std::move(t.mesh);
}

// The DEM must cover what is drawn: the view of a top-down --extent, else
// the package (tileset) extent that --fit frames and the mesh spans. Beyond
// its footprint the terrain takes the DEM's edge heights.
void check_dem_covers(const RenderRequest& a, const DemSpec& dem, const Scene& sc,
                      const View& view) {
  if (dem.path.empty()) return;
  const Extent need = view.topdown ? view.relative : sc.extent;
  const Extent have = dem_extent_in_frame(dem, sc.frame);
  const double ox = sc.frame.origin_x, oy = sc.frame.origin_y;
  if (!contains(have, need))
    warn(a, "the DEM " + dem_text(dem.path, dem.more_paths) + " covers " +
                box(shifted(have, ox, oy)) + ", which " +
                (meets(have, need) ? "does not cover all of " : "misses ") +
                (view.topdown ? "the view " : "the package extent ") + box(shifted(need, ox, oy)) +
                " (xmin,ymin,xmax,ymax in the frame CRS); the terrain there takes the DEM's edge "
                "heights");
}

// The camera: top-down over --extent, from --eye to --target, or --fit
// framing the data obliquely (the default).
Camera place_camera(const RenderRequest& a, const CheckedRender& c, const View& view,
                    const Scene& sc, const Heightfield& terrain) {
  const uint32_t w = c.options.width, h = c.options.height;
  const Projection projection = a.ortho ? Projection::orthographic : Projection::perspective;
  if (view.topdown) return topdown_camera(view.relative, terrain.zmin, terrain.zmax);
  if (!c.eye) return fit_camera(sc.extent, terrain.zmin, terrain.zmax, w, h, projection, a.pitch);
  const Vec3 &e = *c.eye, &t = *c.target;
  Camera cam;
  cam.eye = e;
  cam.target = t;
  const double dx = t[0] - e[0], dy = t[1] - e[1], dz = t[2] - e[2];
  const double along = std::hypot(dx, dy, dz);
  // Looking straight up or down, "up" is north instead of the z axis.
  if (std::hypot(dx, dy) <= 1e-9 * along) cam.up = {0, 1, 0};
  cam.fov_y_deg = a.fov;
  cam.projection = projection;
  const double dist = std::hypot(e[0] - t[0], e[1] - t[1], e[2] - t[2]);
  cam.near = std::max(0.1, dist * 1e-3);
  cam.ortho_h = 2 * dist * std::tan(a.fov * 3.14159265358979 / 360);
  cam.ortho_w = cam.ortho_h * w / h;
  cam.depth_range = 4 * dist;
  // A camera that sees the ground only away from the decals.
  const std::optional<Extent> seen = ground_footprint(cam, w, h, terrain.zmin, terrain.zmax);
  const double ox = sc.frame.origin_x, oy = sc.frame.origin_y;
  if (seen && !meets(*seen, sc.extent))
    warn(a, "the camera sees the ground at " + box(shifted(*seen, ox, oy)) +
                ", which misses the package extent " + box(shifted(sc.extent, ox, oy)) +
                " (xmin,ymin,xmax,ymax in the frame CRS)");
  return cam;
}

// The slope widths the volume and texture methods cannot draw, and the
// unlit layers the texture method lights with the rest of its texture.
void warn_plan_widths(const RenderRequest& a, const RenderOptions& opt, const Scene& sc) {
  if (opt.method == Method::texture && opt.decal_light && sc.unlit_flagged)
    warn(a,
         "the package's light = false layers are lit by --method texture, which lights its "
         "whole decal texture (--method decal or volume keeps them unlit, or --decal-light "
         "off)");
  if (opt.method == Method::decal || opt.slope_widths != SlopeWidths::package) return;
  if (sc.slope_flagged)
    warn(a, "the package's slope_widths layers are drawn with their plan widths by --method " +
                a.method + " (slope widths need --method decal)");
}

// Draws with GL, or the CPU evaluator with --cpu; `ms` the call's time.
Image draw(const RenderRequest& a, const Scene& sc, const Heightfield& terrain,
           const RenderOptions& opt, double& ms) {
  const auto start = std::chrono::steady_clock::now();
#ifdef PREP_RENDER_WITH_GL
  Image img = a.cpu ? render_cpu(sc.list, terrain, opt) : render_gl(sc.list, terrain, opt);
#else
  if (!a.cpu)
    fail<render_error>(kRenderStage, "this build has no GL renderer (DECALPREP_GL=OFF); use --cpu");
  Image img = render_cpu(sc.list, terrain, opt);
#endif
  ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return img;
}

// The PNG, the world file of a top-down view (the absolute extent as given,
// not origin + relative), --decals and --raw.
void write_outputs(const RenderRequest& a, const Image& img, const View& view,
                   const SceneFrame& frame) {
  write_png_rgba(a.output, img.width, img.height, img.rgba);
  if (view.topdown) write_world_file(a.output, view.absolute, img.width, img.height, frame.crs_wkt);
  if (!a.decals_png.empty())
    write_png_rgba(a.decals_png, img.width, img.height, to_rgba8(img.decals));
  if (!a.raw.empty()) {
    std::ofstream out(a.raw, std::ios::binary);
    out.write(reinterpret_cast<const char*>(img.decals.data()),
              std::streamsize(img.decals.size() * sizeof(float)));
    if (!out) fail<output_error>(kRenderStage, "cannot write '" + a.raw + "'");
  }
}

}  // namespace
}  // namespace request

CheckedRender check_render_request(const RenderRequest& a) {
  CheckedRender c;
  request::check_png_name("-o", a.output);
  if (!a.decals_png.empty()) request::check_png_name("--decals", a.decals_png);
  c.select.level = request::parse_level(a.level);
  if (!a.gpu_budget.empty()) c.select.gpu_budget = request::parse_gpu_budget(a.gpu_budget);
  request::check_drawing(a, c.options);
  request::check_kinds_and_lod(a, c.options);
  request::check_view(a, c);
  for (const std::string& text : a.ramps) c.ramps.push_back(request::parse_ramp(text));
  return c;
}

namespace request {
namespace {

// What render() draws, up to the drawing: the view, the terrain and the
// camera, after the outputs were checked.
struct Placed {
  View view;
  Heightfield terrain;
  Camera camera;
};

Placed place(const RenderRequest& a, CheckedRender& c, const Scene& sc) {
  if (!sc.tileset && (c.select.level || c.select.gpu_budget))
    bad_option("--level and --gpu-budget choose among a tileset's tiles; '" + a.package +
               "' is one package");
  Placed p;
  p.view = place_extent(a, c, sc);
  if (p.view.topdown) square_pixels(a, c.options, p.view, sc);
  if (!a.terrain_file.empty()) {
    check_outputs(a, DemSpec{}, p.view.topdown);
    p.terrain = read_terrain_file(a, sc);
    p.camera = place_camera(a, c, p.view, sc, p.terrain);
    return p;
  }
  bool dem_from_package = false;
  DemSpec dem = choose_dem(a, sc, dem_from_package);
  check_outputs(a, dem, p.view.topdown);
  Extent terrain_extent = sc.extent;
  if (p.view.topdown) {
    const Extent& v = p.view.relative;
    terrain_extent = {std::min(terrain_extent.xmin, v.xmin), std::min(terrain_extent.ymin, v.ymin),
                      std::max(terrain_extent.xmax, v.xmax), std::max(terrain_extent.ymax, v.ymax)};
  }
  p.terrain = load_terrain(a, dem, dem_from_package, sc.frame, terrain_extent);
  check_dem_covers(a, dem, sc, p.view);
  p.camera = place_camera(a, c, p.view, sc, p.terrain);
  return p;
}

}  // namespace
}  // namespace request

RenderView place_render_view(const RenderRequest& a) {
  using namespace request;
  CheckedRender c = check_render_request(a);
  const Scene sc = open_scene(a.package);
  Placed p = place(a, c, sc);
  RenderView v;
  v.options = c.options;
  v.options.camera = p.camera;
  v.terrain = std::move(p.terrain);
  v.frame = sc.frame;
  v.extent = sc.extent;
  if (p.view.topdown) v.topdown_absolute = p.view.absolute;
  if (!c.ramps.empty()) v.ramps = ramps_by_layer(c.ramps, sc.metadata);
  return v;
}

RenderOutcome render(const RenderRequest& a) {
  using namespace request;
  CheckedRender c = check_render_request(a);
  Scene sc = open_scene(a.package);
  Placed placed = place(a, c, sc);
  const View& view = placed.view;
  const Heightfield& terrain = placed.terrain;

  RenderOutcome out;
  out.options = c.options;
  out.options.camera = placed.camera;
  // --ramp: value-coloured layers restyled when drawing, from the values the
  // package stores; the package itself is not changed. A layer the package
  // lacks is an error before anything is drawn.
  if (!c.ramps.empty()) ramps_by_layer(c.ramps, sc.metadata);
  RestyledProps restyled;
  auto stats = std::make_shared<OpenedStats>();
  if (sc.tileset) {
    // Only the tiles the view draws (select_tiles meets them with what the
    // camera can see of the terrain), each opened as it is drawn.
    load_tiles(a, sc, out.options, terrain, c.select, c.ramps, stats);
    for (const SelectedTile& t : sc.selection.tiles) out.blob_bytes += t.blob_bytes;
  } else {
    if (!c.ramps.empty()) {
      restyle(sc.tiles[0].source, ramps_by_layer(c.ramps, sc.metadata), restyled);
      stats->recoloured = restyled.recoloured;
    }
    stats->lod = has_lod(sc.tiles[0].source);
    sc.list = tile_list(sc.tiles, out.options);
    out.blob_bytes = decoded_bytes(sc.packages[0]);
  }
  warn_plan_widths(a, out.options, sc);
  out.image = draw(a, sc, terrain, out.options, out.frame_ms);
  out.recoloured = stats->recoloured;
  write_outputs(a, out.image, view, sc.frame);

  out.terrain_nx = terrain.nx;
  out.terrain_ny = terrain.ny;
  out.surface_error_bound = terrain.surface_error_bound;
  out.ramps = c.ramps.size();
  out.tileset = sc.tileset;
  out.selection = std::move(sc.selection);
  for (SelectedTile& t : out.selection.tiles) t.entry = nullptr;  // the index goes
  out.index_tiles = sc.index.tiles.size();
  out.gpu_budget = c.select.gpu_budget;
  out.lod_data_unused = !out.options.lod && stats->lod;
  return out;
}

}  // namespace prep::render
