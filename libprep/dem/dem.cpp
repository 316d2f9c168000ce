// The terrain surface (prep/dem.hpp): open a DEM through GDAL, resolve its
// CRS, transform scene points to pixel space, read the used window, fill
// no-data, scale to metres, bilinear sampling (GDAL's kernel).
#include "prep/dem.hpp"

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>
#include <sys/stat.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <iterator>
#include <limits>
#include <mutex>
#include <sstream>
#include <string_view>
#include <vector>

#include "gdal_util.hpp"
#include "prep/error.hpp"
#include "prep/files.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

struct TransformDeleter {
  void operator()(OGRCoordinateTransformation* t) const {
    OGRCoordinateTransformation::DestroyCT(t);
  }
};
using TransformPtr = std::unique_ptr<OGRCoordinateTransformation, TransformDeleter>;

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Metres per unit of the band's unit type (prep/dem.hpp lists the names).
double metres_per_unit(const std::string& unit) {
  if (unit == "ft" || unit == "foot" || unit == "feet" || unit == "international foot")
    return 0.3048;
  if (unit == "us-ft" || unit == "us survey foot" || unit == "ftus") return 1200.0 / 3937.0;
  return 1.0;
}

// The opened raster, its geotransform and its CRS (own or assumed).
struct OpenedDem {
  // A mosaic's rasters, open while the VRT `ds` (closed first) reads them.
  std::vector<GDALDatasetUniquePtr> tiles;
  GDALDatasetUniquePtr ds;
  double gt[6] = {0, 1, 0, 0, 0, 1};
  OGRSpatialReference srs;
  bool assumed = false;
};

// An archive path given without the file inside it (/vsizip/N43E007.hgt.zip,
// /vsitar/tiles.tar): the one raster GDAL identifies among its entries, as
// the full /vsi path; "" when the path is not such an archive. Two or more
// rasters, or none: input_error listing what the archive holds.
std::string raster_in_archive(const std::string& path) {
  static constexpr std::string_view kArchives[] = {"/vsizip/", "/vsitar/", "/vsi7z/"};
  if (std::none_of(std::begin(kArchives), std::end(kArchives),
                   [&](std::string_view p) { return path.rfind(p, 0) == 0; }))
    return {};
  // Not VSIStatL on the archive: GDAL reports an archive of one file as
  // that file, whose name (N43E007.hgt.zip) no raster driver takes.
  char** entries = VSIReadDirRecursive(path.c_str());
  if (!entries) return {};
  std::vector<std::string> all, rasters;
  const std::string base = path.back() == '/' ? path : path + "/";
  for (char** e = entries; *e; ++e) {
    const std::string full = base + *e;
    VSIStatBufL st{};
    if (VSIStatL(full.c_str(), &st) != 0 || VSI_ISDIR(st.st_mode)) continue;
    all.push_back(*e);
    if (GDALIdentifyDriver(full.c_str(), nullptr)) rasters.push_back(full);
  }
  CSLDestroy(entries);
  if (rasters.size() == 1) return rasters[0];
  auto list = [](const std::vector<std::string>& v) {
    std::string s;
    for (size_t i = 0; i < v.size() && i < 20; ++i) s += (i ? ", " : "") + v[i];
    if (v.size() > 20) s += ", ... (" + std::to_string(v.size() - 20) + " more)";
    return s;
  };
  if (rasters.empty())
    fail<input_error>(kDemStage, path + ": the archive holds no raster GDAL can open (entries: " +
                                     (all.empty() ? std::string("none") : list(all)) + ")");
  fail<input_error>(kDemStage, path + ": the archive holds " + std::to_string(rasters.size()) +
                                   " rasters; name one, e.g. " + rasters[0] +
                                   " (they are: " + list(rasters) + ")");
}

