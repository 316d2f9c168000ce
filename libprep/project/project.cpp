// Stage 2 — project. FeatureSet in source CRSs -> FeatureSet in the scene
// frame, metres relative to the frame origin (ARCHITECTURE.md "2. project", "Precision").
#include "prep/project.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/TransverseMercator.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gdal_util.hpp"
#include "prep/dem.hpp"
#include "prep/error.hpp"
#include "prep/feature_failure.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

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
    fail<input_error>(kProjectStage, "invalid " + what + " '" + text + "'" +
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
  void operator()(OGRCoordinateTransformation* t) const {
    OGRCoordinateTransformation::DestroyCT(t);
  }
};
using TransformPtr = std::unique_ptr<OGRCoordinateTransformation, TransformDeleter>;

TransformPtr make_transform(const OGRSpatialReference& from, const OGRSpatialReference& to,
                            const std::string& context) {
  CPLErrorReset();
  TransformPtr t(OGRCreateCoordinateTransformation(&from, &to));
  if (!t) {
    fail<input_error>(kProjectStage,
                      context + ": no transformation available: " + CPLGetLastErrorMsg());
  }
  return t;
}

// The box of a layer's vertices (dropped features left out).
Extent bounds_of(const FeatureSource& features, size_t layer) {
  Extent e = no_points();
  features.for_each(layer, [&](const SourceFeature& f) {
    if (!f.drop_reason.empty()) return;
    for (const Ring& r : f.rings) extend(e, r);
  });
  return e;
}

// A FeatureSet as a FeatureSource.
class SetSource final : public FeatureSource {
 public:
  explicit SetSource(const FeatureSet& set) : set_(set) {}
  size_t layer_count() const override { return set_.layers.size(); }
  const LayerSpec& spec(size_t layer) const override { return set_.layers[layer].spec; }
  const std::string& srs_wkt(size_t layer) const override { return set_.layers[layer].srs_wkt; }
  void for_each(size_t layer,
                const std::function<void(const SourceFeature&)>& visit) const override {
    for (const SourceFeature& f : set_.layers[layer].features) visit(f);
  }

 private:
  const FeatureSet& set_;
};

// Transforms an extent with densified edges (GDAL's TransformBounds).
Extent transform_bounds(OGRCoordinateTransformation& t, const Extent& e, const std::string& what) {
  Extent out;
  if (!t.TransformBounds(e.xmin, e.ymin, e.xmax, e.ymax, &out.xmin, &out.ymin, &out.xmax, &out.ymax,
                         21)) {
    fail<input_error>(kProjectStage,
                      what + ": extent cannot be transformed: " + CPLGetLastErrorMsg());
  }
  return out;
}

const GeographicLib::TransverseMercator& tm_wgs84() {
  static const GeographicLib::TransverseMercator tm(GeographicLib::Constants::WGS84_a(),
                                                    GeographicLib::Constants::WGS84_f(), 1.0);
  return tm;
}

// Point scale factor for frames that are not our local TM, from geodesic
// steps of a few metres (GeographicLib) carried through the frame (PROJ).
// Conformal frames (the --crs default assumption, and the default frame's
// oblique stereographic) have the same k in every direction: the frame
// distance covered by a 10 m geodesic step east, over 10 m. An equal-area
// frame (Equal Earth, Lambert azimuthal, Albers, ...) stretches one direction
// and shrinks the other: a line across it is `w det(J) / |J t|` frame metres
// wide for a ground width w and direction t (J: the frame's Jacobian in ground
// metres), which ranges over [b, a], the semi-axes of Tissot's indicatrix.
// One factor per part is their geometric mean sqrt(a b) = sqrt(|det J|) (the
// square root of the areal scale: 1 on an equal-area frame), so no direction
// is off by more than sqrt(a / b). It is taken from central differences of
// +-5 m east and north.
class NumericScale {
 public:
  NumericScale(const OGRSpatialReference& frame, bool equal_area) : equal_area_(equal_area) {
    auto geo = wgs84();
    to_geo_ = make_transform(frame, *geo, "frame to WGS84");
    from_geo_ = make_transform(*geo, frame, "WGS84 to frame");
  }
  double at(double x, double y) const {
    double lon = x, lat = y;
    if (!to_geo_->Transform(1, &lon, &lat)) return std::numeric_limits<double>::quiet_NaN();
    const GeographicLib::Geodesic& g = GeographicLib::Geodesic::WGS84();
    if (equal_area_) {
      constexpr double kStep = 5.0;  // metres each way
      double xs[4] = {}, ys[4] = {};
      const double azimuths[4] = {90.0, -90.0, 0.0, 180.0};
      for (int i = 0; i < 4; ++i) g.Direct(lat, lon, azimuths[i], kStep, ys[i], xs[i]);
      if (!from_geo_->Transform(4, xs, ys)) return std::numeric_limits<double>::quiet_NaN();
      const double det = (xs[0] - xs[1]) * (ys[2] - ys[3]) - (ys[0] - ys[1]) * (xs[2] - xs[3]);
      return std::sqrt(std::fabs(det)) / (2 * kStep);
    }
    double lat2 = 0, lon2 = 0;
    g.Direct(lat, lon, 90.0, 10.0, lat2, lon2);
    double xs[2] = {lon, lon2}, ys[2] = {lat, lat2};
    if (!from_geo_->Transform(2, xs, ys)) return std::numeric_limits<double>::quiet_NaN();
    return std::hypot(xs[1] - xs[0], ys[1] - ys[0]) / 10.0;
  }

 private:
  bool equal_area_;
  TransformPtr to_geo_, from_geo_;
};

// Whether `frame` is one of PROJ's equal-area projections, whose width
// factor is sqrt(|det J|) (NumericScale). Every other frame is taken as
// conformal (UTM, national TM and Lambert conformal grids, Mercator,
// stereographic: the CRSs --crs is meant for).
bool is_equal_area(const OGRSpatialReference& frame) {
  char* proj4 = nullptr;
  CPLErrorReset();
  const bool ok = frame.exportToProj4(&proj4) == OGRERR_NONE && proj4;
  const std::string def = ok ? proj4 : "";
  CPLFree(proj4);
  CPLErrorReset();
  static constexpr std::array<const char*, 15> kEqualArea = {
      "eqearth", "laea", "aea",   "cea",   "moll",  "sinu",   "eck4", "eck6",
      "hammer",  "igh",  "igh_o", "goode", "boggs", "mbtfps", "qsc"};
  return std::any_of(kEqualArea.begin(), kEqualArea.end(), [&](const char* method) {
    return def.find(std::string("+proj=") + method + " ") != std::string::npos;
  });
}

