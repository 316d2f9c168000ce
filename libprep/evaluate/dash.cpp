// libprep/evaluate/dash.cpp — dashed lines (prep/evaluate.hpp).
#include "prep/evaluate.hpp"

#include <bit>
#include <cmath>
#include <limits>
#include <string>

#include <nlohmann/json.hpp>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep {

bool DashTable::any() const {
  for (const auto& l : layers)
    if (!l.empty()) return true;
  return false;
}

std::span<const double> DashTable::of(uint32_t layer) const {
  if (layer >= layers.size()) return {};
  return layers[layer];
}

std::vector<double> line_dash_start(std::string_view metadata_json, size_t lines) {
  std::vector<double> out;
  const auto meta = nlohmann::json::parse(metadata_json, nullptr, false);
  if (!meta.is_object() || !meta.contains("line_dash_start")) return out;
  const auto& a = meta["line_dash_start"];
  if (!a.is_array() || a.size() != lines)
    fail<format_error>(kEvaluateStage, "package metadata: line_dash_start is not an array of " +
                                           std::to_string(lines) + " numbers (one per line)");
  for (const auto& x : a) {
    if (!x.is_number() || !std::isfinite(x.get<double>()) || x.get<double>() < 0)
      fail<format_error>(kEvaluateStage,
                         "package metadata: line_dash_start holds " + x.dump() + ", not a length");
    out.push_back(x.get<double>());
  }
  return out;
}

DashTable dash_table(std::string_view metadata_json) {
  DashTable t;
  const auto meta = nlohmann::json::parse(metadata_json, nullptr, false);
  if (!meta.is_object() || !meta.contains("layers") || !meta["layers"].is_array()) return t;
  const auto& layers = meta["layers"];
  t.layers.resize(layers.size());
  for (size_t i = 0; i < layers.size(); ++i) {
    if (!layers[i].is_object() || !layers[i].contains("dash")) continue;
    const auto& d = layers[i]["dash"];
    const std::string where = "package metadata: layers[" + std::to_string(i) + "].dash ";
    if (!d.is_array() || d.size() < 2 || d.size() % 2 != 0)
      fail<format_error>(kEvaluateStage,
                         where + d.dump() + " is not an even count >= 2 of lengths");
    for (const auto& x : d) {
      if (!x.is_number() || !std::isfinite(x.get<double>()) || !(x.get<double>() > 0))
        fail<format_error>(kEvaluateStage, where + d.dump() + " has a length that is not > 0");
      t.layers[i].push_back(x.get<double>());
    }
  }
  return t;
}

std::vector<double> line_vertex_distances(std::span<const ivec2> line_vertices,
                                          std::span<const uint32_t> line_vertex_line,
                                          std::span<const double> line_start) {
  std::vector<double> dist(line_vertices.size(), 0.0);
  for (size_t k = 0; k < line_vertices.size(); ++k) {
    if (k == 0 || line_vertex_line[k] != line_vertex_line[k - 1]) {  // a line's first vertex
      const uint32_t l = line_vertex_line[k];
      dist[k] = l < line_start.size() ? line_start[l] : 0.0;
      continue;
    }
    const double dx = double(line_vertices[k][0] - line_vertices[k - 1][0]) * decal::kQuantumMetres;
    const double dy = double(line_vertices[k][1] - line_vertices[k - 1][1]) * decal::kQuantumMetres;
    dist[k] = dist[k - 1] + std::hypot(dx, dy);
  }
  return dist;
}

namespace {

// r = s mod period in [0, period); the interval of the pattern holding it:
// its start a and whether it is an "on" one.
struct DashPlace {
  double r, a, len;
  bool on;
};

DashPlace place(std::span<const double> pattern, double s) {
  double period = 0;
  for (double x : pattern) period += x;
  double r = s - period * std::floor(s / period);
  if (!(r >= 0 && r < period)) r = 0;  // s mod period rounded up to the period
  double a = 0;
  for (size_t i = 0; i < pattern.size(); ++i) {
    if (r < a + pattern[i] || i + 1 == pattern.size()) return {r, a, pattern[i], i % 2 == 0};
    a += pattern[i];
  }
  return {r, 0, pattern[0], true};
}

}  // namespace

bool dash_on(std::span<const double> pattern, double s) {
  if (pattern.empty()) return true;
  return place(pattern, s).on;
}

double dash_signed_distance(std::span<const double> pattern, double s) {
  if (pattern.empty()) return std::numeric_limits<double>::infinity();
  const DashPlace p = place(pattern, s);
  const double d = std::min(p.r - p.a, p.a + p.len - p.r);
  return p.on ? d : -d;
}

std::vector<uint32_t> dash_gpu_words(const DashTable& table) {
  const uint32_t n = uint32_t(table.layers.size());
  std::vector<uint32_t> w(1 + 3 * size_t(n), 0);
  w[0] = n;
  for (uint32_t l = 0; l < n; ++l) {
    const auto& p = table.layers[l];
    double period = 0;
    for (double x : p) period += x;
    w[1 + 3 * l] = uint32_t(w.size());
    w[2 + 3 * l] = uint32_t(p.size());
    w[3 + 3 * l] = std::bit_cast<uint32_t>(float(period));
    for (double x : p) w.push_back(std::bit_cast<uint32_t>(float(x)));
  }
  return w;
}

}  // namespace prep