// One raster, opened and checked on its own (prep/dem.hpp "Opening").
OpenedDem open_raster(const std::string& path, const DemSpec& spec) {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
  // Before GDAL sees the path: a FIFO or a device would block its open().
  // A directory is a raster for some drivers (an Arc/Info binary grid).
  try {
    check_input_file(path, "DEM", InputKind::file_or_directory);
  } catch (const input_error& e) {
    fail<input_error>(kDemStage, e.what());
  }
  if (spec.named_by_package)
    if (const std::string why = package_dem_refusal(path); !why.empty())
      fail<input_error>(kDemStage, path + ": the package names this DEM, which is not opened: " +
                                       why + "; pass it with --dem to use it");
  OpenedDem d;
  CPLErrorReset();
  std::vector<const char*> drivers;
  if (spec.named_by_package) {
    drivers.assign(std::begin(kPackageDemDrivers), std::end(kPackageDemDrivers));
    drivers.push_back(nullptr);
  }
  // An archive named without the file inside: its one raster.
  const std::string inner = raster_in_archive(path);
  const std::string& open_path = inner.empty() ? path : inner;
  CPLErrorReset();
  d.ds.reset(GDALDataset::Open(open_path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY,
                               drivers.empty() ? nullptr : drivers.data()));
  const std::string why = CPLGetLastErrorMsg();
  if (!d.ds)
    fail<gdal_error>(kDemStage, path + ": cannot open DEM: " +
                                    (why.empty() ? "GDAL recognises no raster format in it" : why) +
                                    (spec.named_by_package
                                         ? " (a DEM the package names is opened only as one of "
                                           "the self-contained formats GeoTIFF, SRTM .hgt, ASCII "
                                           "grid, XYZ, EHdr, ENVI, HFA, USGS DEM, BT, PNG, JPEG, "
                                           "GeoPackage, netCDF; pass it with --dem to use it)"
                                         : ""));
  if (d.ds->GetRasterCount() < 1) fail<gdal_error>(kDemStage, path + ": DEM has no raster band");
  if (d.ds->GetGeoTransform(d.gt) != CE_None)
    fail<input_error>(kDemStage, path + ": DEM has no geotransform");
  if (const OGRSpatialReference* own = d.ds->GetSpatialRef()) {
    d.srs = *own;
  } else if (!spec.assume_crs.empty()) {
    CPLErrorReset();
    if (d.srs.SetFromUserInput(spec.assume_crs.c_str()) != OGRERR_NONE)
      fail<input_error>(kDemStage, path + ": DEM has no CRS and --assume-crs '" + spec.assume_crs +
                                       "' is not a CRS: " + CPLGetLastErrorMsg());
    d.assumed = true;
  } else {
    fail<input_error>(
        kDemStage, path +
                       ": DEM has no CRS; pass --assume-crs (e.g. EPSG:4326) or set assume_crs in "
                       "the scene file");
  }
  d.srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return d;
}

// A CRS for messages: its authority code (EPSG:4326), else its name.
std::string crs_text(const OGRSpatialReference& srs) {
  const char* auth = srs.GetAuthorityName(nullptr);
  const char* code = srs.GetAuthorityCode(nullptr);
  if (auth && code) return std::string(auth) + ":" + code;
  return srs.GetName() ? srs.GetName() : "unnamed";
}

std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// The band 1 properties a mosaic's rasters must share, as text.
struct BandTraits {
  int bands = 0;
  std::string type, scale, offset, unit;
};

BandTraits band_traits(GDALDataset& ds) {
  GDALRasterBand* b = ds.GetRasterBand(1);
  int ok = 0;
  const double scale = b->GetScale(&ok);
  const std::string scale_text = ok ? number_text(scale) : "1";
  const double offset = b->GetOffset(&ok);
  return {ds.GetRasterCount(), GDALGetDataTypeName(b->GetRasterDataType()), scale_text,
          ok ? number_text(offset) : "0",
          "'" + std::string(b->GetUnitType() ? b->GetUnitType() : "") + "'"};
}

