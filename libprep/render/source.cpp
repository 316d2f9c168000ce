// DecalSource: the renderer's view of a model in memory or an opened package.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "prep/error.hpp"
#include "prep/model.hpp"
#include "prep/render.hpp"
#include "prep/stage_error.hpp"

#include "decal/inspect.hpp"
#include "decal/reader.hpp"

namespace prep::render {

namespace {

template <class T>
void add_blob(DecalSource& s, decal::BlobId id, const std::vector<T>& v) {
  if (v.empty()) return;
  s.blobs.push_back({id, v.size(), v.data(), v.size() * sizeof(T)});
}

// Layer-table entry i's number `key`, in (0, hi], else format_error naming it.
double layer_number(const nlohmann::json& l, size_t i, const char* key, double hi) {
  const double v = l[key].get<double>();
  if (!(v > 0 && v <= hi))
    fail<format_error>(kRenderStage, "package metadata: layers[" + std::to_string(i) + "]." + key +
                                         " " + std::to_string(v) + " is not in (0, " +
                                         std::to_string(hi) + "]");
  return v;
}

}  // namespace

DecalSource source_of(const DecalModel& m) {
  DecalSource s;
  s.frame = m.frame;
  s.extent = m.extent;
  s.view = view_of(m);  // the evaluator's view: one list of static blobs
  for_each_model_array(m, [&](decal::BlobId id, const auto& v) { add_blob(s, id, v); });
  return s;
}

DecalSource source_of(const decal::Package& package) {
  DecalSource s;
  // view_of runs the package's structural check with the grid: nothing below
  // (and no GL call later) sees a package that fails it.
  s.view = view_of(package);  // grid from the metadata, checked against the blobs
  s.validated = true;
  for (const decal::BlobView& b : package.blobs())
    if (b.known())
      s.blobs.push_back(
          {static_cast<decal::BlobId>(b.id), b.count, b.bytes.data(), b.bytes.size()});
  // Frame and extent from the metadata chunk (formats/SPEC.md).
  auto meta = nlohmann::json::parse(package.metadata_json(), nullptr, false);
  if (meta.is_discarded() || !meta.is_object())
    fail<format_error>(kRenderStage, "package metadata is not a JSON object");
  try {
    auto pick = [&](std::initializer_list<const char*> keys) -> const nlohmann::json* {
      for (const char* k : keys)
        if (meta.contains(k)) return &meta[k];
      return nullptr;
    };
    if (const auto* crs = pick({"crs_wkt", "crs"})) {
      if (crs->is_string())
        s.frame.crs_wkt = crs->get<std::string>();
      else if (crs->is_object() && crs->contains("wkt"))
        s.frame.crs_wkt = (*crs)["wkt"].get<std::string>();
    }
    if (const auto* o = pick({"origin"})) {
      if (o->is_array() && o->size() >= 2) {
        s.frame.origin_x = (*o)[0].get<double>();
        s.frame.origin_y = (*o)[1].get<double>();
      } else if (o->is_object()) {
        s.frame.origin_x = o->value("x", 0.0);
        s.frame.origin_y = o->value("y", 0.0);
      }
    }
    if (const auto* e = pick({"extent"})) {
      if (e->is_array() && e->size() >= 4) {
        s.extent = {(*e)[0].get<double>(), (*e)[1].get<double>(), (*e)[2].get<double>(),
                    (*e)[3].get<double>()};
      } else if (e->is_object()) {
        s.extent = {e->value("xmin", 0.0), e->value("ymin", 0.0), e->value("xmax", 0.0),
                    e->value("ymax", 0.0)};
      }
    }
    // The miter limit the build used: the dynamic-line pass builds its
    // corners per frame and falls back to round below the same angle.
    if (const auto* bo = pick({"build_options"}); bo && bo->is_object()) {
      const auto it = bo->find("miter_limit_deg");
      if (it != bo->end() && it->is_number()) {
        const double deg = it->get<double>();
        if (!(deg > 0 && deg <= 180))
          fail<format_error>(kRenderStage, "package metadata: build_options.miter_limit_deg " +
                                               std::to_string(deg) + " is not in (0, 180]");
        s.miter_limit_deg = deg;
      }
    }
    // Minimum widths' pixel limit (formats/SPEC.md "Minimum widths").
    if (const auto* m = pick({"min_width_pixel_m"})) {
      const double v = m->get<double>();
      if (!(v > 0 && std::isfinite(v)))
        fail<format_error>(kRenderStage, "package metadata: min_width_pixel_m " +
                                             std::to_string(v) + " is not a length > 0");
      s.min_width_pixel_m = v;
    }
    // Layers whose static lines are measured along the terrain.
    // One flag per layer and a last 0 for line layers past the table.
    if (const auto* layers = pick({"layers"}); layers && layers->is_array()) {
      for (size_t i = 0; i < layers->size(); ++i) {
        const auto& l = (*layers)[i];
        if (l.is_object() && l.contains("slope_widths") && l["slope_widths"] == true) {
          s.slope_layers.resize(layers->size() + 1, 0);
          s.slope_layers[i] = 1;
        }
        if (l.is_object() && l.contains("light") && l["light"] == false) {
          s.unlit_layers.resize(layers->size() + 1, 0);
          s.unlit_layers[i] = 1;
        }
        if (l.is_object() && l.contains("min_width_px")) {
          const double n = layer_number(l, i, "min_width_px", 102);
          s.min_width_px.resize(layers->size() + 1, 0.0f);
          s.min_width_px[i] = float(n);
          // f N, over a miter's reach for a mitred layer (corner 1).
          const bool normal = l.value("outline_mode", 0u) == 0u;
          const bool miter = l.value("corner", 0u) == uint32_t(decal::CornerStyle::miter);
          const double limit = std::clamp(s.miter_limit_deg, 1.0, 180.0) * M_PI / 360.0;
          s.min_width_reach = std::max(s.min_width_reach,
                                       n * (normal ? 0.5 : 1.0) / (miter ? std::sin(limit) : 1.0));
        }
        if (l.is_object() && l.contains("min_width_m")) {
          const double m = layer_number(l, i, "min_width_m", 1e5);
          s.min_width_m.resize(layers->size() + 1, 0.0f);
          s.min_width_m[i] = float(m);
        }
      }
    }
  } catch (const nlohmann::json::exception& ex) {
    fail<format_error>(kRenderStage, std::string("package metadata: ") + ex.what());
  }
  if (s.extent.empty()) {
    // Fall back to the grid's extent.
    const GridParams& g = s.view.grid;
    s.extent = {g.origin_x * decal::kQuantumMetres, g.origin_y * decal::kQuantumMetres,
                (g.origin_x + g.cell_w * int64_t(g.nx)) * decal::kQuantumMetres,
                (g.origin_y + g.cell_h * int64_t(g.ny)) * decal::kQuantumMetres};
  }
  return s;
}

std::vector<uint8_t> slope_layers(const DecalSource& source, SlopeWidths mode) {
  if (mode == SlopeWidths::off) return {};
  if (mode == SlopeWidths::package) return source.slope_layers;
  return source.view.line_props.empty() ? std::vector<uint8_t>{} : std::vector<uint8_t>{1};
}

double min_width_reach(const DecalSource& source) {
  if (source.min_width_px.empty() || !(source.min_width_pixel_m > 0)) return 0.0;
  return 1.01 * source.min_width_reach;
}

TileList tile_list(std::span<const TileSource> tiles, const RenderOptions& options) {
  TileList list;
  for (const TileSource& t : tiles) {
    list.places.push_back({t.square, t.dx, t.dy});
    list.slope =
        list.slope || (options.draw_lines && !slope_layers(t.source, options.slope_widths).empty());
    list.unlit = list.unlit || !t.source.unlit_layers.empty();
    list.min_widths = list.min_widths || !t.source.min_width_px.empty();
  }
  list.open = [tiles](size_t k) { return OpenedTile{tiles[k], nullptr}; };
  return list;
}

std::vector<std::string> layer_strings(const std::string& metadata_json, const char* key) {
  std::vector<std::string> values;
  const auto meta = nlohmann::json::parse(metadata_json, nullptr, false);
  if (!meta.is_object() || !meta.contains("layers") || !meta["layers"].is_array()) return values;
  for (const auto& l : meta["layers"])
    values.push_back(l.is_object() && l.contains(key) && l[key].is_string()
                         ? l[key].get<std::string>()
                         : std::string());
  return values;
}

std::vector<std::string> layer_names(const std::string& metadata_json) {
  return layer_strings(metadata_json, "name");
}

namespace {

// Copies the props blob `id` of `s` into `held`, recolours each element
// `recolour` accepts, and points the blob (and `view`, when given) at the copy.
template <class Props, class Recolour>
void restyle_blob(DecalSource& s, decal::BlobId id, std::vector<Props>& held,
                  std::span<const Props>* view, Recolour recolour) {
  for (DecalSource::Blob& b : s.blobs) {
    if (b.id != id) continue;
    held.resize(b.bytes / sizeof(Props));
    std::memcpy(held.data(), b.data, held.size() * sizeof(Props));
    for (Props& p : held) recolour(p);
    b.data = held.data();
    if (view) *view = held;
    return;
  }
}

}  // namespace

void restyle(DecalSource& source, const LayerRamps& ramps, RestyledProps& held) {
  auto stops_of = [&](uint32_t layer) -> const std::vector<ColorStop>& {
    if (layer >= ramps.size())
      fail<format_error>(kRenderStage, "a feature names layer " + std::to_string(layer) +
                                           " of a layer table of " + std::to_string(ramps.size()));
    return ramps[layer];
  };
  auto recolour = [&](uint32_t& rgba, uint32_t layer, float value) {
    const std::vector<ColorStop>& stops = stops_of(layer);
    held.recoloured += !stops.empty();
    rgba = ramp_rgba(stops, value, rgba);
  };
  auto line = [&](decal::LineProps& p) { recolour(p.rgba, p.layer, p.value); };
  restyle_blob(source, decal::BlobId::line_props, held.line, &source.view.line_props, line);
  restyle_blob<decal::LineProps>(source, decal::BlobId::dyn_line_props, held.dyn, nullptr, line);
  restyle_blob(source, decal::BlobId::poly_props, held.poly, &source.view.poly_props,
               [&](decal::PolyProps& p) {
                 // interior polygons are drawn by their exterior
                 if (p.exterior < 0) recolour(p.rgba, p.layer, p.value);
               });
}

}  // namespace prep::render
