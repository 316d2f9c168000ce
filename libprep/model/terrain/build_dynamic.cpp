// build_dynamic(): the dyn_* blobs (terrain-matched dynamic lines, thesis
// §4.2.2) and the lod_* blobs (LOCALIS) of a DecalModel.
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>

#include "lod/lod.hpp"
#include "prep/error.hpp"
#include "prep/model.hpp"
#include "prep/stage_error.hpp"
#include "terrain/terrain.hpp"

namespace prep {

namespace {

std::string fmt(double v, int digits = 3) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

// Empties what build_dynamic() fills (the dyn_* and lod_* blobs and the
// terrain figures).
void reset_dynamic(DecalModel& model) {
  model.dyn_vertices.clear();
  model.dyn_prev_next.clear();
  model.dyn_line_start.clear();
  model.dyn_line_props.clear();
  model.lod_points.clear();
  model.lod_segments.clear();
  model.lod_line_range.clear();
  model.terrain_min = model.terrain_max = 0;
  model.dyn_vertices_outside_dem = model.dyn_lines_outside_dem = 0;
}

// The scene's name of layer index `layer` (the index itself when there is
// no such layer).
std::string dynamic_layer_name(const SceneFeatures& scene, uint32_t layer) {
  return layer < scene.layers.size() ? scene.layers[layer].name : std::to_string(layer);
}

// The usable dynamic lines, in scene order; a line with too few points goes
// to the manifest as dropped. Notes each static layer that asks for LOD.
std::vector<SceneLine> usable_dynamic_lines(const SceneFeatures& scene, DecalModel& model) {
  std::vector<SceneLine> lines;
  lines.reserve(scene.dynamic_lines.size());
  for (const SceneLine& l : scene.dynamic_lines) {
    if (l.points.size() < 2 || (l.closed && l.points.size() < 3)) {
      model.manifest.entries.push_back(
          {dynamic_layer_name(scene, l.layer), l.fid, l.part, ManifestAction::dropped,
           stage_message(kBuildStage, "dynamic line has " + std::to_string(l.points.size()) +
                                          " points, too few to draw")});
      continue;
    }
    lines.push_back(l);
  }
  for (size_t i = 0; i < scene.layers.size(); ++i)
    if (scene.layers[i].lod && !scene.layers[i].dynamic)
      model.manifest.notes.push_back(stage_message(
          kLodStage,
          "layer '" + scene.layers[i].name +
              "' is static; LOD segments are built for dynamic lines only, its lines keep "
              "full detail"));
  return lines;
}

// The terrain the lines are matched to: the DEM (none without a path, or
// without lines to match) and the match options, lmax by default half the
// DEM cell near the data centre (thesis §4.2.2). Throws usage_error for
// invalid terrain options; notes what was chosen.
void prepare_terrain(const SceneFeatures& scene, const ModelOptions& options,
                     const std::string& dem_path, const std::vector<SceneLine>& lines,
                     std::vector<std::string>& notes, std::unique_ptr<DemSampler>& dem,
                     MatchOptions& match_options) {
  match_options.tolerance = options.terrain_tolerance;
  if (!(options.lmax >= 0) || !(options.terrain_tolerance >= 0) || !(options.z_scale > 0) ||
      !std::isfinite(options.z_scale))
    fail<usage_error>(kBuildStage, "invalid terrain option (lmax " + std::to_string(options.lmax) +
                                       ", terrain tolerance " +
                                       std::to_string(options.terrain_tolerance) + ", z-scale " +
                                       std::to_string(options.z_scale) + ")");
  if (dem_path.empty()) {
    notes.push_back(
        stage_message(kTerrainStage, "no DEM given; dynamic lines lie on flat terrain z = 0"));
    match_options.lmax = options.lmax > 0 ? options.lmax : std::numeric_limits<double>::infinity();
  } else if (lines.empty()) {
    notes.push_back(stage_message(
        kTerrainStage,
        "no dynamic lines; DEM " + dem_text(dem_path, options.dem_more) + " not read"));
  } else {
    DemSpec spec{dem_path, options.dem_assume_crs, options.z_scale, options.nodata_fill};
    spec.more_paths = options.dem_more;
    dem = std::make_unique<DemSampler>(spec, scene.frame);
    Extent b = no_points();
    for (const auto& l : lines) extend(b, l.points);
    const double cell = dem->cell_size_metres({0.5 * (b.xmin + b.xmax), 0.5 * (b.ymin + b.ymax)});
    match_options.lmax = options.lmax > 0 ? options.lmax : 0.5 * cell;
    notes.push_back(stage_message(kTerrainStage, dem->stats().description + "; DEM cell " +
                                                     fmt(cell) + " m near the data centre"));
  }
}

// The lines matched to the terrain (match_terrain) into the dyn_* vertex
// blobs and the terrain figures, with notes on the subdivision and the DEM.
void match_dynamic_lines(const std::vector<SceneLine>& lines, DemSampler* dem,
                         const MatchOptions& match_options, DecalModel& model) {
  auto& notes = model.manifest.notes;
  MatchedLines m = match_terrain(lines, dem, match_options);
  model.dyn_vertices = std::move(m.vertices);
  model.dyn_prev_next = std::move(m.prev_next);
  model.dyn_line_start = std::move(m.line_start);
  std::string mode = match_options.tolerance > 0 && dem
                         ? "adaptive, tolerance " + fmt(match_options.tolerance) + " m"
                         : "fixed lmax";
  notes.push_back(stage_message(
      kTerrainStage,
      "dynamic lines " + std::to_string(lines.size()) + ", vertices in " +
          std::to_string(m.vertices_in) + ", after subdivision to lmax " +
          (std::isinf(match_options.lmax) ? std::string("inf (none)") : fmt(match_options.lmax)) +
          " m " + std::to_string(m.vertices_fixed) + ", stored " + std::to_string(m.vertices_out) +
          " (" + mode + "); longest stored piece " + fmt(m.max_piece_length, 4) +
          " m; max deviation from the DEM surface " + fmt(m.max_deviation, 4) + " m"));
  if (m.tolerance_misses > 0)
    notes.push_back(stage_message(
        kTerrainStage, "" + std::to_string(m.tolerance_misses) +
                           " pieces reached 1 cm and still exceed the terrain tolerance"));
  if (!dem) return;
  const TerrainStats& t = m.terrain;
  model.terrain_min = t.min;
  model.terrain_max = t.max;
  model.dyn_vertices_outside_dem = t.samples_outside;
  model.dyn_lines_outside_dem = m.lines_outside;
  notes.push_back(stage_message(
      kTerrainStage,
      "DEM window " + std::to_string(t.window_cells) + " cells, " + std::to_string(t.nodata_cells) +
          " no-data cells filled (" + t.fill_policy + "); " +
          std::to_string(t.samples_touching_fill) + " of " + std::to_string(t.samples) +
          " vertex heights used a filled cell, " + std::to_string(t.samples_outside) +
          " lie outside the DEM (edge value); terrain " + fmt(t.min) + " .. " + fmt(t.max) + " m"));
}

// Line properties (dyn_line_props); drawing order (formats/SPEC.md "Drawing
// order"): a later scene layer on top of an earlier one; within a layer the
// importance attribute (order_value) when present, else length, larger on
// top (rank 0); ties by input order.
void dynamic_line_props(const SceneFeatures& scene, const std::vector<SceneLine>& lines,
                        DecalModel& model) {
  const auto nl = static_cast<uint32_t>(lines.size());
  std::vector<uint32_t> by_rank(nl);
  std::iota(by_rank.begin(), by_rank.end(), 0u);
  auto key = [&](const SceneLine& l) {
    return std::isfinite(l.order_value) ? l.order_value : l.length;
  };
  std::stable_sort(by_rank.begin(), by_rank.end(), [&](uint32_t a, uint32_t b) {
    if (lines[a].layer != lines[b].layer) return lines[a].layer > lines[b].layer;
    return key(lines[a]) > key(lines[b]);
  });
  model.dyn_line_props.resize(nl);
  for (uint32_t r = 0; r < nl; ++r) model.dyn_line_props[by_rank[r]].order = r;
  for (uint32_t i = 0; i < nl; ++i) {
    const SceneLine& l = lines[i];
    const LayerStyle* style =
        l.layer < scene.layers.size() ? &scene.layers[l.layer].style : nullptr;
    auto& p = model.dyn_line_props[i];
    const double width = l.width > 0 ? l.width : (style ? style->width : 2.0);
    p.half_width = static_cast<float>(0.5 * width);  // pixels
    p.rgba = style ? resolve_color(style->color, l.color_value) : 0xffffffffu;
    p.style = (style ? static_cast<uint32_t>(style->corner) & decal::kStyleCornerMask : 0u) |
              (style ? (static_cast<uint32_t>(style->outline) << decal::kStyleOutlineShift) &
                           decal::kStyleOutlineMask
                     : 0u) |
              (l.closed ? decal::kStyleClosedBit : 0u);
    p.value = static_cast<float>(l.color_value);
    p.layer = l.layer;
    p.feature = stored_feature_id(l.fid);
    p.clip_node = 0;  // dynamic lines are never clipped
  }
}

// The dynamic lines of LOD layers, quantised to 1 mm with repeated points
// dropped (and a closed ring's repeated first point); a line that collapses
// gets a manifest note instead.
std::vector<LodInputLine> lod_input_lines(const SceneFeatures& scene,
                                          const std::vector<SceneLine>& lines, DecalModel& model) {
  std::vector<LodInputLine> lod_lines;
  for (uint32_t i = 0; i < lines.size(); ++i) {
    const SceneLine& l = lines[i];
    if (l.layer >= scene.layers.size() || !scene.layers[l.layer].lod) continue;
    LodInputLine in;
    in.line = i;
    in.closed = l.closed;
    for (const auto& pt : l.points) {
      const ivec2 q = {static_cast<int32_t>(std::llround(pt.x / decal::kQuantumMetres)),
                       static_cast<int32_t>(std::llround(pt.y / decal::kQuantumMetres))};
      if (in.points.empty() || in.points.back() != q) in.points.push_back(q);
    }
    if (in.closed && in.points.size() > 1 && in.points.front() == in.points.back())
      in.points.pop_back();
    if (in.points.size() < (in.closed ? 3u : 2u)) {
      model.manifest.entries.push_back(
          {dynamic_layer_name(scene, l.layer), l.fid, l.part, ManifestAction::note,
           stage_message(kLodStage, "line collapses at 1 mm; no LOD segments")});
      continue;
    }
    lod_lines.push_back(std::move(in));
  }
  return lod_lines;
}

// The LOD segments of `lod_lines` (LOCALIS) into the lod_* blobs, with a
// note of their figures.
void store_lod(const std::vector<LodInputLine>& lod_lines, DecalModel& model) {
  LodSet lod = build_lod(lod_lines);
  model.lod_points = std::move(lod.points);
  model.lod_segments = std::move(lod.segments);
  model.lod_line_range = std::move(lod.line_range);
  const auto& s = lod.stats;
  model.manifest.notes.push_back(stage_message(
      kLodStage,
      "" + std::to_string(s.lines) + " lines, " + std::to_string(s.original_segments) +
          " original segments -> " + std::to_string(s.attributed_segments) +
          " attributed segments (x" +
          fmt(s.original_segments ? double(s.attributed_segments) / double(s.original_segments) : 0,
              2) +
          "); " + std::to_string(s.dependee_edges) + " dependees, " + std::to_string(s.cycles) +
          " cycles merged into proxies (" + std::to_string(s.points_in_cycles) + " points), " +
          std::to_string(s.always_points) + " points always drawn"));
}

}  // namespace

void build_dynamic(const SceneFeatures& scene, const ModelOptions& options,
                   const std::string& dem_path, DecalModel& model) {
  std::unique_ptr<tbb::global_control> threads;
  if (options.threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    options.threads);
  reset_dynamic(model);
  // Usable lines; anything else goes to the manifest with its reason.
  const std::vector<SceneLine> lines = usable_dynamic_lines(scene, model);
  std::unique_ptr<DemSampler> dem;
  MatchOptions match_options;
  prepare_terrain(scene, options, dem_path, lines, model.manifest.notes, dem, match_options);
  if (!lines.empty()) match_dynamic_lines(lines, dem.get(), match_options, model);
  dynamic_line_props(scene, lines, model);
  // LOD segments for the dynamic lines of LOD layers (LOCALIS).
  const std::vector<LodInputLine> lod_lines = lod_input_lines(scene, lines, model);
  if (!lod_lines.empty()) store_lod(lod_lines, model);
}

}  // namespace prep