// GDAL's warnings and errors while the mosaic is made.
void CPL_STDCALL collect_cpl_messages(CPLErr level, CPLErrorNum, const char* msg) {
  if (level < CE_Warning) return;
  auto* out = static_cast<std::vector<std::string>*>(CPLGetErrorHandlerUserData());
  out->push_back(msg ? msg : "");
}

// The mosaic of prep/dem.hpp: every raster opened and checked alone, then
// an anonymous in-memory VRT over the open rasters. Its CRS is the checked
// one (own or assumed), so GDAL's own CRS comparison is off
// (-allow_projection_difference); it would drop a raster without a CRS.
OpenedDem open_mosaic(const DemSpec& spec) {
  std::vector<std::string> paths{spec.path};
  paths.insert(paths.end(), spec.more_paths.begin(), spec.more_paths.end());
  std::vector<OpenedDem> tiles;
  for (const std::string& p : paths) tiles.push_back(open_raster(p, spec));
  const OpenedDem& first = tiles[0];
  const BandTraits want = band_traits(*first.ds);
  for (size_t i = 1; i < tiles.size(); ++i) {
    auto differ = [&](const std::string& what, const std::string& theirs, const std::string& ours) {
      fail<input_error>(kDemStage, paths[i] + ": " + what + " " + theirs + " differs from " +
                                       paths[0] + "'s " + ours +
                                       "; the rasters of a DEM mosaic must share it");
    };
    if (!tiles[i].srs.IsSame(&first.srs))
      differ("CRS", crs_text(tiles[i].srs), crs_text(first.srs));
    const BandTraits have = band_traits(*tiles[i].ds);
    if (have.bands != want.bands)
      differ("band count", std::to_string(have.bands), std::to_string(want.bands));
    if (have.type != want.type) differ("band 1 data type", have.type, want.type);
    if (have.scale != want.scale) differ("band 1 scale", have.scale, want.scale);
    if (have.offset != want.offset) differ("band 1 offset", have.offset, want.offset);
    if (have.unit != want.unit) differ("band 1 unit", have.unit, want.unit);
  }
  CPLStringList args;
  args.AddString("-allow_projection_difference");
  // Cells no raster fills read as no-data, not as 0 (see prep/dem.hpp).
  for (const OpenedDem& t : tiles) {
    int ok = 0;
    const double nodata = t.ds->GetRasterBand(1)->GetNoDataValue(&ok);
    if (!ok) continue;
    args.AddString("-vrtnodata");
    args.AddString(std::isnan(nodata) ? "nan" : CPLSPrintf("%.17g", nodata));
    break;
  }
  std::vector<GDALDatasetH> handles;
  for (const OpenedDem& t : tiles) handles.push_back(GDALDataset::ToHandle(t.ds.get()));
  GDALBuildVRTOptions* options = GDALBuildVRTOptionsNew(args.List(), nullptr);
  std::vector<std::string> messages;
  CPLErrorReset();
  CPLPushErrorHandlerEx(collect_cpl_messages, &messages);
  int usage_error = 0;
  GDALDatasetH vrt = GDALBuildVRT("", static_cast<int>(handles.size()), handles.data(), nullptr,
                                  options, &usage_error);
  CPLPopErrorHandler();
  GDALBuildVRTOptionsFree(options);
  OpenedDem d;
  d.ds.reset(GDALDataset::FromHandle(vrt));
  if (!d.ds || !messages.empty()) {
    std::string why;
    for (const std::string& m : messages) why += (why.empty() ? "" : "; ") + m;
    fail<input_error>(kDemStage, dem_text(spec.path, spec.more_paths) +
                                     ": cannot mosaic the DEM rasters: " +
                                     (why.empty() ? "GDALBuildVRT failed" : why));
  }
  if (d.ds->GetGeoTransform(d.gt) != CE_None)
    fail<input_error>(
        kDemStage, dem_text(spec.path, spec.more_paths) + ": the DEM mosaic has no geotransform");
  // The checked CRS, scale, offset and unit, whatever the VRT copied.
  d.srs = first.srs;
  GDALRasterBand* band = d.ds->GetRasterBand(1);
  GDALRasterBand* first_band = first.ds->GetRasterBand(1);
  int ok = 0;
  const double scale = first_band->GetScale(&ok);
  band->SetScale(ok ? scale : 1.0);
  const double offset = first_band->GetOffset(&ok);
  band->SetOffset(ok ? offset : 0.0);
  band->SetUnitType(first_band->GetUnitType() ? first_band->GetUnitType() : "");
  for (OpenedDem& t : tiles) {
    d.assumed = d.assumed || t.assumed;
    d.tiles.push_back(std::move(t.ds));
  }
  return d;
}