// ------------------------------------------------ verified approximation --
//
// PROJ's exact transverse Mercator (inverse for a UTM source, forward into
// the local frame) costs ~250 ns per vertex, four times what GDAL needs to
// read the vertex. The transformation is analytic over a scene, so it is
// replaced, cell by cell, by its degree-7 Chebyshev interpolant (the idea of
// GDAL's approximate transformer, with a polynomial instead of a straight
// line and a far tighter tolerance). A cell that misses kApproxTolerance at
// any point of its check grid is split in four; a cell still failing at
// kApproxMaxDepth (or where the exact transformation itself fails) keeps the
// exact per-vertex path. The cells depend on the data alone (extent,
// occupancy), never on timing, so the output stays identical at any thread
// count.
//
// Why the check grid bounds the error between its points. The error of the
// degree-n interpolant (at the (n+1)^2 Chebyshev nodes) of an analytic map is
// led by its Chebyshev terms of degree n+1, n+2, ..., which fall
// geometrically (Trefethen, "Approximation Theory and Approximation
// Practice", ch. 8 and 15). The check grid is the tensor product of the m+1
// extreme points cos(k pi / m), m = 2(n+1): corners, edges and centre
// included. By Ehlich and Zeller's discrete norm inequality, a polynomial of
// degree d < m in each variable is bounded over the whole cell by
// sec(d pi / 2m)^2 times its largest value on that grid: 2 for the leading
// error terms (d = n+1 = 8), 6.8 up to d = 12. The tolerance is 1e-8 m; the
// tests ask 1e-7 m per vertex against PROJ (tests/project/test_project.cpp),
// and measure at most 1.4e-8 m over a continent into Equal Earth.
// The grid's even points are the extreme points of degree n+1, where the
// leading error term peaks; they are checked first, so a cell that fails
// (most do, until they are small enough) pays for 1 + 64 + 81 exact
// transformations, not 1 + 64 + 289.
constexpr int kApproxDegree = 7;
constexpr int kApproxNodes = kApproxDegree + 1;
// A part of at least this many vertices is projected in parallel chunks
// (LayerProjection::Impl::project_in_parallel); smaller ones one per thread.
constexpr size_t kParallelPartVertices = 65536;
constexpr int kApproxCheckM = 2 * kApproxNodes;  // check points cos(k pi / m), k = 0..m
constexpr int kApproxCheck = kApproxCheckM + 1;  // per axis
constexpr double kApproxTolerance = 1e-8;        // frame metres
constexpr int kApproxMaxDepth = 12;
constexpr int kApproxOccupancy = 256;  // occupancy grid per axis
// A fit costs 146 to 354 exact transformations: a cell holding fewer
// vertices than this keeps the exact path (sparse or small data: the
// approximation would cost more than it saves).
constexpr uint64_t kApproxMinVertices = 1024;

class ApproxTransform {
 public:
  // `exact` maps source (x, y) to frame coordinates in place; `points` are
  // every source vertex, visited through `for_each(fn)`.
  template <class ForEachPoint>
  ApproxTransform(OGRCoordinateTransformation& exact, const Extent& box, ForEachPoint&& for_each)
      : exact_(exact) {
    double w = box.xmax - box.xmin, h = box.ymax - box.ymin;
    // A degenerate box (one point, an axis-parallel line) still gets an area.
    const double pad_x = w > 0 ? 0 : 1e-9 * std::max(1.0, std::fabs(box.xmin));
    const double pad_y = h > 0 ? 0 : 1e-9 * std::max(1.0, std::fabs(box.ymin));
    root_ = {box.xmin - pad_x, box.ymin - pad_y, box.xmax + pad_x, box.ymax + pad_y};
    // Vertex counts (summed-area table): cells with few vertices are never
    // fitted.
    const int g = kApproxOccupancy;
    sat_.assign(size_t(g + 1) * (g + 1), 0);
    const double sx = g / (root_.xmax - root_.xmin), sy = g / (root_.ymax - root_.ymin);
    for_each([&](double x, double y) {
      const int i = std::clamp(static_cast<int>((x - root_.xmin) * sx), 0, g - 1);
      const int j = std::clamp(static_cast<int>((y - root_.ymin) * sy), 0, g - 1);
      ++sat_[size_t(j + 1) * (g + 1) + size_t(i + 1)];
    });
    for (int j = 1; j <= g; ++j)
      for (int i = 1; i <= g; ++i)
        sat_[size_t(j) * (g + 1) + i] += sat_[size_t(j - 1) * (g + 1) + i] +
                                         sat_[size_t(j) * (g + 1) + i - 1] -
                                         sat_[size_t(j - 1) * (g + 1) + i - 1];
    for (int k = 0; k < kApproxNodes; ++k) node_[k] = std::cos(M_PI * (k + 0.5) / kApproxNodes);
    for (int p = 0; p < kApproxNodes; ++p)
      for (int k = 0; k < kApproxNodes; ++k)
        basis_[p][k] = std::cos(M_PI * p * (k + 0.5) / kApproxNodes);
    for (int k = 0; k <= kApproxCheckM; ++k)
      check_[k] = 2 * k == kApproxCheckM ? 0.0 : std::cos(M_PI * k / kApproxCheckM);
    check_[0] = 1.0;
    check_[kApproxCheckM] = -1.0;
    // Monomial coefficients of the Chebyshev polynomials T_0..T_degree.
    for (auto& row : cheb_) row.fill(0);
    cheb_[0][0] = 1;
    cheb_[1][1] = 1;
    for (int n = 2; n < kApproxNodes; ++n)
      for (int m = 0; m < kApproxNodes; ++m)
        cheb_[n][m] = (m > 0 ? 2 * cheb_[n - 1][m - 1] : 0) - cheb_[n - 2][m];
    build(root_);
  }

  // Frame coordinates of source (x, y); false when (x, y) lies in a cell
  // that keeps the exact transformation (the caller then calls it).
  // `leaf` caches the cell of the previous vertex (-1: none); a vertex
  // strictly inside it (half-open, as the descent splits) skips the descent.
  bool apply(double& x, double& y, int& leaf) const {
    if (leaf >= 0) {
      const Node& node = nodes_[size_t(leaf)];
      if (x >= node.box.xmin && x < node.box.xmax && y >= node.box.ymin && y < node.box.ymax) {
        eval(fits_[size_t(node.fit)], x, y);
        return true;
      }
    }
    if (!(x >= root_.xmin && x <= root_.xmax && y >= root_.ymin && y <= root_.ymax)) return false;
    int n = 0;
    for (;;) {
      const Node& node = nodes_[size_t(n)];
      if (node.child < 0) {
        if (node.fit < 0) return false;
        leaf = n;
        eval(fits_[size_t(node.fit)], x, y);
        return true;
      }
      const double mx = 0.5 * (node.box.xmin + node.box.xmax);
      const double my = 0.5 * (node.box.ymin + node.box.ymax);
      n = node.child + (x >= mx ? 1 : 0) + (y >= my ? 2 : 0);
    }
  }

  size_t cells() const { return fits_.size(); }

 private:
  struct Fit {
    double cx, cy, ix, iy;  // cell centre and 1 / half size (source units)
    double fx, fy;          // exact value at the centre
    double ax[kApproxNodes][kApproxNodes], ay[kApproxNodes][kApproxNodes];  // [i][j]: u^i v^j
  };
  struct Node {
    Extent box;
    int child = -1;  // index of the first of four children (SW, SE, NW, NE)
    int fit = -1;    // leaf: index into fits_, or -1 for exact
  };

  static void eval(const Fit& f, double& x, double& y) {
    const double u = (x - f.cx) * f.ix, v = (y - f.cy) * f.iy;
    double px = 0, py = 0;
    for (int i = kApproxDegree; i >= 0; --i) {
      double rx = f.ax[i][kApproxDegree], ry = f.ay[i][kApproxDegree];
      for (int j = kApproxDegree - 1; j >= 0; --j) {
        rx = rx * v + f.ax[i][j];
        ry = ry * v + f.ay[i][j];
      }
      px = px * u + rx;
      py = py * u + ry;
    }
    x = f.fx + px;
    y = f.fy + py;
  }

  // Vertices in the cell, counted on the occupancy grid: an upper bound for
  // a cell smaller than a grid cell (it counts the grid cells it touches).
  uint64_t vertices_in(const Extent& b) const {
    const int g = kApproxOccupancy;
    const double sx = g / (root_.xmax - root_.xmin), sy = g / (root_.ymax - root_.ymin);
    const int i0 = std::clamp(static_cast<int>(std::floor((b.xmin - root_.xmin) * sx)), 0, g);
    const int j0 = std::clamp(static_cast<int>(std::floor((b.ymin - root_.ymin) * sy)), 0, g);
    const int i1 =
        std::clamp(std::max(i0 + 1, static_cast<int>(std::ceil((b.xmax - root_.xmin) * sx))), 0, g);
    const int j1 =
        std::clamp(std::max(j0 + 1, static_cast<int>(std::ceil((b.ymax - root_.ymin) * sy))), 0, g);
    if (i1 <= i0 || j1 <= j0) return 0;
    const auto at = [&](int i, int j) { return sat_[size_t(j) * (g + 1) + size_t(i)]; };
    return at(i1, j1) - at(i0, j1) - at(i1, j0) + at(i0, j0);
  }

