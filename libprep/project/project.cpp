// Stage 2 — project. FeatureSet in source CRSs -> FeatureSet in the scene
// frame, metres relative to the frame origin (DESIGN.md §1, §4.1).
#include "prep/project.hpp"

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/TransverseMercator.hpp>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <tbb/task_arena.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>

#include "prep/error.hpp"
#include "prep/feature_failure.hpp"

namespace prep {
namespace {

void register_gdal_once() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// Every SRS we hand to PROJ uses x = easting/longitude, whatever the
// authority says (ENV-NOTES: EPSG:4326 is lat,lon in authority order).
std::unique_ptr<OGRSpatialReference> srs_from(const std::string& text, const std::string& what) {
  auto srs = std::make_unique<OGRSpatialReference>();
  CPLErrorReset();
  if (text.empty() || srs->SetFromUserInput(text.c_str()) != OGRERR_NONE) {
    std::string msg = CPLGetLastErrorMsg();
    throw input_error("project: invalid " + what + " '" + text + "'" +
                      (msg.empty() ? std::string() : ": " + msg));
  }
  srs->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

std::unique_ptr<OGRSpatialReference> wgs84() {
  auto srs = std::make_unique<OGRSpatialReference>();
  srs->SetWellKnownGeogCS("WGS84");
  srs->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

struct TransformDeleter {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};
using TransformPtr = std::unique_ptr<OGRCoordinateTransformation, TransformDeleter>;

TransformPtr make_transform(const OGRSpatialReference& from, const OGRSpatialReference& to,
                            const std::string& context) {
  CPLErrorReset();
  TransformPtr t(OGRCreateCoordinateTransformation(&from, &to));
  if (!t) {
    throw input_error("project: " + context + ": no transformation available: " +
                      CPLGetLastErrorMsg());
  }
  return t;
}

std::string to_wkt(const OGRSpatialReference& srs) {
  const char* opts[] = {"FORMAT=WKT2_2019", "MULTILINE=NO", nullptr};
  char* wkt = nullptr;
  srs.exportToWkt(&wkt, opts);
  std::string s = wkt ? wkt : "";
  CPLFree(wkt);
  return s;
}

Extent bounds_of(const SourceLayer& layer) {
  Extent e{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
           -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const SourceFeature& f : layer.features) {
    if (!f.drop_reason.empty()) continue;
    for (const Ring& r : f.rings) {
      for (const Point2& p : r) {
        e.xmin = std::min(e.xmin, p.x);
        e.ymin = std::min(e.ymin, p.y);
        e.xmax = std::max(e.xmax, p.x);
        e.ymax = std::max(e.ymax, p.y);
      }
    }
  }
  return e;
}

// Transforms an extent with densified edges (GDAL's TransformBounds).
Extent transform_bounds(OGRCoordinateTransformation& t, const Extent& e, const std::string& what) {
  Extent out;
  if (!t.TransformBounds(e.xmin, e.ymin, e.xmax, e.ymax, &out.xmin, &out.ymin, &out.xmax,
                         &out.ymax, 21)) {
    throw input_error("project: " + what + ": extent cannot be transformed: " +
                      CPLGetLastErrorMsg());
  }
  return out;
}

const GeographicLib::TransverseMercator& tm_wgs84() {
  static const GeographicLib::TransverseMercator tm(GeographicLib::Constants::WGS84_a(),
                                                    GeographicLib::Constants::WGS84_f(), 1.0);
  return tm;
}

// Point scale factor for frames that are not our local TM: the frame
// distance covered by a 10 m geodesic step east, over 10 m (conformal
// frames have the same k in every direction).
class NumericScale {
 public:
  explicit NumericScale(const OGRSpatialReference& frame) {
    auto geo = wgs84();
    to_geo_ = make_transform(frame, *geo, "frame to WGS84");
    from_geo_ = make_transform(*geo, frame, "WGS84 to frame");
  }
  double at(double x, double y) const {
    double lon = x, lat = y;
    if (!to_geo_->Transform(1, &lon, &lat)) return std::numeric_limits<double>::quiet_NaN();
    double lat2 = 0, lon2 = 0;
    GeographicLib::Geodesic::WGS84().Direct(lat, lon, 90.0, 10.0, lat2, lon2);
    double xs[2] = {lon, lon2}, ys[2] = {lat, lat2};
    if (!from_geo_->Transform(2, xs, ys)) return std::numeric_limits<double>::quiet_NaN();
    return std::hypot(xs[1] - xs[0], ys[1] - ys[0]) / 10.0;
  }

 private:
  TransformPtr to_geo_, from_geo_;
};

// What to do when a vertex falls out of the frame projection's domain.
std::string frame_hint(const SceneFrame& frame) {
  const bool named = !frame.description.empty() && frame.description != "unknown";
  return " (out of the domain of " + (named ? frame.description : std::string("the --crs projection")) +
         "; pass --crs with a projection valid for this area, or leave the feature out with "
         "--extent or --where)";
}

}  // namespace

double frame_scale_factor(const SceneFrame& frame, double x, double y) {
  if (std::isfinite(frame.tm_lon0)) {
    // Local TM: GeographicLib gives k directly. Its northing counts from the
    // equator; the frame's from lat0.
    double x0 = 0, y0 = 0, lat = 0, lon = 0, gamma = 0, k = 1;
    tm_wgs84().Forward(frame.tm_lon0, frame.tm_lat0, frame.tm_lon0, x0, y0);
    tm_wgs84().Reverse(frame.tm_lon0, x + frame.origin_x, y + frame.origin_y + y0, lat, lon,
                       gamma, k);
    return k;
  }
  register_gdal_once();
  auto srs = srs_from(frame.crs_wkt, "frame CRS");
  return NumericScale(*srs).at(x + frame.origin_x, y + frame.origin_y);
}

SceneFrame choose_frame(const FeatureSet& features, const std::string& crs) {
  register_gdal_once();
  // The data's geographic extent, over every layer.
  auto geo = wgs84();
  Extent all{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
             -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const SourceLayer& layer : features.layers) {
    Extent e = bounds_of(layer);
    // A single horizontal or vertical line has a zero-height (or zero-width)
    // box; only a layer without any vertex is skipped.
    if (!(e.xmax >= e.xmin && e.ymax >= e.ymin)) continue;
    auto src = srs_from(layer.srs_wkt, "source CRS");
    auto t = make_transform(*src, *geo, "layer '" + layer.spec.name + "' to WGS84");
    Extent g = transform_bounds(*t, e, "layer '" + layer.spec.name + "'");
    all.xmin = std::min(all.xmin, g.xmin);
    all.ymin = std::min(all.ymin, g.ymin);
    all.xmax = std::max(all.xmax, g.xmax);
    all.ymax = std::max(all.ymax, g.ymax);
  }
  if (!(all.xmax >= all.xmin)) {
    throw input_error("project: no features to centre the scene frame on (every layer is empty)");
  }
  // More than 180 degrees of longitude away from the poles is, for local
  // data, a line or ring that crosses the antimeridian in a geographic CRS
  // (179.9 -> -179.9 read the long way round): the local TM frame would put
  // it around the globe. Say what to do instead of failing later on the
  // int32 range (or worse). Near a pole, a wide longitude range is normal and
  // the TM frame holds it.
  const bool polar = all.ymin > 60.0 || all.ymax < -60.0;
  if (crs.empty() && all.xmax - all.xmin > 180.0 && !polar) {
    char msg[512];
    std::snprintf(msg, sizeof msg,
                  "project: the data spans %.10g..%.10g degrees of longitude (more than 180: "
                  "it crosses the antimeridian in a geographic CRS, or is not local); the "
                  "default local TM frame cannot hold it. Pass --crs with a projected CRS "
                  "for the area (e.g. EPSG:3832 across the Pacific, EPSG:3413 or EPSG:3031 "
                  "at the poles), or split the scene",
                  all.xmin, all.xmax);
    throw input_error(msg);
  }
  // Rounded to 1e-7 degrees (~1 cm) so the frame definition prints exactly.
  const double lon0 = std::round((all.xmin + all.xmax) * 0.5 * 1e7) / 1e7;
  const double lat0 = std::round((all.ymin + all.ymax) * 0.5 * 1e7) / 1e7;

  SceneFrame frame;
  if (crs.empty()) {
    char def[256];
    std::snprintf(def, sizeof def,
                  "+proj=tmerc +lat_0=%.7f +lon_0=%.7f +k=1 +x_0=0 +y_0=0 +datum=WGS84 "
                  "+units=m +no_defs +type=crs",
                  lat0, lon0);
    auto srs = srs_from(def, "local TM frame");
    frame.crs_wkt = to_wkt(*srs);
    std::snprintf(def, sizeof def, "local TM lon0=%.7f lat0=%.7f (WGS84, k0=1)", lon0, lat0);
    frame.description = def;
    frame.tm_lon0 = lon0;
    frame.tm_lat0 = lat0;
    return frame;
  }
  auto srs = srs_from(crs, "--crs");
  if (!srs->IsProjected()) {
    throw input_error("project: --crs '" + crs + "' is not a projected CRS; the scene frame "
                      "needs metres (try a UTM zone or leave --crs out for a local TM)");
  }
  frame.crs_wkt = to_wkt(*srs);
  const char* name = srs->GetName();
  frame.description = name ? name : crs;
  // The origin is the centre of the data's vertices transformed into --crs
  // (up to ~4096 per layer), not the transformed centre of the geographic
  // box: for data across the antimeridian that box is the whole globe and
  // its centre (lon 0) lies half a world away from the data.
  Extent fe{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const SourceLayer& layer : features.layers) {
    std::vector<double> xs, ys;
    size_t total = 0;
    for (const SourceFeature& f : layer.features)
      if (f.drop_reason.empty())
        for (const Ring& r : f.rings) total += r.size();
    if (total == 0) continue;
    const size_t stride = std::max<size_t>(1, total / 4096);
    size_t i = 0;
    for (const SourceFeature& f : layer.features) {
      if (!f.drop_reason.empty()) continue;
      for (const Ring& r : f.rings)
        for (const Point2& p : r)
          if (i++ % stride == 0) xs.push_back(p.x), ys.push_back(p.y);
    }
    auto src = srs_from(layer.srs_wkt, "source CRS");
    auto lt = make_transform(*src, *srs, "layer '" + layer.spec.name + "' to --crs");
    std::vector<int> ok(xs.size(), 0);
    lt->Transform(static_cast<int>(xs.size()), xs.data(), ys.data(), nullptr, ok.data());
    for (size_t k = 0; k < xs.size(); ++k) {
      if (!ok[k] || !std::isfinite(xs[k]) || !std::isfinite(ys[k])) continue;
      fe.xmin = std::min(fe.xmin, xs[k]);
      fe.ymin = std::min(fe.ymin, ys[k]);
      fe.xmax = std::max(fe.xmax, xs[k]);
      fe.ymax = std::max(fe.ymax, ys[k]);
    }
  }
  double x = (fe.xmin + fe.xmax) * 0.5, y = (fe.ymin + fe.ymax) * 0.5;
  if (!(fe.xmax >= fe.xmin)) {
    auto t = make_transform(*geo, *srs, "WGS84 to --crs");
    x = lon0, y = lat0;
    if (!t->Transform(1, &x, &y)) {
      throw input_error("project: the data centre cannot be expressed in --crs '" + crs + "'");
    }
  }
  frame.origin_x = std::round(x);
  frame.origin_y = std::round(y);
  return frame;
}

ProjectedFeatures project(FeatureSet features, const SceneFrame& frame, const SceneSpec& scene) {
  register_gdal_once();
  ProjectedFeatures out;
  out.frame = frame;
  auto frame_srs = srs_from(frame.crs_wkt, "frame CRS");
  const bool local_tm = std::isfinite(frame.tm_lon0);

  for (SourceLayer& layer : features.layers) {
    auto src = srs_from(layer.srs_wkt, "source CRS of layer '" + layer.spec.name + "'");
    const std::string ctx = "layer '" + layer.spec.name + "' to the scene frame";
    // OGRCoordinateTransformation is not thread-safe: one per worker slot,
    // cloned here on one thread (a clone skips PROJ's database search).
    TransformPtr first = make_transform(*src, *frame_srs, ctx);
    const int slots = tbb::this_task_arena::max_concurrency();
    std::vector<TransformPtr> transforms;
    transforms.push_back(std::move(first));
    for (int i = 1; i < slots; ++i) {
      TransformPtr c(transforms[0]->Clone());
      if (!c) c = make_transform(*src, *frame_srs, ctx);
      transforms.push_back(std::move(c));
    }
    std::vector<std::unique_ptr<NumericScale>> scales(slots);
    if (!local_tm)
      for (auto& sc : scales) sc = std::make_unique<NumericScale>(*frame_srs);
    std::vector<double>& k = out.scale.emplace_back(layer.features.size(), 1.0);

    tbb::parallel_for(tbb::blocked_range<size_t>(0, layer.features.size(), 64),
                      [&](const tbb::blocked_range<size_t>& range) {
      const int slot = tbb::this_task_arena::current_thread_index();
      OGRCoordinateTransformation& t = *transforms[static_cast<size_t>(slot)];
      std::vector<double> xs, ys;
      std::vector<int> ok;
      for (size_t i = range.begin(); i != range.end(); ++i) {
        SourceFeature& f = layer.features[i];
        if (!f.drop_reason.empty()) continue;
        double cx = 0, cy = 0;
        size_t n_all = 0;
        for (Ring& r : f.rings) {
          const size_t n = r.size();
          xs.resize(n);
          ys.resize(n);
          ok.assign(n, 0);
          for (size_t j = 0; j < n; ++j) {
            xs[j] = r[j].x;
            ys[j] = r[j].y;
          }
          if (n > 0 && !t.Transform(static_cast<int>(n), xs.data(), ys.data(), nullptr, ok.data())) {
            for (size_t j = 0; j < n; ++j) {
              if (!ok[j]) {
                // Out of the projection's domain (PROJ error or HUGE_VAL).
                f.drop_reason = failure_reason(
                    "project", "vertex " + std::to_string(j) + " (" + std::to_string(r[j].x) +
                                   ", " + std::to_string(r[j].y) +
                                   ") cannot be transformed into the scene frame" +
                                   frame_hint(frame));
                break;
              }
            }
            if (f.drop_reason.empty())
              f.drop_reason = failure_reason("project", "transformation into the scene frame failed");
            break;
          }
          for (size_t j = 0; j < n; ++j) {
            const Point2 source = r[j];
            r[j].x = xs[j] - frame.origin_x;
            r[j].y = ys[j] - frame.origin_y;
            if ((!std::isfinite(r[j].x) || !std::isfinite(r[j].y)) && f.drop_reason.empty()) {
              f.drop_reason = failure_reason(
                  "project", "vertex " + std::to_string(j) + " (" + std::to_string(source.x) +
                                 ", " + std::to_string(source.y) +
                                 ") is not finite in the scene frame" + frame_hint(frame));
            }
            cx += r[j].x;
            cy += r[j].y;
          }
          n_all += n;
        }
        if (!f.drop_reason.empty()) {
          f.rings.clear();
          continue;
        }
        if (n_all == 0) continue;
        cx /= double(n_all);
        cy /= double(n_all);
        // Scale factor at the part's vertex centroid: widths are ground
        // metres, the frame is not (DESIGN.md §1.2).
        k[i] = local_tm ? frame_scale_factor(frame, cx, cy)
                        : scales[static_cast<size_t>(slot)]->at(cx + frame.origin_x, cy + frame.origin_y);
        if (!std::isfinite(k[i])) k[i] = 1.0;
      }
    });
    // Without skip_failures the first failing feature in input order stops
    // the build (the loop above runs in any order).
    if (!scene.skip_failures) {
      for (const SourceFeature& f : layer.features)
        if (is_failure_reason(f.drop_reason))
          throw feature_failure_error("project", layer.spec.source, layer.spec.name, f.fid,
                                      f.drop_reason);
    }
    layer.srs_wkt = frame.crs_wkt;
  }

  // The clip extent: --extent, else the DEM's extent.
  if (scene.extent) {
    Extent e = *scene.extent;
    if (!scene.extent_crs.empty()) {
      auto ext_srs = srs_from(scene.extent_crs, "--extent-crs");
      auto t = make_transform(*ext_srs, *frame_srs, "--extent-crs to the scene frame");
      e = transform_bounds(*t, e, "--extent");
    }
    e.xmin -= frame.origin_x;
    e.xmax -= frame.origin_x;
    e.ymin -= frame.origin_y;
    e.ymax -= frame.origin_y;
    out.clip = e;
  } else if (!scene.dem.empty()) {
    CPLErrorReset();
    std::unique_ptr<GDALDataset> dem(
        GDALDataset::Open(scene.dem.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    if (!dem) {
      throw gdal_error("project: DEM " + scene.dem + ": cannot open: " + CPLGetLastErrorMsg());
    }
    double gt[6];
    if (dem->GetGeoTransform(gt) != CE_None) {
      throw input_error("project: DEM " + scene.dem + ": has no geotransform");
    }
    const OGRSpatialReference* dem_srs = dem->GetSpatialRef();
    if (!dem_srs) throw input_error("project: DEM " + scene.dem + ": has no CRS");
    OGRSpatialReference dsrs(*dem_srs);
    dsrs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    const double w = dem->GetRasterXSize(), h = dem->GetRasterYSize();
    Extent de{std::min(gt[0], gt[0] + w * gt[1] + h * gt[2]),
              std::min(gt[3], gt[3] + w * gt[4] + h * gt[5]),
              std::max(gt[0], gt[0] + w * gt[1] + h * gt[2]),
              std::max(gt[3], gt[3] + w * gt[4] + h * gt[5])};
    auto t = make_transform(dsrs, *frame_srs, "DEM to the scene frame");
    Extent e = transform_bounds(*t, de, "DEM " + scene.dem);
    e.xmin -= frame.origin_x;
    e.xmax -= frame.origin_x;
    e.ymin -= frame.origin_y;
    e.ymax -= frame.origin_y;
    out.clip = e;
  }
  out.features = std::move(features);
  return out;
}

}  // namespace prep
