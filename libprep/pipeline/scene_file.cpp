// Scene file parser (toml++). Every key is documented in samples/README.md;
// an unknown key is an error, so a typo never silently falls back to a
// default.
#include "prep/pipeline.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

#include "prep/error.hpp"
#include "prep/files.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

namespace prep {
namespace {

// Where a key sits, for messages: "scene.toml:12: layer[2].kind".
struct KeyRef {
  const std::string& file;
  std::string key;
  int line;
};

// "scene.toml:12: layer[2].kind: what".
std::string key_message(const KeyRef& ref, const std::string& what) {
  return ref.file + ":" + std::to_string(ref.line) + ": " + ref.key + ": " + what;
}

[[noreturn]] void fail_key(const KeyRef& ref, const std::string& what) {
  prep::fail<scene_error>(kNoStage, key_message(ref, what));
}

int line_of(const toml::node& n) {
  return static_cast<int>(n.source().begin.line);
}

// Every problem of a scene file, reported together in line order (a user
// fixes them in one pass): each key is parsed on its own, and a key's
// error is recorded and the next key parsed.
struct Problems {
  std::vector<std::pair<int, std::string>> list;  // line, message

  // Runs `parse`; a scene_error it throws is recorded at `line`. False
  // when it threw.
  template <typename F>
  bool run(int line, F&& parse) {
    try {
      parse();
      return true;
    } catch (const scene_error& e) {
      list.emplace_back(line, e.what());
      return false;
    }
  }
  // A problem found outside a key's parse (a layer's keys that do not go
  // together).
  void add(const KeyRef& ref, const std::string& what) {
    list.emplace_back(ref.line, key_message(ref, what));
  }
};

// The known keys of each table, for "did you mean" (samples/README.md
// documents them).
constexpr std::string_view kRootKeys[] = {
    "source", "crs",   "assume_crs", "extent_crs",    "extent",      "resolution", "repair",
    "dem",    "build", "tiling",     "skip_failures", "allow_empty", "layer"};
constexpr std::string_view kLayerKeys[] = {
    "name",       "source",       "layer",        "where",           "sql",
    "kind",       "dynamic",      "lod",          "color",           "color_attribute",
    "color_ramp", "casing_width", "casing_color", "slope_widths",    "dash",
    "width",      "corner",       "outline_mode", "order_attribute", "shared_edges",
    "light",      "min_width_px", "min_width_m"};
constexpr std::string_view kBuildKeys[] = {
    "grid", "target_per_cell",   "max_cells", "leaf_capacity", "max_depth", "miter_limit_deg",
    "lmax", "terrain_tolerance", "z_scale",   "nodata_fill",   "threads"};
constexpr std::string_view kTilingKeys[] = {"tile_size", "levels"};

// Optimal string alignment distance (edits, with a swap of two neighbours
// counting one).
size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// The unknown key's error, with the nearest known key within two edits.
template <size_t N>
[[noreturn]] void fail_unknown(const KeyRef& ref, std::string_view key,
                               const std::string_view (&known)[N]) {
  std::string_view best;
  size_t best_d = 3;
  for (std::string_view k : known) {
    const size_t d = edit_distance(key, k);
    if (d < best_d) best_d = d, best = k;
  }
  fail_key(ref, best.empty() ? "unknown key (see samples/README.md)"
                             : "unknown key; did you mean \"" + std::string(best) +
                                   "\"? (see samples/README.md)");
}

std::string type_name(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::string: return "string";
    case toml::node_type::integer: return "integer";
    case toml::node_type::floating_point: return "float";
    case toml::node_type::boolean: return "boolean";
    case toml::node_type::array: return "array";
    case toml::node_type::table: return "table";
    default: return "date/time";
  }
}

std::string get_string(const toml::node& n, const KeyRef& ref) {
  if (!n.is_string()) fail_key(ref, "expected a string, got " + type_name(n));
  return std::string(*n.value<std::string_view>());
}

double get_number(const toml::node& n, const KeyRef& ref) {
  if (!n.is_number()) fail_key(ref, "expected a number, got " + type_name(n));
  return *n.value<double>();
}

bool get_bool(const toml::node& n, const KeyRef& ref) {
  if (!n.is_boolean()) fail_key(ref, "expected true or false, got " + type_name(n));
  return *n.value<bool>();
}

uint32_t get_count(const toml::node& n, const KeyRef& ref, int64_t min, int64_t max) {
  if (!n.is_integer()) fail_key(ref, "expected an integer, got " + type_name(n));
  int64_t v = *n.value<int64_t>();
  if (v < min || v > max)
    fail_key(ref, "value " + std::to_string(v) + " out of range [" + std::to_string(min) + ", " +
                      std::to_string(max) + "]");
  return static_cast<uint32_t>(v);
}

double get_non_negative(const toml::node& n, const KeyRef& ref) {
  double v = get_number(n, ref);
  if (!(v >= 0) || !std::isfinite(v))
    fail_key(ref, "expected a finite number >= 0, got " + std::to_string(v));
  return v;
}

// Runs `parse` and turns a usage_error from a value parser into a scene_error
// naming the key and the line.
template <typename F>
auto with_key(const KeyRef& ref, F&& parse) {
  try {
    return parse();
  } catch (const usage_error& e) {
    fail_key(ref, e.what());
  }
}

std::string dir_of(const std::string& path) {
  auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

void parse_build_key(const std::string& key, const toml::node& v, const KeyRef& ref,
                     ModelOptions& b) {
  {
    if (key == "grid") {
      if (v.is_string() && get_string(v, ref) == "auto") {
        b.grid_nx = b.grid_ny = 0;
        return;
      }
      const toml::array* a = v.as_array();
      if (!a || a->size() != 2) fail_key(ref, "expected \"auto\" or [nx, ny]");
      b.grid_nx = get_count(*a->get(0), ref, 1, 65536);
      b.grid_ny = get_count(*a->get(1), ref, 1, 65536);
    } else if (key == "target_per_cell") {
      b.target_per_cell = get_count(v, ref, 1, 1 << 20);
    } else if (key == "max_cells") {
      b.max_cells = get_count(v, ref, 1, 1LL << 31);
    } else if (key == "leaf_capacity") {
      b.qt_leaf_capacity = get_count(v, ref, 1, 1 << 16);
    } else if (key == "max_depth") {
      b.qt_max_depth = get_count(v, ref, 0, 24);
    } else if (key == "miter_limit_deg") {
      b.miter_limit_deg = get_non_negative(v, ref);
      if (b.miter_limit_deg > 180) fail_key(ref, "expected an angle in [0, 180] degrees");
    } else if (key == "lmax") {
      b.lmax = get_non_negative(v, ref);
    } else if (key == "terrain_tolerance") {
      b.terrain_tolerance = get_non_negative(v, ref);
    } else if (key == "z_scale") {
      b.z_scale = get_number(v, ref);
    } else if (key == "nodata_fill") {
      b.nodata_fill = get_number(v, ref);
    } else if (key == "threads") {
      b.threads = get_count(v, ref, 0, 1024);
    } else {
      fail_unknown(ref, key, kBuildKeys);
    }
  }
}

void parse_build_table(const toml::table& t, const std::string& file, ModelOptions& b,
                       Problems& problems) {
  for (auto&& entry : t) {
    const std::string key(entry.first.str());
    const toml::node& v = entry.second;
    const KeyRef ref{file, "build." + key, line_of(v)};
    problems.run(ref.line, [&] { parse_build_key(key, v, ref, b); });
  }
}

// `dem = "a.tif"`, or `dem = ["a.hgt", "b.hgt", ...]` for a mosaic: each a
// path relative to the scene file's folder, the first in `dem`.
void parse_dem(const toml::node& v, const KeyRef& ref, const std::string& base, SceneSpec& scene) {
  scene.dem_more.clear();
  const toml::array* a = v.as_array();
  if (!a) {
    if (!v.is_string())
      fail_key(ref, "expected a string or an array of strings, got " + type_name(v));
    scene.dem = resolve_scene_path(get_string(v, ref), base);
    return;
  }
  if (a->empty()) fail_key(ref, "expected at least one DEM path, got an empty array");
  for (size_t i = 0; i < a->size(); ++i) {
    const toml::node& x = *a->get(i);
    const KeyRef xref{ref.file, ref.key + "[" + std::to_string(i) + "]", line_of(x)};
    const std::string path = resolve_scene_path(get_string(x, xref), base);
    if (path.empty()) fail_key(xref, "expected a DEM path, got an empty string");
    if (i == 0)
      scene.dem = path;
    else
      scene.dem_more.push_back(path);
  }
}

// `dash = [on, off, ...]`: an even count >= 2 of finite lengths > 0.
std::vector<double> parse_dash(const toml::node& v, const KeyRef& ref) {
  const toml::array* a = v.as_array();
  if (!a) fail_key(ref, "expected an array [on, off, ...] of lengths > 0, got " + type_name(v));
  std::vector<double> dash;
  std::string text = "[";
  for (size_t i = 0; i < a->size(); ++i) {
    const toml::node& x = *a->get(i);
    KeyRef xref{ref.file, ref.key + "[" + std::to_string(i) + "]", line_of(x)};
    dash.push_back(get_number(x, xref));
    if (!(dash.back() > 0) || !std::isfinite(dash.back()))
      fail_key(xref, "expected a dash length > 0, got " + std::to_string(dash.back()));
    text += (i ? ", " : "") + std::to_string(dash.back());
  }
  const std::string problem = dash_problem(dash);
  if (!problem.empty()) fail_key(ref, problem + ", got " + text + "]");
  return dash;
}

// One key of a [[layer]] table into `layer`; `width_set` when it is width.
void parse_layer_key(const std::string& key, const toml::node& v, const KeyRef& ref,
                     const std::string& file, const std::string& base_dir, LayerSpec& layer,
                     bool& width_set) {
  {
    if (key == "name") {
      layer.name = get_string(v, ref);
    } else if (key == "source") {
      layer.source = resolve_scene_path(get_string(v, ref), base_dir);
    } else if (key == "layer") {
      layer.layer = get_string(v, ref);
    } else if (key == "where") {
      layer.where = get_string(v, ref);
    } else if (key == "sql") {
      layer.sql = get_string(v, ref);
    } else if (key == "kind") {
      layer.kind = with_key(ref, [&] { return parse_kind(get_string(v, ref)); });
    } else if (key == "dynamic") {
      layer.dynamic = get_bool(v, ref);
    } else if (key == "lod") {
      layer.lod = get_bool(v, ref);
    } else if (key == "color") {
      layer.style.color.rgba = with_key(ref, [&] { return parse_color(get_string(v, ref)); });
    } else if (key == "color_attribute") {
      layer.style.color.attribute = get_string(v, ref);
    } else if (key == "color_ramp") {
      const toml::array* a = v.as_array();
      if (!a || a->empty()) fail_key(ref, "expected an array of [value, \"#rrggbb\"] pairs");
      for (size_t i = 0; i < a->size(); ++i) {
        const toml::array* stop = a->get(i)->as_array();
        KeyRef sref{file, ref.key + "[" + std::to_string(i) + "]", line_of(*a->get(i))};
        if (!stop || stop->size() != 2) fail_key(sref, "expected [value, \"#rrggbb\"]");
        ColorStop cs;
        cs.value = get_number(*stop->get(0), sref);
        cs.rgba = with_key(sref, [&] { return parse_color(get_string(*stop->get(1), sref)); });
        if (!layer.style.color.ramp.empty() && cs.value <= layer.style.color.ramp.back().value)
          fail_key(sref, "ramp values must increase");
        layer.style.color.ramp.push_back(cs);
      }
    } else if (key == "casing_width") {
      layer.casing_width = get_number(v, ref);
      if (!(layer.casing_width > 0) || !std::isfinite(layer.casing_width))
        fail_key(ref, "expected a casing width > 0, got " + std::to_string(layer.casing_width));
    } else if (key == "casing_color") {
      layer.casing_rgba = with_key(ref, [&] { return parse_color(get_string(v, ref)); });
    } else if (key == "slope_widths") {
      layer.slope_widths = get_bool(v, ref);
    } else if (key == "light") {
      layer.light = get_bool(v, ref);
    } else if (key == "min_width_m") {
      layer.min_width_m = get_number(v, ref);
      if (!(layer.min_width_m > 0 && layer.min_width_m <= 1e5))
        fail_key(ref, "expected a minimum width in metres in (0, 100000], got " +
                          std::to_string(layer.min_width_m));
    } else if (key == "min_width_px") {
      layer.min_width_px = get_number(v, ref);
      if (!(layer.min_width_px > 0 && layer.min_width_px <= 100))
        fail_key(ref, "expected a minimum width in pixels in (0, 100], got " +
                          std::to_string(layer.min_width_px));
    } else if (key == "dash") {
      layer.dash = parse_dash(v, ref);
    } else if (key == "width") {
      layer.style.width = get_number(v, ref);
      if (!(layer.style.width > 0) || !std::isfinite(layer.style.width))
        fail_key(ref, "expected a width > 0, got " + std::to_string(layer.style.width));
      width_set = true;
    } else if (key == "corner") {
      layer.style.corner = with_key(ref, [&] { return parse_corner(get_string(v, ref)); });
    } else if (key == "outline_mode") {
      layer.style.outline = with_key(ref, [&] { return parse_outline_mode(get_string(v, ref)); });
    } else if (key == "order_attribute") {
      layer.style.order_attribute = get_string(v, ref);
    } else if (key == "shared_edges") {
      const std::string t = get_string(v, ref);
      if (t != "all" && t != "once")
        fail_key(ref, "expected \"all\" or \"once\", got \"" + t + "\"");
      layer.shared_edges_once = t == "once";
    } else {
      fail_unknown(ref, key, kLayerKeys);
    }
  }
}

// The keys of a layer that do not go together, each a problem.
void check_layer(const LayerSpec& layer, const KeyRef& here, Problems& problems) {
  if (layer.source.empty())
    problems.add(here, "no source (set layer.source or a top-level source)");
  if (!layer.sql.empty() && (!layer.where.empty() || !layer.layer.empty()))
    problems.add(here, "sql replaces layer and where; give either sql or layer/where");
  if (layer.dynamic && layer.kind == DecalKind::polygon)
    problems.add(here, "dynamic = true needs kind = \"line\" or \"outline\"");
  if (!layer.style.color.attribute.empty() && layer.style.color.ramp.empty())
    problems.add(here, "color_attribute needs a color_ramp");
  if (layer.style.outline != decal::OutlineMode::normal &&
      layer.style.corner != decal::CornerStyle::miter)
    problems.add(
        here,
        "outline_mode inset/offset needs corner = \"miter\" (the kept half is cut at the miter "
        "corners)");
  if (layer.casing_rgba && layer.casing_width == 0)
    problems.add(here, "casing_color needs a casing_width");
  // A static line's half width in a package is below kMaxHalfWidthMetres
  // (formats/SPEC.md "Index constraints"), its casing's too.
  if (!layer.dynamic &&
      !(layer.style.width + 2 * layer.casing_width < 2.0 * double(decal::kMaxHalfWidthMetres))) {
    char v[96];
    std::snprintf(v, sizeof v,
                  layer.casing_width > 0 ? "width %g with casing_width %g" : "width %g",
                  layer.style.width, layer.casing_width);
    problems.add(here,
                 std::string(v) + " m is too wide: a static line must be narrower than 2e7 m");
  }
  if (layer.casing_width > 0 &&
      (layer.kind == DecalKind::polygon || layer.style.outline != decal::OutlineMode::normal))
    problems.add(here,
                 "casing_width needs kind = \"line\" or \"outline\" with outline_mode \"normal\"");
  if (layer.slope_widths && (layer.kind == DecalKind::polygon || layer.dynamic))
    problems.add(
        here,
        "slope_widths needs a static line layer (kind = \"line\" or \"outline\", not dynamic: "
        "dynamic widths are pixels, polygons have no width)");
  if (layer.min_width_px > 0 && (layer.kind == DecalKind::polygon || layer.dynamic))
    problems.add(here,
                 "min_width_px needs a static line layer (kind = \"line\", \"outline\" or "
                 "\"point\", not dynamic: dynamic widths are pixels already, polygons have no "
                 "width)");
  if (layer.min_width_m > 0 && (layer.kind == DecalKind::polygon || !layer.dynamic))
    problems.add(here,
                 "min_width_m needs a dynamic line layer (dynamic = true; static widths are "
                 "metres already, polygons have no width)");
  if (!layer.light && layer.dynamic)
    problems.add(here, "light = false is for static layers: dynamic lines are drawn unlit already");
  // Points are lines of two vertices kPointStep apart, drawn as round dots
  // of the layer's width (formats/SPEC.md "Points").
  if (layer.kind == DecalKind::point) {
    if (layer.style.corner != decal::CornerStyle::round ||
        layer.style.outline != decal::OutlineMode::normal)
      problems.add(here,
                   "kind = \"point\" draws round dots: corner \"round\" and outline_mode "
                   "\"normal\" only");
    if (!layer.dash.empty() || layer.lod || layer.slope_widths)
      problems.add(here, "kind = \"point\" takes no dash, lod or slope_widths (a dot is one disc)");
  }
  if (layer.shared_edges_once &&
      (layer.kind != DecalKind::outline || layer.style.outline != decal::OutlineMode::normal))
    problems.add(here,
                 "shared_edges = \"once\" needs kind = \"outline\" with outline_mode \"normal\" "
                 "(a ring that loses edges is drawn as open lines, which have no inside)");
  if (!layer.dash.empty() && layer.kind == DecalKind::polygon)
    problems.add(here, "dash needs kind = \"line\" or \"outline\"");
  // The dynamic dash scan measures the kept vertex chains, which the LOD
  // segments replace for the lines of a lod layer (formats/SPEC.md "Dashed
  // lines").
  if (!layer.dash.empty() && layer.lod)
    problems.add(here,
                 "dash and lod = true cannot be combined yet: the LOD segments replace the "
                 "vertex chains the dash is measured along");
}

LayerSpec parse_layer(const toml::table& t, const std::string& file, size_t index,
                      const std::string& default_source, const std::string& base_dir,
                      Problems& problems) {
  LayerSpec layer;
  layer.scene_line = static_cast<int>(t.source().begin.line);
  layer.source = default_source;
  const std::string prefix = "layer[" + std::to_string(index) + "].";
  bool width_set = false;
  bool keys_ok = true;
  for (auto&& entry : t) {
    // Not a structured binding: lambdas below capture the value, which
    // clang (and so clang-tidy) accepts only for a plain variable.
    const std::string key(entry.first.str());
    const toml::node& v = entry.second;
    const KeyRef ref{file, prefix + key, line_of(v)};
    keys_ok = problems.run(ref.line, [&] {
      parse_layer_key(key, v, ref, file, base_dir, layer, width_set);
    }) && keys_ok;
  }
  // Which keys go together is judged on keys that parsed (a kind that did
  // not would make every kind rule a false problem).
  if (keys_ok)
    check_layer(layer, {file, prefix.substr(0, prefix.size() - 1), layer.scene_line}, problems);
  if (layer.dynamic && !width_set) layer.style.width = 3.0;  // pixels
  if (layer.name.empty())
    layer.name = layer.layer.empty() ? "layer" + std::to_string(index) : layer.layer;
  return layer;
}

}  // namespace

uint32_t parse_color(const std::string& text) {
  auto hex = [&](size_t i) -> uint32_t {
    auto digit = [&](char c) -> uint32_t {
      if (c >= '0' && c <= '9') return c - '0';
      if (c >= 'a' && c <= 'f') return c - 'a' + 10;
      if (c >= 'A' && c <= 'F') return c - 'A' + 10;
      prep::fail<usage_error>(kNoStage,
                              "bad colour \"" + text + "\": expected #rrggbb or #rrggbbaa");
    };
    return digit(text[i]) * 16 + digit(text[i + 1]);
  };
  if (text.size() != 7 && text.size() != 9) {
    prep::fail<usage_error>(kNoStage, "bad colour \"" + text + "\": expected #rrggbb or #rrggbbaa");
  }
  if (text[0] != '#')
    prep::fail<usage_error>(kNoStage, "bad colour \"" + text + "\": expected #rrggbb or #rrggbbaa");
  uint32_t r = hex(1), g = hex(3), b = hex(5), a = text.size() == 9 ? hex(7) : 255u;
  return r | (g << 8) | (b << 16) | (a << 24);
}

// The casing layer of `layer` (LayerSpec::casing_width): the same features,
// casing_width wider on each side, in the casing colour (default: the layer
// colour at 60% brightness), drawn just below the layer.
LayerSpec casing_layer(const LayerSpec& layer) {
  LayerSpec c = layer;
  c.name = layer.name + ".casing";
  c.style.width = layer.style.width + 2 * layer.casing_width;
  uint32_t rgba = layer.style.color.rgba;
  if (layer.casing_rgba) {
    rgba = *layer.casing_rgba;
  } else {
    uint32_t darker = rgba & 0xff000000u;
    for (int ch = 0; ch < 3; ++ch)
      darker |= uint32_t(std::lround(0.6 * double((rgba >> (8 * ch)) & 0xffu))) << (8 * ch);
    rgba = darker;
  }
  c.style.color = LayerColor{rgba, {}, {}};
  c.casing_width = 0;
  c.casing_rgba.reset();
  c.casing_of = layer.name;
  c.dash.clear();  // the casing stays solid under a dashed line
  // At its minimum width the line keeps a pixel of casing on each side.
  if (layer.min_width_px > 0 && !layer.dynamic) c.min_width_px = layer.min_width_px + 2;
  // A dynamic casing keeps its share of the width at the minimum too.
  if (layer.min_width_m > 0 && layer.dynamic)
    c.min_width_m = layer.min_width_m * c.style.width / layer.style.width;
  return c;
}

std::optional<std::vector<double>> parse_number_list(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    size_t used = 0;
    try {
      v.push_back(std::stod(item, &used));
    } catch (const std::exception&) {
      return std::nullopt;
    }
    // NaN or infinity is no coordinate and no length.
    if (used != item.size() || !std::isfinite(v.back())) return std::nullopt;
  }
  return v;
}