  // Exact frame coordinates of the points (xs, ys), in place; false when
  // any fails or is not finite.
  bool exact_all(std::vector<double>& xs, std::vector<double>& ys) const {
    std::vector<int> ok(xs.size(), 0);
    CPLErrorReset();
    exact_.Transform(static_cast<int>(xs.size()), xs.data(), ys.data(), nullptr, ok.data());
    for (size_t k = 0; k < xs.size(); ++k)
      if (!ok[k] || !std::isfinite(xs[k]) || !std::isfinite(ys[k])) return false;
    return true;
  }

  // Whether the fit `f` is within kApproxTolerance of the exact map at the
  // check points of `b` whose indices (i, j) have the parity `even` (true:
  // both even) or not (false: the rest).
  bool checked(const Extent& b, const Fit& f, bool even) const {
    // The edges and the centre exactly, as the descent splits the cells.
    const auto at = [](double t, double lo, double mid, double hi) {
      return t == -1.0 ? lo : t == 1.0 ? hi : mid + (t < 0 ? mid - lo : hi - mid) * t;
    };
    std::vector<double> xs, ys;
    for (int i = 0; i <= kApproxCheckM; ++i)
      for (int j = 0; j <= kApproxCheckM; ++j) {
        if ((i % 2 == 0 && j % 2 == 0) != even) continue;
        xs.push_back(at(check_[i], b.xmin, f.cx, b.xmax));
        ys.push_back(at(check_[j], b.ymin, f.cy, b.ymax));
      }
    const std::vector<double> x_in = xs, y_in = ys;
    if (!exact_all(xs, ys)) return false;
    for (size_t k = 0; k < xs.size(); ++k) {
      double x = x_in[k], y = y_in[k];
      eval(f, x, y);
      if (!(std::fabs(x - xs[k]) <= kApproxTolerance && std::fabs(y - ys[k]) <= kApproxTolerance))
        return false;
    }
    return true;
  }

  bool fit(const Extent& b, Fit& f) const {
    f.cx = 0.5 * (b.xmin + b.xmax);
    f.cy = 0.5 * (b.ymin + b.ymax);
    const double hx = 0.5 * (b.xmax - b.xmin), hy = 0.5 * (b.ymax - b.ymin);
    if (!(hx > 0) || !(hy > 0)) return false;
    f.ix = 1.0 / hx;
    f.iy = 1.0 / hy;
    // One exact call: the centre, then the Chebyshev nodes.
    constexpr int kN = kApproxNodes * kApproxNodes;
    std::vector<double> xs(1 + kN), ys(1 + kN);
    xs[0] = f.cx;
    ys[0] = f.cy;
    for (int i = 0; i < kApproxNodes; ++i)
      for (int j = 0; j < kApproxNodes; ++j) {
        xs[size_t(1 + i * kApproxNodes + j)] = f.cx + hx * node_[i];
        ys[size_t(1 + i * kApproxNodes + j)] = f.cy + hy * node_[j];
      }
    if (!exact_all(xs, ys)) return false;
    f.fx = xs[0];
    f.fy = ys[0];
    // Chebyshev coefficients by discrete orthogonality over the nodes.
    double c[2][kApproxNodes][kApproxNodes];
    for (int p = 0; p < kApproxNodes; ++p)
      for (int q = 0; q < kApproxNodes; ++q) {
        double sx = 0, sy = 0;
        for (int i = 0; i < kApproxNodes; ++i)
          for (int j = 0; j < kApproxNodes; ++j) {
            const double t = basis_[p][i] * basis_[q][j];
            sx += (xs[size_t(1 + i * kApproxNodes + j)] - f.fx) * t;
            sy += (ys[size_t(1 + i * kApproxNodes + j)] - f.fy) * t;
          }
        const double w = (p ? 2.0 : 1.0) * (q ? 2.0 : 1.0) / kN;
        c[0][p][q] = sx * w;
        c[1][p][q] = sy * w;
      }
    // To monomials in u, v. The coefficients of T_7 reach 112, but a cell
    // passes only where the high terms are far below the tolerance, and the
    // check grid verifies the monomial form itself.
    for (int i = 0; i < kApproxNodes; ++i)
      for (int j = 0; j < kApproxNodes; ++j) {
        double ax = 0, ay = 0;
        for (int p = i; p < kApproxNodes; ++p)
          for (int q = j; q < kApproxNodes; ++q) {
            const double t = cheb_[p][i] * cheb_[q][j];
            if (t == 0) continue;
            ax += c[0][p][q] * t;
            ay += c[1][p][q] * t;
          }
        f.ax[i][j] = ax;
        f.ay[i][j] = ay;
      }
    return checked(b, f, /*even=*/true) && checked(b, f, /*even=*/false);
  }

  void build(const Extent& root) {
    nodes_.push_back(Node{root, -1, -1});
    subtree(0, 0);
  }

  void subtree(int at, int depth) {
    const Extent b = nodes_[size_t(at)].box;
    if (vertices_in(b) < kApproxMinVertices) return;  // exact
    Fit f;
    if (fit(b, f)) {
      fits_.push_back(f);
      nodes_[size_t(at)].fit = static_cast<int>(fits_.size() - 1);
      return;
    }
    if (depth >= kApproxMaxDepth) return;
    const double mx = 0.5 * (b.xmin + b.xmax), my = 0.5 * (b.ymin + b.ymax);
    const Extent kids[4] = {{b.xmin, b.ymin, mx, my},
                            {mx, b.ymin, b.xmax, my},
                            {b.xmin, my, mx, b.ymax},
                            {mx, my, b.xmax, b.ymax}};
    const int first = static_cast<int>(nodes_.size());
    nodes_[size_t(at)].child = first;
    for (const Extent& k : kids) nodes_.push_back(Node{k, -1, -1});
    for (int c = 0; c < 4; ++c) subtree(first + c, depth + 1);
  }