OpenedDem open_dem(const DemSpec& spec) {
  return spec.more_paths.empty() || spec.path.empty() ? open_raster(spec.path, spec)
                                                      : open_mosaic(spec);
}

constexpr int kMargin = 16;  // cells read beyond the requested area, at least

}  // namespace

std::string package_dem_refusal(const std::string& path) {
  if (path.empty()) return "the path is empty";
  if (is_network_path(path)) return "it is a network path";
  if (is_gdal_virtual_path(path)) {
    std::string_view rest;
    for (std::string_view p : {"/vsizip/", "/vsitar/", "/vsigzip/"})
      if (path.rfind(p, 0) == 0) rest = std::string_view(path).substr(p.size());
    if (rest.empty()) return "it is a GDAL virtual path other than /vsizip/, /vsitar/, /vsigzip/";
    if (rest.find("/vsi") != std::string_view::npos)
      return "it nests one GDAL virtual path in another";
    // The archive itself is checked by check_input_file when it is opened
    // (no FIFO, no device), and only self-contained drivers read its member.
    return {};
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "no such local file";
  if (!S_ISREG(st.st_mode)) {
    const std::string kind = special_file_kind(path);
    return "it is " + (kind.empty() ? std::string("a directory") : kind) + ", not a regular file";
  }
  return {};
}

DemFootprint dem_footprint(const DemSpec& spec) {
  const OpenedDem d = open_dem(spec);
  const double* gt = d.gt;
  const double w = d.ds->GetRasterXSize(), h = d.ds->GetRasterYSize();
  DemFootprint f;
  f.crs_wkt = crs_wkt2(d.srs);
  f.crs_assumed = d.assumed;
  f.bounds = {std::min(gt[0], gt[0] + w * gt[1] + h * gt[2]),
              std::min(gt[3], gt[3] + w * gt[4] + h * gt[5]),
              std::max(gt[0], gt[0] + w * gt[1] + h * gt[2]),
              std::max(gt[3], gt[3] + w * gt[4] + h * gt[5])};
  return f;
}

struct DemSampler::Impl {
  std::string path;                         // for messages: dem_text of the rasters
  std::vector<GDALDatasetUniquePtr> tiles;  // a mosaic's rasters (OpenedDem::tiles)
  GDALDatasetUniquePtr ds;
  GDALRasterBand* band = nullptr;
  int width = 0, height = 0;
  double gt[6] = {0, 1, 0, 0, 0, 1};
  double inv_gt[6] = {0, 1, 0, 0, 0, 1};
  double origin_x = 0, origin_y = 0;
  OGRSpatialReference scene_srs, dem_srs;
  bool same_crs = true;
  double z_scale = 1, scale = 1, offset = 0, unit = 1;
  std::optional<double> nodata_fill;
  bool has_nodata = false;
  double nodata = 0;
  // The window read: cells [wx0, wx0 + ww) x [wy0, wy0 + wh).
  int wx0 = 0, wy0 = 0, ww = 0, wh = 0;
  std::vector<double> z;
  std::vector<uint8_t> filled;
  double max_twist = 0;
  TerrainStats stats;
  std::string base_fill_policy;
  mutable tbb::enumerable_thread_specific<TransformPtr> forward, inverse;

  TransformPtr make(bool to_dem) const {
    if (same_crs) return nullptr;
    OGRCoordinateTransformation* t = to_dem
                                         ? OGRCreateCoordinateTransformation(&scene_srs, &dem_srs)
                                         : OGRCreateCoordinateTransformation(&dem_srs, &scene_srs);
    if (!t)
      fail<gdal_error>(kDemStage, path +
                                      ": cannot transform between the scene CRS and the DEM CRS: " +
                                      CPLGetLastErrorMsg());
    return TransformPtr(t);
  }
  OGRCoordinateTransformation* fwd() const {
    auto& t = forward.local();
    if (!t && !same_crs) t = make(true);
    return t.get();
  }
  OGRCoordinateTransformation* inv() const {
    auto& t = inverse.local();
    if (!t && !same_crs) t = make(false);
    return t.get();
  }
  double cell(int i, int j) const { return z[static_cast<size_t>(j - wy0) * ww + (i - wx0)]; }
  bool cell_filled(int i, int j) const {
    return filled[static_cast<size_t>(j - wy0) * ww + (i - wx0)];
  }

  void read_window(int x0, int y0, int x1, int y1);
  bool fill(int bx0, int by0, int bx1, int by1, uint64_t& invalid_count, bool& none_valid);
};

DemSampler::DemSampler(const std::string& path, const SceneFrame& frame, double z_scale,
                       std::optional<double> nodata_fill)
    : DemSampler(DemSpec{path, "", z_scale, nodata_fill}, frame) {}

DemSampler::DemSampler(const DemSpec& spec, const SceneFrame& frame)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  OpenedDem d = open_dem(spec);
  m.path = dem_text(spec.path, spec.more_paths);
  const std::string& path = m.path;
  m.z_scale = spec.z_scale;
  m.nodata_fill = spec.nodata_fill;
  m.origin_x = frame.origin_x;
  m.origin_y = frame.origin_y;
  m.tiles = std::move(d.tiles);
  m.ds = std::move(d.ds);
  std::copy(d.gt, d.gt + 6, m.gt);
  m.dem_srs = d.srs;
  m.band = m.ds->GetRasterBand(1);
  m.width = m.ds->GetRasterXSize();
  m.height = m.ds->GetRasterYSize();
  if (!GDALInvGeoTransform(m.gt, m.inv_gt))
    fail<gdal_error>(kDemStage, path + ": DEM geotransform is not invertible");
  int ok = 0;
  m.scale = m.band->GetScale(&ok);
  if (!ok) m.scale = 1;
  m.offset = m.band->GetOffset(&ok);
  if (!ok) m.offset = 0;
  const std::string unit = lower(m.band->GetUnitType() ? m.band->GetUnitType() : "");
  m.unit = metres_per_unit(unit);
  m.nodata = m.band->GetNoDataValue(&ok);
  m.has_nodata = ok != 0;

  if (!frame.crs_wkt.empty()) {
    if (m.scene_srs.importFromWkt(frame.crs_wkt.c_str()) != OGRERR_NONE)
      fail<gdal_error>(kDemStage, path + ": the scene CRS WKT cannot be read");
    m.scene_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    m.same_crs = m.scene_srs.IsSame(&m.dem_srs) != 0;
    (void)m.fwd();  // fail early when PROJ cannot make the transformation
  }
  std::ostringstream desc;
  desc << "DEM " << path << " (";
  if (!m.tiles.empty())
    desc << "VRT mosaic of " << m.tiles.size() << " " << m.tiles[0]->GetDriver()->GetDescription()
         << " rasters, ";
  else
    desc << m.ds->GetDriver()->GetDescription() << ", ";
  desc << m.width << "x" << m.height << ", CRS "
       << (m.dem_srs.GetName() ? m.dem_srs.GetName() : "none") << (d.assumed ? " (assumed)" : "")
       << (m.same_crs ? ", same as scene" : ", points transformed") << ", unit '" << unit << "' x"
       << m.unit << ", scale " << m.scale << ", offset " << m.offset << ", z-scale " << spec.z_scale
       << ")";
  m.stats.description = desc.str();
  m.base_fill_policy = spec.nodata_fill ? "value " + std::to_string(*spec.nodata_fill)
                                        : std::string("nearest valid cell");
  m.stats.fill_policy = m.base_fill_policy;
}

