// One scene as `decalprep build` was asked for it: a scene file with the
// command line's overrides, or the file-less form's single layer
// (prep/pipeline.hpp "one scene, as asked"). Messages name the option.
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "decal/format.hpp"
#include "prep/error.hpp"
#include "prep/pipeline.hpp"
#include "prep/read.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

namespace prep {

namespace {

bool any_given(const FilelessLayer& l) {
  return !l.layer.empty() || !l.where.empty() || !l.sql.empty() || !l.kind.empty() || l.width ||
         !l.corner.empty() || !l.outline_mode.empty() || !l.color.empty() || l.dynamic ||
         !l.name.empty() || !l.color_attribute.empty() || !l.color_ramp.empty() ||
         !l.dash.empty() || l.casing_width || !l.casing_color.empty();
}

Extent parse_extent(const std::string& text) {
  Extent e;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(text);
  if (!(in >> e.xmin >> c1 >> e.ymin >> c2 >> e.xmax >> c3 >> e.ymax) || c1 != ',' || c2 != ',' ||
      c3 != ',' || e.empty()) {
    fail<usage_error>(
        kNoStage, "--extent: expected xmin,ymin,xmax,ymax with max > min, got \"" + text + "\"");
  }
  return e;
}

void parse_grid(const std::string& text, ModelOptions& b) {
  if (text == "auto") {
    b.grid_nx = b.grid_ny = 0;
    return;
  }
  unsigned nx = 0, ny = 0;
  char x = 0;
  std::istringstream in(text);
  if (!(in >> nx >> x >> ny) || (x != 'x' && x != 'X') || nx == 0 || ny == 0 || nx > 65536 ||
      ny > 65536) {
    fail<usage_error>(kNoStage,
                      "--grid: expected NXxNY (e.g. 500x500) or auto, got \"" + text + "\"");
  }
  b.grid_nx = nx;
  b.grid_ny = ny;
}

// The scene-file keys of a layer's style in the file-less form, checked
// as the scene file checks them, each message naming its option.
void fileless_style(const FilelessLayer& a, LayerSpec& l) {
  auto option = [](const char* name, auto&& parse) {
    try {
      return parse();
    } catch (const usage_error& e) {
      fail<usage_error>(kNoStage, std::string(name) + " " + e.what());
    }
  };
  const bool line = l.kind != DecalKind::polygon;
  if (!a.name.empty()) l.name = a.name;
  if (!a.color_attribute.empty() || !a.color_ramp.empty()) {
    if (a.color_attribute.empty() || a.color_ramp.empty())
      fail<usage_error>(kNoStage, "--color-attribute and --color-ramp go together");
    l.style.color.attribute = a.color_attribute;
    l.style.color.ramp = option("--color-ramp:", [&] { return parse_color_stops(a.color_ramp); });
  }
  if (!a.dash.empty()) {
    if (!line) fail<usage_error>(kNoStage, "--dash needs --kind line or outline");
    const std::optional<std::vector<double>> given = parse_number_list(a.dash);
    if (!given) fail<usage_error>(kNoStage, "--dash '" + a.dash + "': not a list of numbers");
    const std::vector<double>& v = *given;
    const std::string problem = dash_problem(v);
    if (!problem.empty()) fail<usage_error>(kNoStage, "--dash '" + a.dash + "': " + problem);
    l.dash = v;
  }
  if (a.casing_width) {
    if (!(*a.casing_width > 0) || !std::isfinite(*a.casing_width))
      fail<usage_error>(kNoStage, "--casing-width: must be > 0");
    if (!line || l.style.outline != decal::OutlineMode::normal)
      fail<usage_error>(kNoStage,
                        "--casing-width needs --kind line or outline with --outline-mode normal");
    l.casing_width = *a.casing_width;
  }
  if (!a.casing_color.empty()) {
    if (!a.casing_width) fail<usage_error>(kNoStage, "--casing-color needs --casing-width");
    l.casing_rgba = option("--casing-color:", [&] { return parse_color(a.casing_color); });
  }
}

// The file-less form: one layer of one GDAL source.
LayerSpec fileless_layer(const std::string& source, const FilelessLayer& a) {
  LayerSpec l;
  l.source = source;
  l.layer = a.layer;
  l.where = a.where;
  l.sql = a.sql;
  l.name = !a.layer.empty() ? a.layer : "layer0";
  l.kind = a.kind.empty() ? DecalKind::polygon : parse_kind(a.kind);
  l.dynamic = a.dynamic;
  if (!a.corner.empty()) l.style.corner = parse_corner(a.corner);
  if (!a.outline_mode.empty()) l.style.outline = parse_outline_mode(a.outline_mode);
  if (!a.color.empty()) l.style.color.rgba = parse_color(a.color);
  if (a.width) {
    if (!(*a.width > 0)) fail<usage_error>(kNoStage, "--width: must be > 0");
    // A static line's half width in a package is below kMaxHalfWidthMetres
    // (formats/SPEC.md "Index constraints"); the writer refuses the rest.
    if (!a.dynamic && !(*a.width < 2.0 * double(decal::kMaxHalfWidthMetres))) {
      char v[32];
      std::snprintf(v, sizeof v, "%g", *a.width);
      fail<usage_error>(kNoStage, std::string("--width: ") + v +
                                      " m is too wide: a static line must be narrower than 2e7 m");
    }
    l.style.width = *a.width;
  } else if (l.dynamic) {
    l.style.width = 3.0;  // pixels
  }
  if (l.dynamic && l.kind == DecalKind::polygon)
    fail<usage_error>(kNoStage, "--dynamic needs --kind line or outline");
  if (!l.sql.empty() && (!l.where.empty() || !l.layer.empty()))
    fail<usage_error>(kNoStage, "--sql replaces --layer and --where; give one or the other");
  if (l.style.outline != decal::OutlineMode::normal && l.style.corner != decal::CornerStyle::miter)
    fail<usage_error>(kNoStage, "--outline-mode inset/offset needs --corner miter");
  fileless_style(a, l);
  return l;
}

// Terrain matching of dynamic lines and the DEM surface (ModelOptions).
void apply_terrain_overrides(const SceneOverrides& o, ModelOptions& b) {
  if (o.lmax) {
    if (!(*o.lmax >= 0))
      fail<usage_error>(kNoStage, "--lmax: must be >= 0 metres (0: half the DEM cell)");
    b.lmax = *o.lmax;
  }
  if (o.terrain_tolerance) {
    if (!(*o.terrain_tolerance >= 0))
      fail<usage_error>(kNoStage,
                        "--terrain-tolerance: must be >= 0 metres (0: uniform subdivision)");
    b.terrain_tolerance = *o.terrain_tolerance;
  }
  if (o.z_scale) {
    if (!std::isfinite(*o.z_scale))
      fail<usage_error>(kNoStage, "--z-scale: must be a finite number");
    b.z_scale = *o.z_scale;
  }
  if (o.nodata_fill) {
    if (!std::isfinite(*o.nodata_fill))
      fail<usage_error>(kNoStage, "--nodata-fill: must be a finite height");
    b.nodata_fill = *o.nodata_fill;
  }
}

// Command-line values override the scene file's.
void apply_overrides(const SceneOverrides& o, BuildSpec& scene) {
  if (!o.crs.empty()) scene.crs = o.crs;
  if (!o.assume_crs.empty()) scene.assume_crs = o.assume_crs;
  if (!o.extent.empty()) scene.extent = parse_extent(o.extent);
  if (!o.extent_crs.empty()) scene.extent_crs = o.extent_crs;
  if (!o.extent_crs.empty() && !scene.extent)
    fail<usage_error>(kNoStage, "--extent-crs needs --extent");
  if (!o.dem.empty()) {
    scene.dem = o.dem[0];
    scene.dem_more.assign(o.dem.begin() + 1, o.dem.end());
  }
  if (o.resolution) {
    if (!(*o.resolution >= 0)) fail<usage_error>(kNoStage, "--resolution: must be >= 0 metres");
    scene.resolution = *o.resolution;
  }
  if (o.tile_size) {
    if (!(*o.tile_size >= kMinTileSize && *o.tile_size <= kMaxTileSize))
      fail<usage_error>(kNoStage,
                        "--tile-size: must be in [1, 4000000] metres of the frame CRS (a tile's "
                        "half must fit int32 millimetres around its centre)");
    scene.tile_size = *o.tile_size;
  }
  if (!o.levels.empty()) {
    if (o.levels == "auto") {
      scene.levels = kLevelsAuto;
    } else {
      int n = -1;
      char tail = 0;
      if (std::sscanf(o.levels.c_str(), "%d%c", &n, &tail) != 1 || n < 0 || n > kMaxLevels)
        fail<usage_error>(
            kNoStage, "--levels: expected a number of overview levels (0 to 16) or auto, not '" +
                          o.levels + "'");
      scene.levels = n;
    }
  }
  if (!o.repair.empty()) scene.repair = parse_repair_method(o.repair);
  if (!o.grid.empty()) parse_grid(o.grid, scene.model);
  if (o.leaf_capacity) scene.model.qt_leaf_capacity = *o.leaf_capacity;
  if (o.max_depth) scene.model.qt_max_depth = *o.max_depth;
  if (o.threads) scene.model.threads = *o.threads;
  if (o.skip_failures) scene.skip_failures = true;
  if (o.allow_empty) scene.allow_empty = true;
  apply_terrain_overrides(o, scene.model);
}

}  // namespace

BuildSpec scene_spec(const SceneRequest& request) {
  BuildSpec scene;
  if (request.input.ends_with(".toml")) {
    if (any_given(request.layer)) {
      fail<usage_error>(
          kBuildStage,
          "--layer/--where/--sql/--kind/--width/--corner/--outline-mode/--color/--dynamic/"
          "--name/--color-attribute/--color-ramp/--dash/--casing-width/--casing-color "
          "describe the single layer of the file-less form; with a scene file set them in " +
              request.input);
    }
    scene = load_scene_file(request.input);
  } else {
    LayerSpec layer = fileless_layer(request.input, request.layer);
    if (layer.casing_width > 0) scene.layers.push_back(casing_layer(layer));
    scene.layers.push_back(std::move(layer));
  }
  apply_overrides(request.overrides, scene);
  // Overview levels are tiles of a tileset (formats/SPEC.md "Overview levels").
  const std::string levels_from =
      !request.overrides.levels.empty() ? "--levels" : "[tiling] levels in " + request.input;
  if (scene.levels != 0 && scene.tile_size <= 0)
    fail<usage_error>(
        kNoStage, levels_from +
                      ": overview levels are levels of a tileset: give --tile-size (or [tiling] "
                      "tile_size)");
  if (scene.levels > 0 && std::ldexp(scene.tile_size, scene.levels) > kMaxTileSize)
    fail<usage_error>(kNoStage, levels_from + ": level " + std::to_string(scene.levels) +
                                    " would have tiles of " +
                                    std::to_string(std::ldexp(scene.tile_size, scene.levels)) +
                                    " m, above the largest tile size (4000000 m)");
  return scene;
}

ExitCode build_exit_code(const SceneSpec& scene, const BuildResult& result) {
  // skip_failures: features that would have stopped the build (OGR decode,
  // PROJ, GEOS, out of the build's range: prep/feature_failure.hpp) were
  // dropped and recorded; the package is partial (ogr2ogr -skipfailures).
  return scene.skip_failures && result.skipped_failures > 0 ? ExitCode::partial : ExitCode::ok;
}

}  // namespace prep