  OGRCoordinateTransformation& exact_;
  Extent root_{};
  std::vector<uint64_t> sat_;
  double node_[kApproxNodes] = {};
  double basis_[kApproxNodes][kApproxNodes] = {};  // T_p at node k
  double check_[kApproxCheck] = {};  // cos(k pi / m); exactly 1, 0, -1 at k = 0, m/2, m
  std::array<std::array<double, kApproxNodes>, kApproxNodes> cheb_{};
  std::vector<Node> nodes_;
  std::vector<Fit> fits_;
};
// The centre of the box of the data's vertices in `frame` (up to ~4096 per
// layer, every stride-th), or, when none transforms, of the geographic
// point (lon0, lat0); `what` names the frame in the error when neither can.
std::pair<double, double> data_centre_in(const FeatureSource& features,
                                         const OGRSpatialReference& frame, const std::string& what,
                                         double lon0, double lat0) {
  Extent fe{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (size_t li = 0; li < features.layer_count(); ++li) {
    std::vector<double> xs, ys;
    size_t total = 0;
    features.for_each(li, [&](const SourceFeature& f) {
      if (f.drop_reason.empty())
        for (const Ring& r : f.rings) total += r.size();
    });
    if (total == 0) continue;
    const size_t stride = std::max<size_t>(1, total / 4096);
    size_t i = 0;
    features.for_each(li, [&](const SourceFeature& f) {
      if (!f.drop_reason.empty()) return;
      for (const Ring& r : f.rings)
        for (const Point2& p : r)
          if (i++ % stride == 0) xs.push_back(p.x), ys.push_back(p.y);
    });
    auto src = srs_from(features.srs_wkt(li), "source CRS");
    auto lt = make_transform(*src, frame, "layer '" + features.spec(li).name + "' to " + what);
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
    auto t = make_transform(*wgs84(), frame, "WGS84 to " + what);
    x = lon0, y = lat0;
    if (!t->Transform(1, &x, &y)) {
      fail<input_error>(kProjectStage, "the data centre cannot be expressed in " + what);
    }
  }
  return {x, y};
}

// ------------------------------------------------------- the default frame --
//
// With no --crs the frame is the first of three that holds the data
// (docs/build.md "The scene frame", ARCHITECTURE.md "project"):
//
// 1. local TM: a transverse Mercator centred on the data, while the data
//    lies within kTmMaxEasting of its central meridian. There PROJ's tmerc
//    and GeographicLib's series (which gives the width factor) both keep
//    their full accuracy (a few nm; Karney 2011, "Transverse Mercator with
//    an accuracy of a few nanometers"), and the scale factor stays under
//    1.19 (k ~ cosh(x / R)). Every scene that fits this frame keeps the
//    frame it always had (same centre, same definition).
// 2. local oblique stereographic (EPSG method 9809), centred on the data
//    or on the nearer pole, while every point of the data's extent lies
//    within kStereoMaxAngle of the centre: conformal, so widths are exact
//    with one factor per part, and k = 1 / cos^2(c / 2) reaches 2 on the
//    hemisphere's rim (the projected area is at most twice the ground's);
//    beyond, k grows without bound towards the antipode.
// 3. Equal Earth (EPSG method 1078; EPSG:8857 when centred on Greenwich):
//    every point of the globe is finite (the poles are lines), so every
//    layer projects. Not conformal: the width factor is the geometric mean
//    sqrt(a b) of NumericScale, which is 1 on this equal-area projection.
//
// Longitudes are taken on the circle: the data's longitude arc is the
// complement of the largest run of longitudes that no vertex and no segment
// covers (a segment read the short way, as a frame centred on the data
// draws it, except one from -180 to +180, which goes all the way round), so
// a Pacific layer across the antimeridian (lon 177..-178) gets a frame
// centred near 180, and rings split at +-180 (RFC 7946) meet again there.
constexpr double kTmMaxEasting = 3.9e6;   // metres from the central meridian
constexpr double kStereoMaxAngle = 90.0;  // degrees from the centre
constexpr int kLonBins = 3600;            // 0.1 degree
constexpr double kLonBin = 360.0 / kLonBins;

// The data's longitudes as an arc [west, east] (east - west <= 360), or
// `full` when they cover the whole circle.
struct LonArc {
  bool full = false;
  double west = 0, east = 0;
};

// Longitude in [-180, 180).
double wrap180(double lon) {
  return lon - 360.0 * std::floor((lon + 180.0) / 360.0);
}

// A geographic CRS in degrees from Greenwich: x is the longitude itself.
bool is_lon_lat(const OGRSpatialReference& srs) {
  return srs.IsGeographic() && std::fabs(srs.GetAngularUnits() - M_PI / 180) < 1e-12 &&
         srs.GetPrimeMeridian() == 0.0;
}

LonArc data_longitudes(const FeatureSource& features) {
  // Coverage per bin as a difference array: +1 where an interval starts,
  // -1 after it ends (intervals wrap past +180 at most once).
  // The arc's ends are exact: an interval covering the first (last) covered
  // bin after (before) a gap starts (ends) in it, so each bin keeps the
  // least start and the greatest end of the intervals there.
  std::vector<int64_t> diff(kLonBins + 1, 0);
  std::vector<double> least_start(kLonBins, std::numeric_limits<double>::infinity());
  std::vector<double> greatest_end(kLonBins, -std::numeric_limits<double>::infinity());
  const auto bin = [](double lon) {
    return std::clamp(static_cast<int>(std::floor((lon + 180.0) / kLonBin)), 0, 2 * kLonBins - 1);
  };
  const auto cover = [&](double lo, double hi) {  // lo in [-180, 180), lo <= hi < lo + 360
    const int s = bin(lo), e = bin(hi);
    least_start[size_t(s % kLonBins)] = std::min(least_start[size_t(s % kLonBins)], lo);
    greatest_end[size_t(e % kLonBins)] =
        std::max(greatest_end[size_t(e % kLonBins)], e < kLonBins ? hi : hi - 360.0);
    ++diff[size_t(s)];
    if (e < kLonBins) {
      --diff[static_cast<size_t>(e) + 1];
    } else {
      --diff[kLonBins];
      ++diff[0];
      --diff[size_t(std::min(e - kLonBins + 1, kLonBins))];
    }
  };
  auto geo = wgs84();
  for (size_t li = 0; li < features.layer_count(); ++li) {
    auto src = srs_from(features.srs_wkt(li), "source CRS");
    // A geographic source in degrees from Greenwich is read as it is (a datum
    // shift of a few metres does not move the frame); any other goes through
    // PROJ.
    const bool lon_lat = is_lon_lat(*src);
    TransformPtr t;
    if (!lon_lat) t = make_transform(*src, *geo, "layer '" + features.spec(li).name + "' to WGS84");
    std::vector<double> xs, ys;
    std::vector<int> ok;
    features.for_each(li, [&](const SourceFeature& f) {
      if (!f.drop_reason.empty()) return;
      for (const Ring& r : f.rings) {
        xs.resize(r.size());
        ys.resize(r.size());
        ok.assign(r.size(), 1);
        for (size_t j = 0; j < r.size(); ++j) xs[j] = r[j].x, ys[j] = r[j].y;
        if (t && !r.empty())
          t->Transform(static_cast<int>(xs.size()), xs.data(), ys.data(), nullptr, ok.data());
        bool have_prev = false;
        double prev = 0, prev_raw = 0;
        for (size_t j = 0; j < r.size(); ++j) {
          if (!ok[j] || !std::isfinite(xs[j]) || !std::isfinite(ys[j])) {
            have_prev = false;
            continue;
          }
          const double lon = wrap180(xs[j]);
          if (!have_prev) {
            cover(lon, lon);
          } else if (std::fabs(xs[j] - prev_raw) >= 360.0) {
            // -180 to 180: the edge of a world box or a polar cap (RFC 7946
            // draws them so), all the way round.
            cover(-180.0, 180.0 - kLonBin * 0.5);
          } else {
            // The segment the short way round (an exact half circle: eastwards).
            const double d = std::remainder(lon - prev, 360.0);
            if (d >= 0) {
              cover(prev, prev + d);
            } else {
              cover(lon, lon - d);
            }
          }
          prev = lon;
          prev_raw = xs[j];
          have_prev = true;
        }
      }
    });
  }
  // The longest circular run of uncovered bins.
  std::vector<int64_t> covered(kLonBins);
  int64_t run = 0;
  for (int i = 0; i < kLonBins; ++i) covered[size_t(i)] = run += diff[size_t(i)];
  int best_start = -1, best_len = 0;
  for (int i = 0, len = 0; i < 2 * kLonBins; ++i) {
    if (covered[size_t(i % kLonBins)] == 0) {
      if (++len > best_len && len <= kLonBins) best_len = len, best_start = i - len + 1;
    } else {
      len = 0;
    }
  }
  LonArc arc;
  // No gap, or nothing covered (no vertex transformed): the whole circle.
  if (best_len == 0 || best_len == kLonBins) {
    arc.full = true;
    arc.west = -180.0;
    arc.east = 180.0;
    return arc;
  }
  // The arc runs from the gap's east end to its west end, eastwards.
  arc.west = least_start[size_t((best_start + best_len) % kLonBins)];
  arc.east = greatest_end[size_t((best_start + kLonBins - 1) % kLonBins)];
  if (arc.east < arc.west) arc.east += 360.0;
  return arc;
}

// Angular distance in degrees between two points (WGS84 geodesic, on
// GeographicLib's auxiliary sphere).
double arc_degrees(double lat1, double lon1, double lat2, double lon2) {
  double s12 = 0;
  return GeographicLib::Geodesic::WGS84().Inverse(lat1, lon1, lat2, lon2, s12);
}

// The largest angular distance from (lat_c, lon_c) to the box of longitudes
// [west, east] (east - west <= 360) and latitudes [south, north]: on the
// box's boundary, or 180 when the antipode lies inside it.
double max_angle_to_box(double lat_c, double lon_c, double west, double east, double south,
                        double north) {
  const double anti_lat = -lat_c, anti_lon = wrap180(lon_c + 180.0);
  const double rel = anti_lon - west - 360.0 * std::floor((anti_lon - west) / 360.0);
  if (anti_lat >= south && anti_lat <= north && rel <= east - west) return 180.0;
  constexpr int kSteps = 64;
  double worst = 0;
  for (int i = 0; i <= kSteps; ++i) {
    const double lon = west + (east - west) * i / kSteps;
    const double lat = south + (north - south) * i / kSteps;
    worst = std::max({worst, arc_degrees(lat_c, lon_c, south, lon),
                      arc_degrees(lat_c, lon_c, north, lon), arc_degrees(lat_c, lon_c, lat, west),
                      arc_degrees(lat_c, lon_c, lat, east)});
  }
  return worst;
}

SceneFrame default_frame(const FeatureSource& features, const Extent& all, bool wrapped,
                         double lat0) {
  const auto round7 = [](double deg) { return std::round(deg * 1e7) / 1e7; };
  // The longitude arc: the plain extent while it is at most a half circle
  // (then no shorter arc covers the data), else the coverage on the circle.
  LonArc arc;
  double lon0 = 0;
  if (!wrapped && all.xmax - all.xmin <= 180.0) {
    arc.west = all.xmin;
    arc.east = all.xmax;
    lon0 = round7((all.xmin + all.xmax) * 0.5);
  } else {
    arc = data_longitudes(features);
    lon0 = arc.full ? 0.0 : round7(wrap180((arc.west + arc.east) * 0.5));
    if (lon0 == -180.0) lon0 = 180.0;  // the antimeridian, written as +180
  }
  const double half = (arc.east - arc.west) * 0.5;
  SceneFrame frame;
  char def[256];

  // 1. Local TM: the easting is largest at the data's widest longitude from
  // the central meridian (at most 90: beyond, the TM folds back over the
  // pole), on the latitude nearest the equator.
  const double lat_near = std::clamp(0.0, all.ymin, all.ymax);
  const double dlon = std::min(half, 90.0);
  double easting = std::numeric_limits<double>::infinity();
  if (!(dlon >= 90.0 && lat_near == 0.0)) {
    double x = 0, y = 0;
    tm_wgs84().Forward(0.0, lat_near, dlon, x, y);
    easting = std::fabs(x);
  }
  if (easting <= kTmMaxEasting) {
    std::snprintf(def, sizeof def,
                  "+proj=tmerc +lat_0=%.7f +lon_0=%.7f +k=1 +x_0=0 +y_0=0 +datum=WGS84 "
                  "+units=m +no_defs +type=crs",
                  lat0, lon0);
    auto srs = srs_from(def, "local TM frame");
    frame.crs_wkt = crs_wkt2(*srs);
    std::snprintf(def, sizeof def, "local TM lon0=%.7f lat0=%.7f (WGS84, k0=1)", lon0, lat0);
    frame.description = def;
    frame.tm_lon0 = lon0;
    frame.tm_lat0 = lat0;
    return frame;
  }

  // 2. Local oblique stereographic, on the data's centre or a pole,
  // whichever is nearer to the farthest point of the extent.
  double s_lat = lat0, s_lon = lon0;
  double angle = max_angle_to_box(lat0, lon0, arc.west, arc.east, all.ymin, all.ymax);
  if (90.0 - all.ymin < angle) s_lat = 90.0, angle = 90.0 - all.ymin;
  if (90.0 + all.ymax < angle) s_lat = -90.0, angle = 90.0 + all.ymax;
  if (angle <= kStereoMaxAngle) {
    std::snprintf(def, sizeof def,
                  "+proj=sterea +lat_0=%.7f +lon_0=%.7f +k=1 +x_0=0 +y_0=0 +datum=WGS84 "
                  "+units=m +no_defs +type=crs",
                  s_lat, s_lon);
    auto srs = srs_from(def, "local stereographic frame");
    frame.crs_wkt = crs_wkt2(*srs);
    std::snprintf(def, sizeof def, "local oblique stereographic lon0=%.7f lat0=%.7f (WGS84, k0=1)",
                  s_lon, s_lat);
    frame.description = def;
    return frame;
  }

  // 3. Equal Earth, its cut (lon0 + 180) in the widest gap of the data's
  // longitudes; on Greenwich (EPSG:8857, cut at the antimeridian where
  // RFC 7946 splits rings) when the data covers every longitude.
  std::unique_ptr<OGRSpatialReference> srs;
  if (lon0 == 0.0) {
    srs = srs_from("EPSG:8857", "Equal Earth frame");
    frame.description = "Equal Earth lon0=0.0000000 (WGS84; EPSG:8857)";
  } else {
    std::snprintf(def, sizeof def,
                  "+proj=eqearth +lon_0=%.7f +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs "
                  "+type=crs",
                  lon0);
    srs = srs_from(def, "Equal Earth frame");
    std::snprintf(def, sizeof def, "Equal Earth lon0=%.7f (WGS84)", lon0);
    frame.description = def;
  }
  frame.crs_wkt = crs_wkt2(*srs);
  const auto [x, y] = data_centre_in(features, *srs, "the Equal Earth frame", lon0, lat0);
  frame.origin_x = std::round(x);
  frame.origin_y = std::round(y);
  return frame;
}

// The longitude of the frame's centre: the projection's central meridian
// (the local TM's, Equal Earth's lon0, a --crs's), or the frame origin's
// longitude when the projection names none (0 when it has no origin).
// The central meridian, not the origin: a world projection cuts the globe
// at central meridian + 180, where it puts -180 and +180 on opposite edges.
// Longitudes brought within 180 degrees of the origin instead (an origin at
// lon 0.13 in an Equal Earth frame on Greenwich) would move a ring's
// vertices at -180 to the +180 edge, across the whole map.
double frame_centre_lon(const SceneFrame& frame, const OGRSpatialReference& frame_srs) {
  if (std::isfinite(frame.tm_lon0)) return frame.tm_lon0;
  if (frame_srs.IsProjected()) {
    OGRErr err = OGRERR_NONE;
    const double cm = frame_srs.GetNormProjParm(SRS_PP_CENTRAL_MERIDIAN, NAN, &err);
    if (err == OGRERR_NONE && std::isfinite(cm)) return cm;
    const double lc = frame_srs.GetNormProjParm(SRS_PP_LONGITUDE_OF_CENTER, NAN, &err);
    if (err == OGRERR_NONE && std::isfinite(lc)) return lc;
  }
  auto t = make_transform(frame_srs, *wgs84(), "frame to WGS84");
  double x = frame.origin_x, y = frame.origin_y;
  if (!t->Transform(1, &x, &y) || !std::isfinite(x)) return 0.0;
  return x;
}

// What to do when a vertex falls out of the frame projection's domain.
std::string frame_hint(const SceneFrame& frame) {
  const bool named = !frame.description.empty() && frame.description != "unknown";
  return " (out of the domain of " +
         (named ? frame.description : std::string("the --crs projection")) +
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
    tm_wgs84().Reverse(frame.tm_lon0, x + frame.origin_x, y + frame.origin_y + y0, lat, lon, gamma,
                       k);
    return k;
  }
  register_gdal_once();
  auto srs = srs_from(frame.crs_wkt, "frame CRS");
  return NumericScale(*srs, is_equal_area(*srs)).at(x + frame.origin_x, y + frame.origin_y);
}