std::string dash_problem(const std::vector<double>& dash) {
  for (double d : dash)
    if (!(d > 0) || !std::isfinite(d)) return "expected dash lengths > 0";
  if (dash.size() < 2 || dash.size() % 2 != 0)
    return "expected an even count >= 2 of lengths [on, off, ...] (" + std::to_string(dash.size()) +
           " values)";
  return {};
}

std::vector<ColorStop> parse_color_stops(const std::string& text) {
  auto bad = [](const std::string& why) { prep::fail<usage_error>(kNoStage, why); };
  std::vector<ColorStop> stops;
  std::stringstream ss(text);
  std::string stop;
  while (std::getline(ss, stop, ',')) {
    const size_t colon = stop.find(':');
    if (colon == std::string::npos) bad("stop '" + stop + "' has no ':'");
    ColorStop cs{};
    try {
      size_t used = 0;
      cs.value = std::stod(stop.substr(0, colon), &used);
      if (used != colon || !std::isfinite(cs.value)) throw std::invalid_argument(stop);
    } catch (const std::exception&) {
      bad("stop '" + stop + "' does not start with a finite number");
    }
    cs.rgba = parse_color(stop.substr(colon + 1));
    if (!stops.empty() && !(cs.value > stops.back().value)) bad("stop values must increase");
    stops.push_back(cs);
  }
  if (stops.empty()) bad("no stops");
  return stops;
}

