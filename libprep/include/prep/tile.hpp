// prep/tile.hpp — stage 3b, tile: one cleaned scene -> the scenes of the
// tiles of a tileset (ARCHITECTURE.md "3b. tile"; the index format is
// formats/SPEC.md "Tilesets").
//
//   SceneFeatures --tile_plan--> TilePlan --tile_scene(key)--> SceneFeatures
//                                                              (one tile, own origin)
//
// Tiles are squares of `size` metres of the frame CRS on a grid anchored at
// the CRS's own zero: tile (x, y) covers [x*size, (x+1)*size) x
// [y*size, (y+1)*size) in absolute frame coordinates, and its package's
// origin is the tile centre, so every tile keeps int32 millimetre positions
// (decal/format.hpp) however far it lies from the scene centre.
//
// A pixel is answered by exactly one tile (the one whose half-open square
// holds it), and the tile answers it exactly as a single package of the whole
// scene would. Each tile therefore carries every feature that can cover a
// point of its square, cut so that the cut cannot show inside it:
//  - static lines and outlines keep whole segments: every segment whose box
//    meets the square grown by `margin` (the widest stroke's reach, corners
//    included), plus one neighbour segment at each end of a run, so the
//    corners on the segments that matter are the corners of the whole line;
//    the run's cut ends lie farther than `margin` from the square;
//  - polygons are clipped to the square grown by `margin` (GEOS rectangle
//    clip); the new edges lie on that border, out of reach of the square;
//  - outlines clipped to their own ring (inset / offset) are clipped as that
//    ring's polygon, so the even-odd test that keeps one side (thesis §3.6)
//    is unchanged inside the square;
//  - dynamic lines (pixel widths) keep whole segments within
//    `dynamic_margin` (half a tile) of the square.
// Drawing-order keys (area, length, importance) are those of the whole
// feature, so every tile sorts its features as the whole scene does.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "prep/scene.hpp"

namespace prep {

struct TileKey {
  int64_t x = 0, y = 0;
  auto operator<=>(const TileKey&) const = default;
};

// "x<X>_y<Y>", the tile's file stem.
std::string tile_name(const TileKey& key);

// The smallest and largest tile size accepted, metres. Above the largest a
// tile's half plus its margin would not fit int32 millimetres.
constexpr double kMinTileSize = 1.0;
constexpr double kMaxTileSize = 4'000'000.0;

struct TilePlan {
  double size = 0;            // tile edge, frame metres
  double margin = 0;          // static strokes' reach beyond a tile, frame metres
  double dynamic_margin = 0;  // dynamic lines' reach (half a tile)
  SceneFrame frame;           // the scene's frame (origin: the scene's)
  // Every tile that receives a part, in key order, with the indices of the
  // scene's polygons, lines and dynamic lines whose boxes reach it.
  struct Members {
    std::vector<uint32_t> polygons, lines, dynamic_lines;
  };
  std::map<TileKey, Members> tiles;

  // The tile's square in absolute frame coordinates.
  Extent square(const TileKey& key) const;
  // The tile's package origin (the square's centre), absolute.
  std::pair<double, double> origin(const TileKey& key) const;
};

// The widest reach of any static stroke of `scene` beyond its line, frame
// metres: half the band (the whole band for inset / offset outlines) over
// sin(miter_limit / 2), the longest a miter corner can reach, plus 1%, at
// least 1 m.
double stroke_margin(const SceneFeatures& scene, const ModelOptions& options);

// The margin stroke_margin() gives for a widest half band `half_width`
// (the same arithmetic): the maximum over chunks of a scene equals the
// whole scene's margin, so a streaming pass can compute it chunk by chunk.
double stroke_margin_of(double half_width, const ModelOptions& options);
// The widest half band of `scene`'s static lines (the argument of
// stroke_margin_of; 0 when there is none).
double stroke_half_width(const SceneFeatures& scene);

// The bounding box of a ring (a polygon part's shell, a line's points):
// what the plan places a part by. Empty rings give an inverted box.
Extent ring_box(const Ring& ring);

// The tiles a part with box `local` (scene coordinates, relative to the
// frame origin `origin_x, origin_y`) reaches when grown by `by`: x in
// [lo.x, hi.x], y in [lo.y, hi.y]. tile_plan places every part with it.
struct TileRange {
  TileKey lo, hi;
  bool holds(const TileKey& k) const {
    return k.x >= lo.x && k.x <= hi.x && k.y >= lo.y && k.y <= hi.y;
  }
};
TileRange tile_range(const Extent& local, double by, double origin_x, double origin_y,
                     double tile_size);

// Throws usage_error when `tile_size` is outside [kMinTileSize, kMaxTileSize].
void check_tile_size(double tile_size);

// Which tiles each part reaches. Throws usage_error when `tile_size` is
// outside [kMinTileSize, kMaxTileSize].
TilePlan tile_plan(const SceneFeatures& scene, const ModelOptions& options, double tile_size);

// The scene of one tile: its parts cut as described above, in the scene's
// order, in coordinates relative to the tile's origin; the frame is the
// scene's with the tile's origin; the extent is the tile's parts' box. The
// manifest holds this tile's counts only (read = kept = features with a part
// here, parts, vertices_out; no entries; the scene's notes): the tileset
// index carries the scene's. Thread-safe (each call has its own GEOS
// context).
SceneFeatures tile_scene(const SceneFeatures& scene, const TilePlan& plan, const TileKey& key);

}  // namespace prep