SceneFrame choose_frame(const FeatureSet& features, const std::string& crs) {
  return choose_frame(SetSource(features), crs);
}

SceneFrame choose_frame(const FeatureSource& features, const std::string& crs) {
  register_gdal_once();
  // The data's geographic extent, over every layer.
  auto geo = wgs84();
  Extent all{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
             -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  // A layer whose extent GDAL returns with xmin > xmax crosses the
  // antimeridian (a projected source: TransformBounds says so this way).
  bool wrapped = false;
  for (size_t li = 0; li < features.layer_count(); ++li) {
    const LayerSpec& spec = features.spec(li);
    Extent e = bounds_of(features, li);
    // A single horizontal or vertical line has a zero-height (or zero-width)
    // box; only a layer without any vertex is skipped.
    if (!(e.xmax >= e.xmin && e.ymax >= e.ymin)) continue;
    auto src = srs_from(features.srs_wkt(li), "source CRS");
    auto t = make_transform(*src, *geo, "layer '" + spec.name + "' to WGS84");
    Extent g = transform_bounds(*t, e, "layer '" + spec.name + "'");
    if (g.xmin > g.xmax) {
      wrapped = true;
      std::swap(g.xmin, g.xmax);
    }
    // The default frame is placed by the data's longitudes: one that is not
    // a longitude at all (beyond one and a half turns) is a layer in the
    // wrong CRS or a broken vertex, and no frame can be centred on it.
    if (crs.empty() && !(g.xmin >= -540.0 && g.xmax <= 540.0)) {
      char msg[512];
      std::snprintf(msg, sizeof msg,
                    ": longitudes %.10g..%.10g degrees are not longitudes (a vertex is broken, "
                    "or the layer's CRS is wrong); the default frame cannot be centred on them. "
                    "Fix the source or its CRS, or pass --crs",
                    g.xmin, g.xmax);
      fail<input_error>(kProjectStage, "layer '" + spec.name + "' (" + spec.source + ")" + msg);
    }
    all.xmin = std::min(all.xmin, g.xmin);
    all.ymin = std::min(all.ymin, g.ymin);
    all.xmax = std::max(all.xmax, g.xmax);
    all.ymax = std::max(all.ymax, g.ymax);
  }
  if (!(all.xmax >= all.xmin)) {
    std::string layers;
    for (size_t li = 0; li < features.layer_count(); ++li)
      layers += (layers.empty() ? "" : ", ") +
                ("'" + features.spec(li).name + "' (" + features.spec(li).source + ")");
    fail<input_error>(kProjectStage,
                      "no features to centre the scene frame on: every layer is empty "
                      "or has only dropped features: " +
                          layers + "; check the source, --layer and --where");
  }
  // Rounded to 1e-7 degrees (~1 cm) so the frame definition prints exactly.
  const auto round7 = [](double deg) { return std::round(deg * 1e7) / 1e7; };
  const double lat0 = round7((all.ymin + all.ymax) * 0.5);
  if (crs.empty()) return default_frame(features, all, wrapped, lat0);
  const double lon0 = round7((all.xmin + all.xmax) * 0.5);
  auto srs = srs_from(crs, "--crs");
  if (!srs->IsProjected()) {
    fail<input_error>(kProjectStage,
                      "--crs '" + crs +
                          "' is not a projected CRS; the scene frame "
                          "needs metres (try a UTM zone or leave --crs out for a local TM)");
  }
  SceneFrame frame;
  frame.crs_wkt = crs_wkt2(*srs);
  const char* name = srs->GetName();
  frame.description = name ? name : crs;
  // The origin is the centre of the data's vertices transformed into --crs
  // (data_centre_in), not the transformed centre of the geographic box: for
  // data across the antimeridian that box is the whole globe and its centre
  // (lon 0) lies half a world away from the data.
  const auto [x, y] = data_centre_in(features, *srs, "--crs '" + crs + "'", lon0, lat0);
  frame.origin_x = std::round(x);
  frame.origin_y = std::round(y);
  return frame;
}

struct LayerProjection::Impl {
  SceneFrame frame_;
  const SceneSpec& scene_;
  LayerSpec spec_;
  std::unique_ptr<OGRSpatialReference> frame_srs_, src_;
  bool local_tm = false, equal_area = false, identity = false, rewrap = false;
  double tm_x0 = 0, tm_y0 = 0, centre = 0;
  std::string ctx;
  TransformPtr exact;
  std::vector<TransformPtr> transforms;
  std::vector<std::unique_ptr<NumericScale>> scales;
  std::mutex clone_mutex;
  std::optional<ApproxTransform> approx;

  Impl(const SceneFrame& frame, const SceneSpec& scene) : frame_(frame), scene_(scene) {}

  double source_x(double x) const {
    return rewrap && std::fabs(x - centre) > 180.0 ? centre + wrap180(x - centre) : x;
  }
  OGRCoordinateTransformation& slot_transform(size_t slot) {
    if (!transforms[slot]) {
      std::lock_guard<std::mutex> lock(clone_mutex);
      TransformPtr c(exact->Clone());
      if (!c) c = make_transform(*src_, *frame_srs_, ctx);
      transforms[slot] = std::move(c);
    }
    return *transforms[slot];
  }
  NumericScale& slot_scale(size_t slot) {
    if (!scales[slot]) {
      std::lock_guard<std::mutex> lock(clone_mutex);
      scales[slot] = std::make_unique<NumericScale>(*frame_srs_, equal_area);
    }
    return *scales[slot];
  }
  // One vertex into the frame, relative to its origin: false when PROJ
  // cannot (out of the projection's domain, or an error).
  bool to_frame(size_t slot, int& leaf, double& x, double& y) {
    x = source_x(x);
    if (!identity && !(approx && approx->apply(x, y, leaf))) {
      int ok = 0;
      if (!slot_transform(slot).Transform(1, &x, &y, nullptr, &ok) || !ok) return false;
    }
    x -= frame_.origin_x;
    y -= frame_.origin_y;
    return true;
  }
  // The reason a feature is dropped for vertex j at `source`.
  std::string vertex_reason(size_t j, const Point2& source, bool transformed) const {
    return "vertex " + std::to_string(j) + " (" + std::to_string(source.x) + ", " +
           std::to_string(source.y) + ")" +
           (transformed ? " is not finite in the scene frame"
                        : " cannot be transformed into the scene frame") +
           frame_hint(frame_);
  }
  // Projects f's rings in place on this thread, summing the projected
  // vertices into (cx, cy) in ring order; the first vertex that cannot be
  // projected sets f's drop reason.
  void project_serially(SourceFeature& f, size_t slot, double& cx, double& cy) {
    int leaf = -1;
    for (Ring& r : f.rings) {
      for (size_t j = 0; j < r.size(); ++j) {
        double x = r[j].x, y = r[j].y;
        if (!to_frame(slot, leaf, x, y)) {
          f.drop_reason = vertex_reason(j, r[j], false);
          f.failed_in = FailureStage::project;
          return;
        }
        if ((!std::isfinite(x) || !std::isfinite(y)) && f.drop_reason.empty()) {
          f.drop_reason = vertex_reason(j, r[j], true);
          f.failed_in = FailureStage::project;
        }
        r[j] = {x, y};
        cx += x;
        cy += y;
      }
      if (!f.drop_reason.empty()) return;
    }
  }
  // The same for a part of many vertices (a world ocean's shell): the
  // vertices are projected in parallel chunks, then checked and summed in
  // ring order, so the result is project_serially's whatever the threads.
  void project_in_parallel(SourceFeature& f, double& cx, double& cy) {
    std::vector<size_t> first{0};
    for (const Ring& r : f.rings) first.push_back(first.back() + r.size());
    const size_t n = first.back();
    std::vector<Point2> out(n);
    std::vector<char> ok(n, 1);
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, n, 16384), [&](const tbb::blocked_range<size_t>& range) {
          const size_t slot = static_cast<size_t>(tbb::this_task_arena::current_thread_index());
          int leaf = -1;
          size_t ring =
              size_t(std::upper_bound(first.begin(), first.end(), range.begin()) - first.begin()) -
              1;
          for (size_t k = range.begin(); k != range.end(); ++k) {
            while (k >= first[ring + 1]) ++ring;
            const Point2& p = f.rings[ring][k - first[ring]];
            double x = p.x, y = p.y;
            ok[k] = to_frame(slot, leaf, x, y);
            out[k] = {x, y};
          }
        });
    for (size_t ring = 0; ring < f.rings.size(); ++ring) {
      Ring& r = f.rings[ring];
      for (size_t j = 0; j < r.size(); ++j) {
        const size_t k = first[ring] + j;
        if (!ok[k]) {
          f.drop_reason = vertex_reason(j, r[j], false);
          f.failed_in = FailureStage::project;
          return;
        }
        const Point2 q = out[k];
        if ((!std::isfinite(q.x) || !std::isfinite(q.y)) && f.drop_reason.empty()) {
          f.drop_reason = vertex_reason(j, r[j], true);
          f.failed_in = FailureStage::project;
        }
        r[j] = q;
        cx += q.x;
        cy += q.y;
      }
      if (!f.drop_reason.empty()) return;
    }
  }
  std::vector<double> apply(SourceLayer& chunk, ProgressStage* stage) {
    std::vector<double> k(chunk.features.size(), 1.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, chunk.features.size(), 64),
                      [&](const tbb::blocked_range<size_t>& range) {
                        const size_t slot =
                            static_cast<size_t>(tbb::this_task_arena::current_thread_index());
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          SourceFeature& f = chunk.features[i];
                          if (!f.drop_reason.empty()) continue;
                          double cx = 0, cy = 0;
                          size_t n_all = 0;
                          for (const Ring& r : f.rings) n_all += r.size();
                          if (n_all >= kParallelPartVertices)
                            project_in_parallel(f, cx, cy);
                          else
                            project_serially(f, slot, cx, cy);
                          if (!f.drop_reason.empty()) {
                            f.rings.clear();
                            continue;
                          }
                          if (n_all == 0) continue;
                          cx /= double(n_all);
                          cy /= double(n_all);
                          // Scale factor at the part's vertex centroid: widths are ground
                          // metres, the frame is not (ARCHITECTURE.md "2. project").
                          if (local_tm) {
                            // frame_scale_factor, with the frame's false northing y0 hoisted.
                            double lat = 0, lon = 0, gamma = 0;
                            tm_wgs84().Reverse(frame_.tm_lon0, cx + frame_.origin_x,
                                               cy + frame_.origin_y + tm_y0, lat, lon, gamma, k[i]);
                          } else {
                            k[i] = slot_scale(slot).at(cx + frame_.origin_x, cy + frame_.origin_y);
                          }
                          if (!std::isfinite(k[i])) k[i] = 1.0;
                        }
                        if (stage) stage->add(range.size());
                      });
    // Without skip_failures the first failing feature in input order stops
    // the build (the loop above runs in any order).
    if (!scene_.skip_failures) {
      for (const SourceFeature& f : chunk.features)
        if (f.failed_in) fail_feature(*f.failed_in, spec_.source, spec_.name, f.fid, f.drop_reason);
    }
    chunk.srs_wkt = frame_.crs_wkt;
    return k;
  }
};

