// prep/terrain.hpp — terrain matching of dynamic lines (thesis §3.2.2,
// §4.2.2): DEM sampling (any GDAL raster, any CRS, no-data fill) and the
// subdivision of dynamic lines into 3D vertices, fixed (lmax) or adaptive
// (--terrain-tolerance). GDAL stays inside libprep/terrain.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "prep/model.hpp"
#include "prep/scene.hpp"

namespace prep {

// What a build learned about its DEM, for the manifest.
struct TerrainStats {
  std::string description;            // path, driver, size, CRS name, units
  double cell_size_m = 0;             // ground size of a DEM cell (smaller side) near the data
  uint64_t window_cells = 0;          // cells read
  uint64_t nodata_cells = 0;          // of them: no-data (or NaN) cells, filled per policy
  std::string fill_policy;            // "nearest valid cell" or "value V"
  uint64_t samples = 0;               // heights sampled for stored vertices
  uint64_t samples_touching_fill = 0; // of them: bilinear stencil used a filled cell
  uint64_t samples_outside = 0;       // of them: outside the raster (edge value used)
  double min = 0, max = 0;            // over the cells read, metres after all scaling
};

// A DEM opened for sampling heights at scene points.
//
// No-data policy: a no-data (or NaN) cell takes the value of a nearest
// valid cell in the window read (Chebyshev distance in cells, computed by a
// breadth-first search over the 8-neighbourhood seeded with the valid cells
// in row-major order; among equally near cells the search's first wins), or
// `nodata_fill` (raw DEM units) when given. Filled cells and the vertex
// heights that used one are counted in TerrainStats (and the manifest). Heights are raw * band scale + band offset, converted from
// feet when the band's unit says so, times `z_scale`.
class DemSampler {
 public:
  // Opens `path` (GeoTIFF, SRTM .hgt, /vsizip/..., VRT: anything GDAL
  // reads). Scene coordinates are metres relative to frame.origin in
  // frame.crs_wkt; an empty crs_wkt means the DEM's own CRS. Points are
  // transformed to the DEM CRS (OAMS_TRADITIONAL_GIS_ORDER); the raster is
  // never warped. Throws gdal_error when the file or a CRS cannot be used.
  DemSampler(const std::string& path, const SceneFrame& frame, double z_scale,
             std::optional<double> nodata_fill);
  ~DemSampler();
  DemSampler(const DemSampler&) = delete;
  DemSampler& operator=(const DemSampler&) = delete;

  // Pixel/line coordinates in the full raster, pixel-is-area (the centre of
  // cell (i, j) is (i + 0.5, j + 0.5)), of scene points. Thread-safe.
  void to_pixel(std::span<const Point2> scene, std::span<Point2> pixel) const;
  Point2 to_pixel(Point2 scene) const;

  // Ground size in metres of one DEM cell at scene point p (the smaller of
  // its two sides, measured in the scene frame).
  double cell_size_metres(Point2 p) const;

  // Reads the cells covering the pixel box (plus a 16-cell margin, clipped
  // to the raster) and fills no-data. Call before height(). Not thread-safe.
  void load(double px0, double py0, double px1, double py1);

  // GDAL's bilinear height at pixel coordinates: weights from the
  // half-pixel cell centres, the edge cell's value beyond the outermost
  // centres. Thread-safe after load(); points outside the window read use
  // its edge. `touched_fill`, when given, is set if a filled cell has
  // non-zero weight.
  double height(double px, double py, bool* touched_fill = nullptr) const;

  // True when the pixel position lies outside the raster.
  bool outside(double px, double py) const;

  const TerrainStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct MatchOptions {
  double lmax = 0;       // maximum horizontal piece length, metres (>= 0.01;
                         // infinity: no subdivision)
  double tolerance = 0;  // > 0: adaptive subdivision with this bound, metres
};

// Terrain-matched dynamic lines, ready for the dyn_* blobs.
struct MatchedLines {
  std::vector<ivec4> vertices;       // (x, y, z quanta, line index)
  std::vector<ivec2> prev_next;      // -1 at open ends; closed lines wrap
  std::vector<uint32_t> line_start;  // first vertex per line
  uint64_t vertices_in = 0;          // input vertices
  uint64_t vertices_fixed = 0;       // after subdivision to lmax
  uint64_t vertices_out = 0;         // stored (== vertices_fixed unless adaptive)
  double max_piece_length = 0;       // longest stored piece, horizontal metres
  double max_deviation = 0;          // max |3D piece - DEM surface| along stored pieces, metres
  uint64_t tolerance_misses = 0;     // adaptive pieces that reached 1 cm and still miss the bound
  TerrainStats terrain;
};

// Matches `lines` (scene coordinates, width ignored) to the terrain:
// thesis Algorithm 3.1 with the output offsets from a parallel prefix sum,
// then one bilinear height per vertex, sampled at the stored (quantised)
// position. Pieces are at most lmax long horizontally after quantisation.
// With options.tolerance > 0 only vertices needed to keep every straight
// 3D piece within the tolerance of the DEM surface are kept (original
// vertices always stay); the bound is checked exactly on the piecewise
// quadratic restriction of the bilinear surface, with 5 mm held back for
// quantisation. `dem` null: flat terrain, z = 0. Lines need >= 2 points
// (closed: >= 3); throws input_error otherwise. Deterministic at any thread
// count.
MatchedLines match_terrain(const std::vector<SceneLine>& lines, DemSampler* dem,
                           const MatchOptions& options);

// A point of a piece's path in DEM pixel space: parameter s in [0, 1]
// along the piece and its pixel position.
struct PixelPathPoint {
  double s = 0;
  Point2 pixel;
};

// Maximum |z(s) - h(s)| along a straight 3D piece with heights za at s = 0
// and zb at s = 1, h the DEM's bilinear surface along `path` (pixel
// positions at increasing s, first s = 0, last s = 1, linear between
// them). Each path part is cut where it crosses a line through cell
// centres and each quadratic part is maximised exactly. Returns the
// maximum and, in *arg, the s where it occurs. Thread-safe after load().
double piece_deviation(const DemSampler& dem, std::span<const PixelPathPoint> path, double za,
                       double zb, double* arg = nullptr);

}  // namespace prep
