// prep/dem.hpp — the terrain surface: one DEM module for the whole toolchain
// (libprep/dem). The project stage takes the DEM's footprint from it,
// terrain matching drapes dynamic lines on it (libprep/model/terrain) and the
// renderer draws its terrain mesh from it (libprep/render), so all three
// see the same heights. GDAL stays inside libprep/dem.
//
// The surface of a DEM, in metres:
//   * Opening: any GDAL raster (GeoTIFF, SRTM .hgt, VRT, /vsizip/...), band 1,
//     with a geotransform. Its CRS is the raster's own; a raster without one
//     is an error naming the file unless DemSpec::assume_crs is given. A
//     local path that is not a regular file (a FIFO, a device, a socket, a
//     directory) is refused before GDAL opens it (prep/files.hpp), so no
//     DEM can block a command. A DEM that a package names (not the user:
//     DemSpec::named_by_package) is opened only when it is a local regular
//     file, or a /vsizip/, /vsitar/ or /vsigzip/ path into one, and only by
//     the drivers of self-contained raster formats (kPackageDemDrivers): never
//     a network path, a connection string or a VRT that could reach anything.
//   * Mosaic: DemSpec::more_paths joins further rasters to `path` through an
//     anonymous in-memory VRT (GDALBuildVRT). Each raster is opened and
//     checked on its own first, by the rules above (assume_crs for one
//     without a CRS, the package rule for each); rasters whose CRS, band
//     count, band 1 data type, scale, offset or unit differ from the
//     first's are an input_error naming both and the values. Each source
//     keeps its own no-data, so a raster's voids do not cover its
//     neighbour's cells; where rasters overlap, the later one's valid cells
//     win. The mosaic's no-data (cells no raster covers, or all cover with
//     voids) is the first raster's no-data that has one. A raster GDAL
//     would leave out of the mosaic (it warns) is an input_error too.
//   * Heights: (raw * band scale + band offset) * unit * z_scale, where unit
//     converts the band's unit type to metres: "ft", "foot", "feet",
//     "international foot" are 0.3048 m; "us-ft", "US survey foot", "ftUS"
//     are 1200/3937 m; anything else (metres, empty) is 1.
//   * No-data: a raw value equal to the band's no-data value, or NaN. Such a
//     cell takes `nodata_fill` (raw units, so it is scaled like any cell)
//     when given; otherwise the value of the nearest valid cell of the
//     raster, by Chebyshev distance in cells. Ties go to the first cell a
//     breadth-first search over the 8-neighbourhood reaches, the search
//     seeded with the valid cells in row-major order and visiting
//     neighbours row by row (dy = -1, 0, 1; dx = -1, 0, 1 within a row):
//     a cell next to valid cells takes the first of them in row-major
//     order. The result does not depend on the window read (the window
//     grows until every cell it must answer for has its nearest valid cell
//     inside, up to kMaxFillMargin cells beyond the requested area; deeper
//     voids take the nearest valid cell within that margin, and the
//     fill_policy says so). A raster with no valid cell within reach is
//     flat at 0 m.
//   * Between cell centres: GDAL's bilinear kernel (cell (i, j) has its
//     centre at pixel (i + 0.5, j + 0.5)); beyond the outermost centres the
//     edge cell's value.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "prep/features.hpp"