DemSampler::~DemSampler() = default;

void DemSampler::to_pixel(std::span<const Point2> scene, std::span<Point2> pixel) const {
  const Impl& m = *impl_;
  std::vector<double> xs(scene.size()), ys(scene.size());
  for (size_t i = 0; i < scene.size(); ++i) {
    xs[i] = scene[i].x + m.origin_x;
    ys[i] = scene[i].y + m.origin_y;
  }
  if (auto* t = m.fwd(); t && !scene.empty()) {
    std::vector<int> ok(scene.size(), 0);
    if (!t->Transform(static_cast<int>(scene.size()), xs.data(), ys.data(), nullptr, ok.data()))
      for (size_t i = 0; i < scene.size(); ++i)
        if (!ok[i])
          fail<gdal_error>(kDemStage, m.path + ": cannot transform scene point (" +
                                          std::to_string(scene[i].x) + ", " +
                                          std::to_string(scene[i].y) + ") to the DEM CRS");
  }
  for (size_t i = 0; i < scene.size(); ++i) {
    pixel[i].x = m.inv_gt[0] + m.inv_gt[1] * xs[i] + m.inv_gt[2] * ys[i];
    pixel[i].y = m.inv_gt[3] + m.inv_gt[4] * xs[i] + m.inv_gt[5] * ys[i];
  }
}

