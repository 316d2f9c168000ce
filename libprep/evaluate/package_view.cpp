// libprep/evaluate/package_view.cpp — StaticView over a package read from
// disk: blobs from decal::Package, grid from the metadata chunk, checked by
// the package's structural check with that grid (the evaluator indexes
// without checks).
#include <nlohmann/json.hpp>

#include "decal/inspect.hpp"
#include "decal/layout.hpp"
#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

GridParams grid_from_metadata(std::string_view metadata) {
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

}  // namespace

StaticView view_of(const decal::Package& p) {
  using decal::BlobId;
  StaticView v;
  v.grid = grid_from_metadata(p.metadata_json());
  // The package's one structural check, with the grid: every index the
  // evaluator follows is in range and every BVH is a full tree per cell.
  const decal::Grid grid{v.grid.origin_x, v.grid.origin_y, v.grid.cell_w,
                         v.grid.cell_h,   v.grid.nx,       v.grid.ny};
  if (decal::Status st = decal::validate_indices(p, &grid); !st)
    fail<format_error>(kEvaluateStage, st.message);
#define PREP_FROM_PACKAGE(T, name) v.name = p.array<T>(BlobId::name);
  PREP_STATIC_VIEW_BLOBS(PREP_FROM_PACKAGE)
#undef PREP_FROM_PACKAGE
  v.qt_leaf_range = p.array<uvec2>(BlobId::qt_leaf_range);  // v1.2 and older
  v.qt_leaf_segments = p.array<uvec2>(BlobId::qt_leaf_segments);
  if (p.minor() < 2) v.polygon_rank_bias = v.line_props.size();
  // v1.3 compact blobs (formats/SPEC.md "Compact layout (v1.3)"): decoded
  // into the v1.2 ranges and leaf segments the evaluator walks.
  namespace L = decal::layout;
  struct Decoded {
    std::vector<L::u2> seg_range, poly_range, leaf_range, leaf_segments;
    std::vector<L::u4> line_bvh, poly_bvh;
    std::vector<ivec4> line_boxes, poly_boxes;
    std::vector<L::u4> cell_polys;
  };
  const L::CellGrid cg{v.grid.origin_x, v.grid.origin_y, v.grid.cell_w, v.grid.cell_h, v.grid.nx};
  auto d = std::make_shared<Decoded>();
  const auto line_first = p.array<L::u2>(BlobId::cell_line_first);
  const auto poly_first = p.array<L::u2>(BlobId::cell_poly_first);
  const auto loop_range = p.array<L::u2>(BlobId::qt_leaf_loop_range);
  const auto loops = p.array<uint32_t>(BlobId::qt_leaf_loops);
  static_assert(std::is_same_v<L::u2, uvec2> && std::is_same_v<L::u4, uvec4>);
  auto as_u2 = [](const std::vector<L::u2>& a) { return std::span<const uvec2>(a); };
  auto as_u4 = [](const std::vector<L::u4>& a) { return std::span<const uvec4>(a); };
  // One kind's per-cell firsts and 16-bit boxes into its ranges, BVH ranges
  // and boxes.
  auto cells = [&](std::span<const L::u2> first, BlobId box16, std::vector<L::u2>& range,
                   std::vector<L::u4>& bvh, std::vector<ivec4>& boxes,
                   std::span<const uvec2>& vrange, std::span<const uvec4>& vbvh,
                   std::span<const ivec4>& vboxes) {
    if (first.empty()) return;
    L::decode_cells(first, range, bvh);
    vrange = as_u2(range);
    vbvh = as_u4(bvh);
    boxes = L::decode_boxes16(first, p.array<L::u2>(box16), cg);
    vboxes = boxes;
  };
  cells(line_first, BlobId::line_bvh_box16, d->seg_range, d->line_bvh, d->line_boxes,
        v.cell_segment_range, v.line_bvh_range, v.line_bvh_box);
  cells(poly_first, BlobId::poly_bvh_box16, d->poly_range, d->poly_bvh, d->poly_boxes,
        v.cell_poly_range, v.poly_bvh_range, v.poly_bvh_box);
  if (!loop_range.empty() || !loops.empty()) {
    L::decode_leaves(loop_range, loops, d->leaf_range, d->leaf_segments);
    v.qt_leaf_range = as_u2(d->leaf_range);
    v.qt_leaf_segments = as_u2(d->leaf_segments);
  }
  const auto entries = p.array<L::u2>(BlobId::cell_poly_entries);
  if (!entries.empty()) {
    L::decode_poly_entries(entries, p.array<uint32_t>(BlobId::cell_poly_holes), d->cell_polys);
    v.cell_polys = as_u4(d->cell_polys);
  }
  v.storage = std::move(d);
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
