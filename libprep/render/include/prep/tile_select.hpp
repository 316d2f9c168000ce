// prep/tile_select.hpp — which tiles of a tileset (prep/tileset.hpp) a view
// draws: full-detail tiles near the camera, overview levels farther away,
// within a budget of GPU memory (the drawn tiles' blobs, decoded). No GL:
// `decalprep render` runs it before either renderer
// (prep/render_request.hpp render()).
//
// The rule is a screen-space-error rule, as 3D Tiles refines by geometric
// error: the quadtree of levels is walked from the coarsest level down, and
// a tile of level L is drawn when the level's resolution r_L (ground metres
// its parts were simplified to, TileLevel::resolution) is at most the
// ground size of one screen pixel at the tile's nearest visible point;
// otherwise its four children are visited. Level 0 (full detail) always
// qualifies. The pixel's ground size at distance d from the eye is
// d * 2 tan(fov_y / 2) / height (perspective) and min(ortho_w / width,
// ortho_h / height) (orthographic). A tile's nearest visible point is the
// point of its square, cut to the ground footprint of the view and to the
// tileset's extent, between the terrain heights zmin and zmax, nearest the
// eye. A tile absent from the index has no data: nothing is drawn there.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "prep/render.hpp"
#include "prep/tileset.hpp"

namespace prep::render {

// The bytes a tile's package holds decoded: the sum of its blobs' decoded
// sizes (count x stride), which is what a loaded tile holds in memory and
// bounds what GL uploads of it (several times TileEntry::bytes, which are
// compressed). `decalprep render` reads them from each tile's header and
// blob table (decal::read_package_sizes) and throws format_error naming
// the file when it cannot.
using TileBlobBytes = std::function<uint64_t(int level, const TileEntry& tile)>;

struct TileSelectOptions {
  // Decoded blob bytes (blob_bytes) the drawn tiles may hold; 0: no limit.
  uint64_t gpu_budget = 0;
  // Asked once for each drawn tile and each tile the budget considers
  // drawing instead of its children, no other. Required with a budget;
  // without one it may be empty (the blob byte figures are then 0).
  TileBlobBytes blob_bytes;
  // Draw this level everywhere (0: full detail) instead of choosing.
  std::optional<int> level;
};

struct SelectedTile {
  int level = 0;                     // 0: full detail
  const TileEntry* entry = nullptr;  // into the index
  double pixel_size = 0;             // ground metres per pixel at its nearest visible point
  uint64_t blob_bytes = 0;           // its blobs decoded (TileSelectOptions::blob_bytes)
};

struct TileSelection {
  // Disjoint squares that together cover every tile with data that meets the
  // footprint; by level, then key.
  std::vector<SelectedTile> tiles;
  uint64_t blob_bytes = 0;         // the drawn tiles' blobs decoded: what gpu_budget caps
  uint64_t package_bytes = 0;      // the drawn tiles' package bytes (TileEntry::bytes)
  uint64_t full_detail_bytes = 0;  // package bytes of the level-0 tiles that meet the footprint
  size_t full_detail_tiles = 0;    // how many level-0 tiles meet the footprint
  std::vector<size_t> per_level;   // tiles drawn per level, index = level
  size_t coarsened = 0;            // groups of children the budget replaced by their parent
  // The ground footprint (absolute frame coordinates); none: the camera
  // sees the sky, every tile counts as met.
  std::optional<Extent> footprint;
};

// The ground size of one screen pixel at `point` (metres relative to the
// camera's frame, like the camera).
double pixel_ground_size(const Camera& camera, uint32_t width, uint32_t height, const Vec3& point);

// The tiles of `index` to draw for `camera` (metres relative to the index's
// frame origin) on a width x height image over terrain between zmin and zmax.
// With a budget, while the drawn blob bytes exceed it, the four (or fewer,
// where the others are empty or out of view) drawn children of a tile are
// replaced by that tile, the tile whose own screen-space error (r_L over its
// pixel size) is smallest first, so the view coarsens where it shows least:
// this is raising the error threshold until the view fits. Throws resource_error
// naming the budget and the blob bytes the coarsest tiles need when even
// they exceed it, usage_error when `options.level` names no level of the
// index, and what options.blob_bytes throws.
TileSelection select_tiles(const TilesetIndex& index, const Camera& camera, uint32_t width,
                           uint32_t height, double zmin, double zmax,
                           const TileSelectOptions& options = {});

}  // namespace prep::render