decal::CornerStyle parse_corner(const std::string& t) {
  if (t == "round") return decal::CornerStyle::round;
  if (t == "miter") return decal::CornerStyle::miter;
  if (t == "bevel") return decal::CornerStyle::bevel;
  prep::fail<usage_error>(kNoStage, "expected round|miter|bevel, got \"" + t + "\"");
}

RepairMethod parse_repair_method(const std::string& t) {
  if (t == "linework") return RepairMethod::linework;
  if (t == "structure") return RepairMethod::structure;
  prep::fail<usage_error>(kNoStage, "expected linework|structure, got \"" + t + "\"");
}

decal::OutlineMode parse_outline_mode(const std::string& t) {
  if (t == "normal") return decal::OutlineMode::normal;
  if (t == "inset") return decal::OutlineMode::inset;
  if (t == "offset") return decal::OutlineMode::offset;
  prep::fail<usage_error>(kNoStage, "expected normal|inset|offset, got \"" + t + "\"");
}

DecalKind parse_kind(const std::string& t) {
  if (t == "polygon") return DecalKind::polygon;
  if (t == "line") return DecalKind::line;
  if (t == "outline") return DecalKind::outline;
  if (t == "point") return DecalKind::point;
  prep::fail<usage_error>(kNoStage, "expected polygon|line|outline|point, got \"" + t + "\"");
}

