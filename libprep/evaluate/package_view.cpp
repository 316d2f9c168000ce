// libprep/evaluate/package_view.cpp — StaticView over a package read from
// disk: blobs from decal::Package, grid from the metadata chunk, checked by
// the package's structural check with that grid (the evaluator indexes
// without checks).
#include <nlohmann/json.hpp>

#include "compact_view.hpp"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/stage_error.hpp"

namespace prep {

GridParams grid_of_metadata(std::string_view metadata) {
  const auto meta = nlohmann::json::parse(metadata, nullptr, false);
  if (meta.is_discarded() || !meta.is_object())
    fail<format_error>(kEvaluateStage, "package metadata is not a JSON object");
  if (!meta.contains("grid"))
    fail<format_error>(kEvaluateStage, "package metadata has no \"grid\" key");
  GridParams g;
  try {
    const auto& j = meta.at("grid");
    g.origin_x = j.at("origin").at(0).get<int64_t>();
    g.origin_y = j.at("origin").at(1).get<int64_t>();
    g.cell_w = j.at("cell").at(0).get<int64_t>();
    g.cell_h = j.at("cell").at(1).get<int64_t>();
    g.nx = j.at("dims").at(0).get<uint32_t>();
    g.ny = j.at("dims").at(1).get<uint32_t>();
  } catch (const nlohmann::json::exception& e) {
    fail<format_error>(kEvaluateStage, std::string("package metadata \"grid\": ") + e.what());
  }
  if (g.cell_w <= 0 || g.cell_h <= 0)
    fail<format_error>(kEvaluateStage, "package metadata \"grid\": cell size " +
                                           std::to_string(g.cell_w) + "x" +
                                           std::to_string(g.cell_h) + " is not positive");
  return g;
}

StaticView view_of(const decal::Package& p) {
  using decal::BlobId;
  StaticView v;
  v.grid = grid_of_metadata(p.metadata_json());
  // The package's one structural check, with the grid: every index the
  // evaluator follows is in range and every BVH is a full tree per cell.
  const decal::Grid grid{v.grid.origin_x, v.grid.origin_y, v.grid.cell_w,
                         v.grid.cell_h,   v.grid.nx,       v.grid.ny};
  if (decal::Status st = decal::validate_indices(p, &grid); !st)
    fail<format_error>(kEvaluateStage, st.message);
#define PREP_FROM_PACKAGE(T, name) v.name = p.array<BlobId::name>();
  PREP_STATIC_VIEW_BLOBS(PREP_FROM_PACKAGE)
#undef PREP_FROM_PACKAGE
  if (p.minor() < 2) v.polygon_rank_bias = v.line_props.size();
  // v1.2 and older: the per-cell ranges, boxes and leaf segments as stored.
  v.cell_segment_range = p.array<BlobId::cell_segment_range>();
  v.cell_poly_range = p.array<BlobId::cell_poly_range>();
  v.cell_polys = p.array<BlobId::cell_polys>();
  v.line_bvh_range = p.array<BlobId::line_bvh_range>();
  v.poly_bvh_range = p.array<BlobId::poly_bvh_range>();
  v.line_bvh_box = p.array<BlobId::line_bvh_box>();
  v.poly_bvh_box = p.array<BlobId::poly_bvh_box>();
  v.qt_leaf_range = p.array<BlobId::qt_leaf_range>();
  v.qt_leaf_segments = p.array<BlobId::qt_leaf_segments>();
  // v1.3: the compact blobs, decoded into those.
  CompactBlobs c;
#define PREP_COMPACT_FROM_PACKAGE(T, name) c.name = p.array<BlobId::name>();
  PREP_COMPACT_BLOBS(PREP_COMPACT_FROM_PACKAGE)
#undef PREP_COMPACT_FROM_PACKAGE
  decode_compact(c, v);
  // Dash patterns from the layer table; the along-line distances of the
  // static-line vertices are computed here rather than stored, from each
  // line's start (a tile's cut line: from its "line_dash_start"; formats/SPEC.md
  // "Dashed lines").
  auto dashes = std::make_shared<LineDashes>();
  dashes->table = dash_table(p.metadata_json());
  if (dashes->table.any()) {
    dashes->vertex_distance =
        line_vertex_distances(v.line_vertices, v.line_vertex_line,
                              line_dash_start(p.metadata_json(), v.line_props.size()));
    v.dashes = std::move(dashes);
  }
  return v;
}

}  // namespace prep