Point2 DemSampler::to_pixel(Point2 scene) const {
  Point2 out;
  to_pixel(std::span<const Point2>(&scene, 1), std::span<Point2>(&out, 1));
  return out;
}

double DemSampler::cell_size_metres(Point2 p) const {
  const Impl& m = *impl_;
  const Point2 c = to_pixel(p);
  // Scene positions of the cell's edge midpoints around c.
  double px[4] = {c.x - 0.5, c.x + 0.5, c.x, c.x};
  double py[4] = {c.y, c.y, c.y - 0.5, c.y + 0.5};
  double xs[4], ys[4];
  for (int i = 0; i < 4; ++i) {
    xs[i] = m.gt[0] + m.gt[1] * px[i] + m.gt[2] * py[i];
    ys[i] = m.gt[3] + m.gt[4] * px[i] + m.gt[5] * py[i];
  }
  if (auto* t = m.inv()) {
    int ok[4] = {0, 0, 0, 0};
    if (!t->Transform(4, xs, ys, nullptr, ok))
      fail<gdal_error>(kDemStage, m.path + ": cannot transform DEM cell corners to the scene CRS");
  }
  const double w = std::hypot(xs[1] - xs[0], ys[1] - ys[0]);
  const double h = std::hypot(xs[3] - xs[2], ys[3] - ys[2]);
  return std::min(w, h);
}

std::optional<DemLattice> DemSampler::lattice() const {
  const Impl& m = *impl_;
  if (!m.same_crs || m.gt[2] != 0 || m.gt[4] != 0) return std::nullopt;
  return DemLattice{m.gt[0] + 0.5 * m.gt[1] - m.origin_x, m.gt[3] + 0.5 * m.gt[5] - m.origin_y,
                    m.gt[1], m.gt[5]};
}