std::string resolve_scene_path(const std::string& path, const std::string& base_dir) {
  if (path.empty() || base_dir.empty() || base_dir == ".") return path;
  if (path[0] == '/') {
    // Archive handlers whose inner path is a local file: resolve that part.
    for (std::string_view prefix : {"/vsizip/", "/vsigzip/", "/vsitar/", "/vsi7z/"}) {
      if (path.rfind(prefix, 0) == 0) {
        std::string rest = path.substr(prefix.size());
        if (!rest.empty() && rest[0] != '/' && rest[0] != '{' && rest.rfind("/vsi", 0) != 0)
          return std::string(prefix) + base_dir + "/" + rest;
        return path;
      }
    }
    return path;
  }
  if (path.find("://") != std::string::npos) return path;
  // A bare CRS-like or driver-prefixed string (e.g. "PG:...") is not a path.
  auto colon = path.find(':');
  if (colon != std::string::npos && colon > 1 && path.find('/') > colon) return path;
  return base_dir + "/" + path;
}

namespace {

// One key of [tiling].
void parse_tiling_key(const std::string& key, const toml::node& v, const KeyRef& ref,
                      BuildSpec& scene) {
  if (key == "levels") {
    // Overview levels (formats/SPEC.md "Overview levels"): N or "auto".
    if (v.is_string() && get_string(v, ref) == "auto") {
      scene.levels = kLevelsAuto;
    } else if (v.is_integer()) {
      scene.levels = static_cast<int>(get_count(v, ref, 0, kMaxLevels));
    } else {
      fail_key(ref, "expected a number of levels (0 to 16) or \"auto\"");
    }
    return;
  }
  if (key != "tile_size") fail_unknown(ref, key, kTilingKeys);
  scene.tile_size = get_non_negative(v, ref);
  if (scene.tile_size < kMinTileSize || scene.tile_size > kMaxTileSize)
    fail_key(ref, "expected a tile size in [1, 4000000] metres");
}

// One top-level key of a scene file into `scene` ([build] and [tiling]
// key by key, their problems recorded); `layers` and `layers_line` from
// the [[layer]] array.
void parse_root_key(const std::string& key, const toml::node& v, const KeyRef& ref,
                    const std::string& base, Problems& problems, BuildSpec& scene,
                    const toml::array*& layers, int& layers_line) {
  const std::string& path = ref.file;
  if (key == "source") {
    return;  // read first: layers may come before it in the table order
  } else if (key == "crs") {
    scene.crs = get_string(v, ref);
  } else if (key == "assume_crs") {
    scene.assume_crs = get_string(v, ref);
  } else if (key == "extent_crs") {
    scene.extent_crs = get_string(v, ref);
  } else if (key == "extent") {
    const toml::array* a = v.as_array();
    if (!a || a->size() != 4) fail_key(ref, "expected [xmin, ymin, xmax, ymax]");
    Extent e{get_number(*a->get(0), ref), get_number(*a->get(1), ref), get_number(*a->get(2), ref),
             get_number(*a->get(3), ref)};
    if (e.empty()) fail_key(ref, "empty extent: need xmax > xmin and ymax > ymin");
    scene.extent = e;
  } else if (key == "resolution") {
    scene.resolution = get_non_negative(v, ref);
  } else if (key == "repair") {
    scene.repair = with_key(ref, [&] { return parse_repair_method(get_string(v, ref)); });
  } else if (key == "dem") {
    parse_dem(v, ref, base, scene);
  } else if (key == "skip_failures") {
    scene.skip_failures = get_bool(v, ref);
  } else if (key == "allow_empty") {
    scene.allow_empty = get_bool(v, ref);
  } else if (key == "build") {
    const toml::table* t = v.as_table();
    if (!t) fail_key(ref, "expected a table [build]");
    parse_build_table(*t, path, scene.model, problems);
  } else if (key == "tiling") {
    const toml::table* t = v.as_table();
    if (!t) fail_key(ref, "expected a table [tiling]");
    for (auto&& entry : *t) {
      const std::string tk(entry.first.str());
      const toml::node& tv = entry.second;
      const KeyRef tref{path, "tiling." + tk, line_of(tv)};
      problems.run(tref.line, [&] { parse_tiling_key(tk, tv, tref, scene); });
    }
  } else if (key == "layer") {
    layers = v.as_array();
    layers_line = ref.line;
    if (!layers) fail_key(ref, "expected an array of tables [[layer]]");
  } else {
    fail_unknown(ref, key, kRootKeys);
  }
}

// Two layers (casing layers included) with one name: the first such pair.
void check_layer_names(const BuildSpec& scene, const std::string& path) {
  // The [[layer]] index of scene.layers[i] (a casing layer: its layer's).
  auto file_index = [&](size_t i) {
    size_t n = 0;
    for (size_t k = 0; k < i; ++k) n += scene.layers[k].casing_of.empty();
    return n;
  };
  for (size_t i = 0; i < scene.layers.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (scene.layers[i].name == scene.layers[j].name) {
        const bool casing =
            !scene.layers[i].casing_of.empty() || !scene.layers[j].casing_of.empty();
        fail_key(
            {path, "layer[" + std::to_string(file_index(i)) + "].name", scene.layers[i].scene_line},
            "duplicate layer name \"" + scene.layers[i].name + "\" (also layer[" +
                std::to_string(file_index(j)) + "]" +
                (casing ? ", a casing layer takes its layer's name + \".casing\"" : "") +
                "); set name = \"...\"");
      }
    }
  }
}