namespace prep {

// Which DEM, and everything that decides its surface.
struct DemSpec {
  std::string path;                   // any GDAL raster path; empty: flat terrain
  std::string assume_crs;             // CRS of a raster that has none (--assume-crs)
  double z_scale = 1.0;               // vertical exaggeration
  std::optional<double> nodata_fill;  // raw DEM units; none: nearest valid cell
  // The path comes from a package's metadata, not from the user: opened
  // only under the package rule above (package_dem_refusal).
  bool named_by_package = false;
  // Further rasters mosaicked with `path` (the mosaic rule above); empty:
  // `path` alone. Ignored without a path.
  std::vector<std::string> more_paths;
};

// The GDAL drivers a DEM named by a package may be opened with: formats
// whose file holds the raster itself and names no other file or URL.
inline constexpr const char* kPackageDemDrivers[] = {
    "GTiff", "SRTMHGT", "AAIGrid", "GSAG", "GSBG", "GS7BG", "XYZ",  "EHdr",
    "ENVI",  "HFA",     "USGSDEM", "BT",   "PNG",  "JPEG",  "GPKG", "netCDF"};

// Why the DEM path a package names is not opened, or empty when it may be:
// it must be a local file that exists and is regular, or a /vsizip/,
// /vsitar/ or /vsigzip/ path whose archive is one (nothing nested inside);
// a network path, any other /vsi path, a URL or a connection string is
// refused. Only stat()s.
std::string package_dem_refusal(const std::string& path);

// What a DEM read learned, for the manifest.
struct TerrainStats {
  std::string description;             // path, driver, size, CRS name, units
  double cell_size_m = 0;              // ground size of a DEM cell (smaller side) near the data
  uint64_t window_cells = 0;           // cells read
  uint64_t nodata_cells = 0;           // of them: no-data (or NaN) cells, filled per policy
  std::string fill_policy;             // "nearest valid cell" or "value V"
  uint64_t samples = 0;                // heights sampled for stored vertices
  uint64_t samples_touching_fill = 0;  // of them: bilinear stencil used a filled cell
  uint64_t samples_outside = 0;        // of them: outside the raster (edge value used)
  double min = 0, max = 0;             // over the cells read, metres after all scaling
};

// The raster's footprint, for the project stage's default clip extent.
struct DemFootprint {
  std::string crs_wkt;  // the DEM's CRS (its own, or DemSpec::assume_crs), WKT2
  bool crs_assumed = false;
  Extent bounds;  // bounding box of the raster's corners, in that CRS
};

// Opens the DEM (checks the file, the geotransform and the CRS rule above)
// and returns its footprint. Throws gdal_error / input_error naming the file.
DemFootprint dem_footprint(const DemSpec& spec);

// The DEM's cell-centre lattice as seen from the scene frame, when that is a
// regular axis-aligned grid: the DEM is in the frame CRS (or the frame has
// none) and north-up without rotation. Cell (i, j) has its centre at scene
// (x0 + i * dx, y0 + j * dy); dy < 0 for a north-up raster.
struct DemLattice {
  double x0 = 0, y0 = 0, dx = 1, dy = -1;
};

// A DEM opened for sampling heights at scene points.
class DemSampler {
 public:
  // Opens spec.path. Scene coordinates are metres relative to frame.origin
  // in frame.crs_wkt; an empty crs_wkt means the DEM's own CRS. Points are
  // transformed to the DEM CRS (OAMS_TRADITIONAL_GIS_ORDER); the raster is
  // never warped. Throws gdal_error when the file or a CRS cannot be used,
  // input_error when the DEM has no CRS and spec.assume_crs is empty.
  DemSampler(const DemSpec& spec, const SceneFrame& frame);
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

  // The cell-centre lattice in scene coordinates, when it is a regular
  // axis-aligned grid there (see DemLattice); nullopt otherwise.
  std::optional<DemLattice> lattice() const;

  // Reads the cells covering the pixel box (plus a margin of at least 16
  // cells, clipped to the raster) and fills no-data. Call before height().
  // Not thread-safe.
  void load(double px0, double py0, double px1, double py1);

  // GDAL's bilinear height at pixel coordinates: weights from the
  // half-pixel cell centres, the edge cell's value beyond the outermost
  // centres. Thread-safe after load(); points outside the window read use
  // its edge. `touched_fill`, when given, is set if a filled cell has
  // non-zero weight.
  double height(double px, double py, bool* touched_fill = nullptr) const;

  // The largest |z00 - z10 - z01 + z11| (metres) over the 2x2 cell blocks
  // of the window read: how far the bilinear surface is from planar. Any
  // mesh with a vertex at every cell centre whose triangles halve 1/s x 1/s
  // sub-cells lies within twist / (4 s^2) of the surface. After load().
  double max_twist() const;

  // True when the pixel position lies outside the raster.
  bool outside(double px, double py) const;

  const TerrainStats& stats() const;

  // Fill search reach: voids deeper than this many cells beyond the
  // requested area take the nearest valid cell within it.
  static constexpr int kMaxFillMargin = 1024;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace prep