void DemSampler::Impl::read_window(int x0, int y0, int x1, int y1) {
  wx0 = x0;
  wy0 = y0;
  ww = x1 - x0 + 1;
  wh = y1 - y0 + 1;
  const size_t n = static_cast<size_t>(ww) * wh;
  z.assign(n, 0.0);
  filled.assign(n, 0);
  if (band->RasterIO(GF_Read, x0, y0, ww, wh, z.data(), ww, wh, GDT_Float64, 0, 0, nullptr) !=
      CE_None)
    fail<gdal_error>(kDemStage, path + ": cannot read DEM window: " + CPLGetLastErrorMsg());
}

// No-data policy of prep/dem.hpp, on raw values of the window read. Returns
// whether every filled cell of the box [bx0, bx1] x [by0, by1] (absolute
// cells) found its nearest valid cell of the whole raster: its search
// distance d fits inside the window on every side that is not the raster's
// edge, so no nearer valid cell lies outside, and the whole search that
// decided it (cells within d) lies inside.
bool DemSampler::Impl::fill(int bx0, int by0, int bx1, int by1, uint64_t& invalid_count,
                            bool& none_valid) {
  const size_t n = z.size();
  std::deque<size_t> queue;
  for (size_t i = 0; i < n; ++i) {
    const bool invalid = std::isnan(z[i]) || (has_nodata && z[i] == nodata);
    if (invalid) {
      filled[i] = 1;
      if (nodata_fill) z[i] = *nodata_fill;
    } else {
      queue.push_back(i);
    }
  }
  invalid_count = static_cast<uint64_t>(std::count(filled.begin(), filled.end(), 1));
  none_valid = queue.empty();
  if (nodata_fill || invalid_count == 0) return true;
  const bool whole = wx0 == 0 && wy0 == 0 && wx0 + ww == width && wy0 + wh == height;
  if (none_valid) return whole;
  // Breadth-first search from the valid cells; level = Chebyshev distance.
  constexpr uint32_t kUnreached = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> level(n, kUnreached);
  for (size_t i : queue) level[i] = 0;
  while (!queue.empty()) {
    const size_t i = queue.front();
    queue.pop_front();
    const int ix = static_cast<int>(i % ww), iy = static_cast<int>(i / ww);
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int jx = ix + dx, jy = iy + dy;
        if (jx < 0 || jy < 0 || jx >= ww || jy >= wh) continue;
        const size_t j = static_cast<size_t>(jy) * ww + jx;
        if (level[j] != kUnreached) continue;
        level[j] = level[i] + 1;
        z[j] = z[i];
        queue.push_back(j);
      }
  }
  const int x_lo = std::max(bx0, wx0), x_hi = std::min(bx1, wx0 + ww - 1);
  const int y_lo = std::max(by0, wy0), y_hi = std::min(by1, wy0 + wh - 1);
  for (int j = y_lo; j <= y_hi; ++j)
    for (int i = x_lo; i <= x_hi; ++i) {
      const size_t k = static_cast<size_t>(j - wy0) * ww + (i - wx0);
      if (!filled[k]) continue;
      const int d = static_cast<int>(level[k]);
      if ((i - d < wx0 && wx0 > 0) || (i + d >= wx0 + ww && wx0 + ww < width) ||
          (j - d < wy0 && wy0 > 0) || (j + d >= wy0 + wh && wy0 + wh < height))
        return false;
    }
  return true;
}