// One problem: its own message, as it always was. More: a count, then each
// on its own line, in line order (a line's problems in the order found).
void fail_problems(Problems& problems, const std::string& path) {
  if (problems.list.empty()) return;
  if (problems.list.size() == 1) prep::fail<scene_error>(kNoStage, problems.list[0].second);
  std::stable_sort(problems.list.begin(), problems.list.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::string all = path + ": " + std::to_string(problems.list.size()) + " problems:";
  for (const auto& [line, message] : problems.list) all += "\n  " + message;
  prep::fail<scene_error>(kNoStage, all);
}

}  // namespace

BuildSpec parse_scene(const std::string& text, const std::string& path) {
  toml::table root;
  try {
    root = toml::parse(text, std::string_view(path));
  } catch (const toml::parse_error& e) {
    prep::fail<scene_error>(kNoStage, path + ":" + std::to_string(e.source().begin.line) + ": " +
                                          std::string(e.description()));
  }
  BuildSpec scene;
  scene.scene_path = path;
  const std::string base = dir_of(path);
  Problems problems;
  std::string default_source;
  if (const toml::node* s = root.get("source")) {
    problems.run(line_of(*s), [&] {
      default_source = resolve_scene_path(get_string(*s, {path, "source", line_of(*s)}), base);
    });
  }
  const toml::array* layers = nullptr;
  int layers_line = 1;
  for (auto&& entry : root) {
    const std::string key(entry.first.str());
    const toml::node& v = entry.second;
    const KeyRef ref{path, key, line_of(v)};
    problems.run(ref.line,
                 [&] { parse_root_key(key, v, ref, base, problems, scene, layers, layers_line); });
  }
  if (!layers || layers->empty()) {
    problems.add({path, "layer", layers_line}, "the scene has no [[layer]] table");
    layers = nullptr;
  }
  for (size_t i = 0; layers && i < layers->size(); ++i) {
    const toml::table* t = layers->get(i)->as_table();
    if (!t) {
      problems.add({path, "layer[" + std::to_string(i) + "]", line_of(*layers->get(i))},
                   "expected a table");
      continue;
    }
    LayerSpec layer = parse_layer(*t, path, i, default_source, base, problems);
    if (layer.casing_width > 0) scene.layers.push_back(casing_layer(layer));
    scene.layers.push_back(std::move(layer));
  }
  if (problems.list.empty()) check_layer_names(scene, path);
  fail_problems(problems, path);
  return scene;
}

BuildSpec load_scene_file(const std::string& path) {
  check_input_file(path, "scene file");
  std::ifstream in(path, std::ios::binary);
  if (!in) prep::fail<scene_error>(kNoStage, path + ": cannot open scene file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_scene(text.str(), path);
}

}  // namespace prep