LayerProjection::LayerProjection(const FeatureSource& features, size_t layer,
                                 const SceneFrame& frame, const SceneSpec& scene)
    : impl_(std::make_unique<Impl>(frame, scene)) {
  register_gdal_once();
  Impl& m = *impl_;
  m.spec_ = features.spec(layer);
  m.frame_srs_ = srs_from(frame.crs_wkt, "frame CRS");
  m.local_tm = std::isfinite(frame.tm_lon0);
  m.equal_area = !m.local_tm && is_equal_area(*m.frame_srs_);
  if (m.local_tm) tm_wgs84().Forward(frame.tm_lon0, frame.tm_lat0, frame.tm_lon0, m.tm_x0, m.tm_y0);
  m.src_ = srs_from(features.srs_wkt(layer), "source CRS of layer '" + m.spec_.name + "'");
  m.ctx = "layer '" + m.spec_.name + "' to the scene frame";
  // OGRCoordinateTransformation is not thread-safe: `exact` fits the
  // approximation here, on one thread; the workers clone it (a clone skips
  // PROJ's database search) only if some vertex needs the exact path.
  m.exact = make_transform(*m.src_, *m.frame_srs_, m.ctx);
  const int slots = tbb::this_task_arena::max_concurrency();
  m.transforms.resize(static_cast<size_t>(slots));
  m.scales.resize(static_cast<size_t>(slots));
  // The same CRS as the frame: PROJ's transformation is the identity (a
  // no-op); skip it, and the approximation too, which would move vertices
  // by up to kApproxTolerance and could part vertices that touch exactly.
  m.identity = m.src_->IsSame(m.frame_srs_.get()) != 0;
  // Lon/lat data wider than a half circle (across the antimeridian, as
  // -178.5 beside 179.9) is read within 180 degrees of the frame's centre:
  // the same points for PROJ, but one compact box for the approximation
  // instead of the whole globe (which it would split down to slivers,
  // fitting thousands of cells: 10 s instead of 1 s for a million
  // vertices). A longitude exactly 180 from the centre stays as it is (+180
  // and -180 are apart in a world frame); messages give the source's own.
  Extent box = bounds_of(features, layer);
  if (!m.identity && is_lon_lat(*m.src_) && box.xmax - box.xmin > 180.0) {
    m.rewrap = true;
    m.centre = frame_centre_lon(frame, *m.frame_srs_);
    box = {std::numeric_limits<double>::infinity(), box.ymin,
           -std::numeric_limits<double>::infinity(), box.ymax};
  }
  if (m.rewrap) {
    features.for_each(layer, [&](const SourceFeature& f) {
      if (!f.drop_reason.empty()) return;
      for (const Ring& r : f.rings)
        for (const Point2& p : r) {
          box.xmin = std::min(box.xmin, m.source_x(p.x));
          box.xmax = std::max(box.xmax, m.source_x(p.x));
        }
    });
  }
  if (!m.identity && box.xmax >= box.xmin && box.ymax >= box.ymin && std::isfinite(box.xmin) &&
      std::isfinite(box.ymin) && std::isfinite(box.xmax) && std::isfinite(box.ymax)) {
    m.approx.emplace(*m.exact, box, [&](auto&& visit) {
      features.for_each(layer, [&](const SourceFeature& f) {
        if (!f.drop_reason.empty()) return;
        for (const Ring& r : f.rings)
          for (const Point2& p : r) visit(m.source_x(p.x), p.y);
      });
    });
  }
}