void DemSampler::load(double px0, double py0, double px1, double py1) {
  Impl& m = *impl_;
  auto clampi = [](double v, int lo, int hi) {
    if (!(v > lo)) return lo;  // NaN too
    if (v > hi) return hi;
    return static_cast<int>(v);
  };
  // Cells a height() inside the box can weigh.
  const int bx0 = clampi(std::floor(px0) - 1, 0, m.width - 1),
            bx1 = clampi(std::ceil(px1) + 1, 0, m.width - 1);
  const int by0 = clampi(std::floor(py0) - 1, 0, m.height - 1),
            by1 = clampi(std::ceil(py1) + 1, 0, m.height - 1);
  uint64_t invalid_count = 0;
  bool none_valid = false, settled = false;
  for (int margin = kMargin;; margin *= 4) {
    const int x0 = clampi(std::floor(px0) - margin, 0, m.width - 1);
    const int x1 = clampi(std::ceil(px1) + margin, 0, m.width - 1);
    const int y0 = clampi(std::floor(py0) - margin, 0, m.height - 1);
    const int y1 = clampi(std::ceil(py1) + margin, 0, m.height - 1);
    m.read_window(x0, y0, x1, y1);
    settled = m.fill(bx0, by0, bx1, by1, invalid_count, none_valid);
    const bool whole = x0 == 0 && y0 == 0 && x1 == m.width - 1 && y1 == m.height - 1;
    if (settled || whole || margin >= kMaxFillMargin) break;
  }
  m.stats.fill_policy = m.base_fill_policy;
  if (!settled && !none_valid)
    m.stats.fill_policy += " (voids deeper than " + std::to_string(kMaxFillMargin) +
                           " cells: nearest within that reach)";
  const double k = m.unit * m.z_scale;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (auto& v : m.z) {
    // No valid cell within reach (and no nodata_fill): flat at 0 m.
    v = none_valid && !m.nodata_fill ? 0.0 : (v * m.scale + m.offset) * k;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  double twist = 0;
  for (int j = 0; j + 1 < m.wh; ++j)
    for (int i = 0; i + 1 < m.ww; ++i) {
      const size_t a = static_cast<size_t>(j) * m.ww + i;
      twist = std::max(twist, std::abs(m.z[a] - m.z[a + 1] - m.z[a + m.ww] + m.z[a + m.ww + 1]));
    }
  m.max_twist = twist;
  m.stats.window_cells = m.z.size();
  m.stats.nodata_cells = invalid_count;
  m.stats.min = lo;
  m.stats.max = hi;
}

double DemSampler::height(double px, double py, bool* touched_fill) const {
  const Impl& m = *impl_;
  // GDAL bilinear: cell centres at i + 0.5; beyond the outermost centres
  // the kernel renormalises onto the edge cell, which equals clamping.
  const double fx = px - 0.5, fy = py - 0.5;
  const double flx = std::floor(fx), fly = std::floor(fy);
  const double tx = fx - flx, ty = fy - fly;
  auto cx = [&](double i) {
    return static_cast<int>(std::clamp(i, double(m.wx0), double(m.wx0 + m.ww - 1)));
  };
  auto cy = [&](double j) {
    return static_cast<int>(std::clamp(j, double(m.wy0), double(m.wy0 + m.wh - 1)));
  };
  const int i0 = cx(flx), i1 = cx(flx + 1), j0 = cy(fly), j1 = cy(fly + 1);
  const double a = m.cell(i0, j0), b = m.cell(i1, j0), c = m.cell(i0, j1), d = m.cell(i1, j1);
  if (touched_fill) {
    *touched_fill = ((1 - tx) * (1 - ty) > 0 && m.cell_filled(i0, j0)) ||
                    (tx * (1 - ty) > 0 && m.cell_filled(i1, j0)) ||
                    ((1 - tx) * ty > 0 && m.cell_filled(i0, j1)) ||
                    (tx * ty > 0 && m.cell_filled(i1, j1));
  }
  return (1 - ty) * ((1 - tx) * a + tx * b) + ty * ((1 - tx) * c + tx * d);
}

double DemSampler::max_twist() const {
  return impl_->max_twist;
}

bool DemSampler::outside(double px, double py) const {
  const Impl& m = *impl_;
  return !(px >= 0 && py >= 0 && px <= m.width && py <= m.height);
}

const TerrainStats& DemSampler::stats() const {
  return impl_->stats;
}

}  // namespace prep
