// Scene file parser (toml++). Every key is documented in samples/README.md;
// an unknown key is an error, so a typo never silently falls back to a
// default.
#include "prep/pipeline.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string_view>

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

[[noreturn]] void fail_key(const KeyRef& ref, const std::string& what) {
  prep::fail<scene_error>(kNoStage,
                          ref.file + ":" + std::to_string(ref.line) + ": " + ref.key + ": " + what);
}

int line_of(const toml::node& n) {
  return static_cast<int>(n.source().begin.line);
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

void parse_build_table(const toml::table& t, const std::string& file, ModelOptions& b) {
  for (auto&& [k, v] : t) {
    std::string key(k.str());
    KeyRef ref{file, "build." + key, line_of(v)};
    if (key == "grid") {
      if (v.is_string() && get_string(v, ref) == "auto") {
        b.grid_nx = b.grid_ny = 0;
        continue;
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
      fail_key(ref, "unknown key (see samples/README.md)");
    }
  }
}

// The casing layer of `layer` (LayerSpec::casing_width): the same features,
// casing_width wider on each side, in the casing colour (default: the layer
// colour at 60% brightness), drawn just below the layer.
LayerSpec casing_of(const LayerSpec& layer) {
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
  return c;
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
  if (dash.size() < 2 || dash.size() % 2 != 0)
    fail_key(ref, "expected an even count >= 2 of lengths [on, off, ...], got " + text + "] (" +
                      std::to_string(dash.size()) + " values)");
  return dash;
}

LayerSpec parse_layer(const toml::table& t, const std::string& file, size_t index,
                      const std::string& default_source, const std::string& base_dir) {
  LayerSpec layer;
  layer.scene_line = static_cast<int>(t.source().begin.line);
  layer.source = default_source;
  const std::string prefix = "layer[" + std::to_string(index) + "].";
  bool width_set = false;
  for (auto&& entry : t) {
    // Not a structured binding: lambdas below capture the value, which
    // clang (and so clang-tidy) accepts only for a plain variable.
    const std::string key(entry.first.str());
    const toml::node& v = entry.second;
    KeyRef ref{file, prefix + key, line_of(v)};
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
    } else {
      fail_key(ref, "unknown key (see samples/README.md)");
    }
  }
  KeyRef here{file, prefix.substr(0, prefix.size() - 1), layer.scene_line};
  if (layer.source.empty()) fail_key(here, "no source (set layer.source or a top-level source)");
  if (!layer.sql.empty() && (!layer.where.empty() || !layer.layer.empty()))
    fail_key(here, "sql replaces layer and where; give either sql or layer/where");
  if (layer.dynamic && layer.kind == DecalKind::polygon)
    fail_key(here, "dynamic = true needs kind = \"line\" or \"outline\"");
  if (!layer.style.color.attribute.empty() && layer.style.color.ramp.empty())
    fail_key(here, "color_attribute needs a color_ramp");
  if (layer.style.outline != decal::OutlineMode::normal &&
      layer.style.corner != decal::CornerStyle::miter)
    fail_key(
        here,
        "outline_mode inset/offset needs corner = \"miter\" (the kept half is cut at the miter "
        "corners)");
  if (layer.casing_rgba && layer.casing_width == 0)
    fail_key(here, "casing_color needs a casing_width");
  // A static line's half width in a package is below kMaxHalfWidthMetres
  // (formats/SPEC.md "Index constraints"), its casing's too.
  if (!layer.dynamic &&
      !(layer.style.width + 2 * layer.casing_width < 2.0 * double(decal::kMaxHalfWidthMetres))) {
    char v[96];
    std::snprintf(v, sizeof v,
                  layer.casing_width > 0 ? "width %g with casing_width %g" : "width %g",
                  layer.style.width, layer.casing_width);
    fail_key(here, std::string(v) + " m is too wide: a static line must be narrower than 2e7 m");
  }
  if (layer.casing_width > 0 &&
      (layer.kind == DecalKind::polygon || layer.style.outline != decal::OutlineMode::normal))
    fail_key(here,
             "casing_width needs kind = \"line\" or \"outline\" with outline_mode \"normal\"");
  if (layer.slope_widths && (layer.kind == DecalKind::polygon || layer.dynamic))
    fail_key(here,
             "slope_widths needs a static line layer (kind = \"line\" or \"outline\", not dynamic: "
             "dynamic widths are pixels, polygons have no width)");
  if (!layer.dash.empty() && layer.kind == DecalKind::polygon)
    fail_key(here, "dash needs kind = \"line\" or \"outline\"");
  // The dynamic dash scan measures the kept vertex chains, which the LOD
  // segments replace for the lines of a lod layer (formats/SPEC.md "Dashed
  // lines").
  if (!layer.dash.empty() && layer.lod)
    fail_key(here,
             "dash and lod = true cannot be combined yet: the LOD segments replace the "
             "vertex chains the dash is measured along");
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
  prep::fail<usage_error>(kNoStage, "expected polygon|line|outline, got \"" + t + "\"");
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
  std::string default_source;
  if (const toml::node* s = root.get("source")) {
    default_source = resolve_scene_path(get_string(*s, {path, "source", line_of(*s)}), base);
  }
  const toml::array* layers = nullptr;
  int layers_line = 1;
  for (auto&& [k, v] : root) {
    std::string key(k.str());
    KeyRef ref{path, key, line_of(v)};
    if (key == "source") {
      continue;  // handled above: layers may come before it in the table order
    } else if (key == "crs") {
      scene.crs = get_string(v, ref);
    } else if (key == "assume_crs") {
      scene.assume_crs = get_string(v, ref);
    } else if (key == "extent_crs") {
      scene.extent_crs = get_string(v, ref);
    } else if (key == "extent") {
      const toml::array* a = v.as_array();
      if (!a || a->size() != 4) fail_key(ref, "expected [xmin, ymin, xmax, ymax]");
      Extent e{get_number(*a->get(0), ref), get_number(*a->get(1), ref),
               get_number(*a->get(2), ref), get_number(*a->get(3), ref)};
      if (e.empty()) fail_key(ref, "empty extent: need xmax > xmin and ymax > ymin");
      scene.extent = e;
    } else if (key == "resolution") {
      scene.resolution = get_non_negative(v, ref);
    } else if (key == "repair") {
      try {
        scene.repair = parse_repair_method(get_string(v, ref));
      } catch (const usage_error& e) {
        fail_key(ref, e.what());
      }
    } else if (key == "dem") {
      scene.dem = resolve_scene_path(get_string(v, ref), base);
    } else if (key == "skip_failures") {
      scene.skip_failures = get_bool(v, ref);
    } else if (key == "allow_empty") {
      scene.allow_empty = get_bool(v, ref);
    } else if (key == "build") {
      const toml::table* t = v.as_table();
      if (!t) fail_key(ref, "expected a table [build]");
      parse_build_table(*t, path, scene.model);
    } else if (key == "tiling") {
      const toml::table* t = v.as_table();
      if (!t) fail_key(ref, "expected a table [tiling]");
      for (auto&& [tk, tv] : *t) {
        const KeyRef tref{path, "tiling." + std::string(tk.str()), line_of(tv)};
        if (tk.str() == "levels") {
          // Overview levels (formats/SPEC.md "Overview levels"): N or "auto".
          if (tv.is_string() && get_string(tv, tref) == "auto") {
            scene.levels = kLevelsAuto;
          } else if (tv.is_integer()) {
            scene.levels = static_cast<int>(get_count(tv, tref, 0, kMaxLevels));
          } else {
            fail_key(tref, "expected a number of levels (0 to 16) or \"auto\"");
          }
          continue;
        }
        if (tk.str() != "tile_size") fail_key(tref, "unknown key (see samples/README.md)");
        scene.tile_size = get_non_negative(tv, tref);
        if (scene.tile_size < kMinTileSize || scene.tile_size > kMaxTileSize)
          fail_key(tref, "expected a tile size in [1, 4000000] metres");
      }
    } else if (key == "layer") {
      layers = v.as_array();
      layers_line = ref.line;
      if (!layers) fail_key(ref, "expected an array of tables [[layer]]");
    } else {
      fail_key(ref, "unknown key (see samples/README.md)");
    }
  }
  if (!layers || layers->empty()) {
    prep::fail<scene_error>(kNoStage, path + ":" + std::to_string(layers_line) +
                                          ": layer: the scene has no [[layer]] table");
  }
  for (size_t i = 0; i < layers->size(); ++i) {
    const toml::table* t = layers->get(i)->as_table();
    if (!t)
      fail_key({path, "layer[" + std::to_string(i) + "]", line_of(*layers->get(i))},
               "expected a table");
    LayerSpec layer = parse_layer(*t, path, i, default_source, base);
    if (layer.casing_width > 0) scene.layers.push_back(casing_of(layer));
    scene.layers.push_back(std::move(layer));
  }
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