LayerProjection::~LayerProjection() = default;

std::vector<double> LayerProjection::apply(SourceLayer& chunk, ProgressStage* stage) const {
  return impl_->apply(chunk, stage);
}

namespace {

// Closed boxes meet (a zero-width data box, one line, still meets).
bool meets(const Extent& a, const Extent& b) {
  return a.xmax >= b.xmin && a.xmin <= b.xmax && a.ymax >= b.ymin && a.ymin <= b.ymax;
}

Extent shifted(Extent e, double dx, double dy) {
  e.xmin += dx;
  e.xmax += dx;
  e.ymin += dy;
  e.ymax += dy;
  return e;
}

std::string box_text(const Extent& e) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%.3f,%.3f,%.3f,%.3f", e.xmin, e.ymin, e.xmax, e.ymax);
  return buf;
}

// The data's extent in scene coordinates: each layer's box in its source
// CRS, transformed into the frame (densified edges). nullopt when there is
// no vertex or a layer's box cannot be transformed (then nothing is
// checked against it).
std::optional<Extent> data_extent_in_frame(const FeatureSource& features,
                                           const OGRSpatialReference& frame_srs,
                                           const SceneFrame& frame) {
  Extent all = no_points();
  for (size_t li = 0; li < features.layer_count(); ++li) {
    const Extent e = bounds_of(features, li);
    if (!(e.xmax >= e.xmin && e.ymax >= e.ymin)) continue;
    try {
      auto src = srs_from(features.srs_wkt(li), "source CRS");
      auto t = make_transform(*src, frame_srs, "source to the scene frame");
      const Extent f = transform_bounds(*t, e, "layer '" + features.spec(li).name + "'");
      if (!(f.xmax >= f.xmin && f.ymax >= f.ymin)) return std::nullopt;
      all = {std::min(all.xmin, f.xmin), std::min(all.ymin, f.ymin), std::max(all.xmax, f.xmax),
             std::max(all.ymax, f.ymax)};
    } catch (const input_error&) {
      return std::nullopt;  // project() itself says what is wrong with the layer
    }
  }
  if (!(all.xmax >= all.xmin)) return std::nullopt;
  return shifted(all, -frame.origin_x, -frame.origin_y);
}

}  // namespace

Extent dem_extent_in_frame(const DemSpec& dem, const SceneFrame& frame) {
  register_gdal_once();
  // The DEM module opens it and resolves its CRS (own, or assume_crs).
  const DemFootprint footprint = dem_footprint(dem);
  if (frame.crs_wkt.empty()) return shifted(footprint.bounds, -frame.origin_x, -frame.origin_y);
  auto frame_srs = srs_from(frame.crs_wkt, "frame CRS");
  const auto dem_srs = srs_from(footprint.crs_wkt, "DEM CRS");
  auto t = make_transform(*dem_srs, *frame_srs, "DEM to the scene frame");
  const Extent e =
      transform_bounds(*t, footprint.bounds, "DEM " + dem_text(dem.path, dem.more_paths));
  return shifted(e, -frame.origin_x, -frame.origin_y);
}

void check_extent_units(const Extent& extent, const std::string& extent_crs,
                        const SceneFrame& frame, const Extent& data, const std::string& context) {
  if (!extent_crs.empty() || frame.crs_wkt.empty()) return;
  if (!(std::abs(extent.xmin) <= 180 && std::abs(extent.xmax) <= 180 &&
        std::abs(extent.ymin) <= 90 && std::abs(extent.ymax) <= 90))
    return;
  if (!(data.xmax >= data.xmin && data.ymax >= data.ymin)) return;
  register_gdal_once();
  OGRSpatialReference frame_srs;
  if (frame_srs.importFromWkt(frame.crs_wkt.c_str()) != OGRERR_NONE || !frame_srs.IsProjected())
    return;
  // A frame in feet is still a linear unit: numbers within +-180 are then
  // as suspicious as in metres.
  frame_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  const Extent data_abs = shifted(data, frame.origin_x, frame.origin_y);
  // The numbers read as longitude/latitude, in the frame.
  Extent as_degrees;
  try {
    auto t = make_transform(*wgs84(), frame_srs, "WGS84 to the frame CRS");
    as_degrees = transform_bounds(*t, extent, "--extent as degrees");
  } catch (const input_error&) {
    return;  // not a place on the globe in this frame: leave it as metres
  }
  if (!(as_degrees.xmax >= as_degrees.xmin) || !meets(as_degrees, data_abs)) return;
  // Read as degrees the extent names the data's place. Read as metres it
  // either misses the data, or its size is farther from the data's size
  // than the degree reading's is (a 3 cm view of a 2 km scene).
  const double data_size =
      std::max({data_abs.xmax - data_abs.xmin, data_abs.ymax - data_abs.ymin, 1.0});
  const double metres_size = std::max(extent.xmax - extent.xmin, extent.ymax - extent.ymin);
  const double degrees_size =
      std::max(as_degrees.xmax - as_degrees.xmin, as_degrees.ymax - as_degrees.ymin);
  const bool metres_miss = !meets(extent, data_abs);
  const bool degrees_closer =
      metres_size > 0 && degrees_size > 0 &&
      std::abs(std::log(degrees_size / data_size)) < std::abs(std::log(metres_size / data_size));
  if (!metres_miss && !degrees_closer) return;
  const char* srs_name = frame_srs.GetName();
  // The package records the frame's WKT, whose local TM is named "unknown".
  std::string name = frame.description;
  if (name.empty()) name = srs_name && std::string(srs_name) != "unknown" ? srs_name : "projected";
  char sizes[160];
  std::snprintf(sizes, sizeof sizes, "%.3g m wide against the data's %.3g m", metres_size,
                data_size);
  fail<usage_error>(
      context, "--extent " + box_text(extent) +
                   " looks like longitude/latitude degrees, but it is read in the frame CRS (" +
                   name + ", metres), where the data lie at " + box_text(data_abs) +
                   " (xmin,ymin,xmax,ymax); read as metres the view " +
                   (metres_miss ? std::string("misses them") : "is " + std::string(sizes)) +
                   ". Pass --extent-crs EPSG:4326 to give the extent in degrees (lon/lat order)");
}

std::optional<Extent> clip_extent(const SceneFrame& frame, const SceneSpec& scene,
                                  const FeatureSource& features) {
  register_gdal_once();
  auto frame_srs = srs_from(frame.crs_wkt, "frame CRS");
  // The data's extent in the frame, computed once and only when a check
  // needs it.
  std::optional<std::optional<Extent>> data;
  auto data_extent = [&]() -> const std::optional<Extent>& {
    if (!data) data = data_extent_in_frame(features, *frame_srs, frame);
    return *data;
  };
  std::optional<Extent> clip;
  // The clip extent: --extent, else the DEM's extent.
  if (scene.extent) {
    if (scene.extent_crs.empty())
      if (const std::optional<Extent>& d = data_extent())
        check_extent_units(*scene.extent, scene.extent_crs, frame, *d, "project");
    clip = shifted(extent_in_frame_crs(*scene.extent, scene.extent_crs, frame, "project"),
                   -frame.origin_x, -frame.origin_y);
  }
  if (!scene.dem.empty()) {
    DemSpec spec{scene.dem, scene.assume_crs};
    spec.more_paths = scene.dem_more;
    const Extent dem = dem_extent_in_frame(spec, frame);
    // A DEM beside the data would clip everything away (or, with --extent,
    // drape every line on its edge cells): refused, naming both boxes.
    auto refuse = [&](const std::string& what, const Extent& other) {
      fail<input_error>(kProjectStage,
                        "DEM " + dem_text(scene.dem, scene.dem_more) + " does not overlap " + what +
                            ": its footprint is " +
                            box_text(shifted(dem, frame.origin_x, frame.origin_y)) + ", " + what +
                            " is " + box_text(shifted(other, frame.origin_x, frame.origin_y)) +
                            " (xmin,ymin,xmax,ymax in the frame CRS); give the DEM of this area");
    };
    if (clip && !meets(dem, *clip)) refuse("the --extent", *clip);
    if (const std::optional<Extent>& d = data_extent(); d && !meets(dem, *d))
      refuse("the data's extent", *d);
    if (!clip) clip = dem;
  }
  return clip;
}

ProjectedFeatures project(FeatureSet features, const SceneFrame& frame, const SceneSpec& scene,
                          Progress* progress) {
  register_gdal_once();
  uint64_t parts = 0;
  for (const SourceLayer& layer : features.layers) parts += layer.features.size();
  ProgressStage stage(progress, "project", parts, "parts");
  ProjectedFeatures out;
  out.frame = frame;
  const SetSource source(features);
  // Before projecting: the extent and the DEM are checked against the data
  // in their source CRSs.
  out.clip = clip_extent(frame, scene, source);
  for (size_t li = 0; li < features.layers.size(); ++li) {
    const LayerProjection projection(source, li, frame, scene);
    out.scale.push_back(projection.apply(features.layers[li], &stage));
  }
  out.features = std::move(features);
  stage.finish();
  return out;
}

Extent extent_in_frame_crs(const Extent& extent, const std::string& crs, const SceneFrame& frame,
                           const std::string& context) {
  if (crs.empty()) return extent;
  register_gdal_once();
  try {
    auto from = srs_from(crs, "--extent-crs");
    auto to = srs_from(frame.crs_wkt, "frame CRS");
    auto t = make_transform(*from, *to, "--extent-crs to the frame CRS");
    return transform_bounds(*t, extent, "--extent");
  } catch (const input_error& e) {
    // srs_from and friends speak for the project stage.
    std::string what = e.what();
    const std::string project = stage_message(kProjectStage, "");
    if (context != kProjectStage && what.rfind(project, 0) == 0)
      what = stage_message(context, what.substr(project.size()));
    fail<input_error>(kNoStage, what);
  }
}

}  // namespace prep
