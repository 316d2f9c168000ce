// The DEM surface (prep/dem.hpp): GDAL's bilinear, CRS transforms, the CRS
// rule, no-data policy, band scale/offset and units.
#include <gtest/gtest.h>
#include <unistd.h>

#include <functional>
#include <random>
#include <stdexcept>

#include "prep/dem.hpp"
#include "prep/error.hpp"
#include "terrain_fixtures.hpp"

namespace {

using terraintest::GdalBilinear;

// Bumpy synthetic terrain in UTM 32N, 10 m cells.
double bumpy(int i, int j) {
  return 100 + 30 * std::sin(i * 0.37) * std::cos(j * 0.21) + 0.5 * i - 0.25 * j;
}

TEST(DemSampler, BilinearEqualsGdalBilinearOnSyntheticGeoTiff) {
  const std::string dir = terraintest::temp_dir("bilinear");
  const double gt[6] = {500000, 10, 0, 5000000, 0, -10};
  const std::string path =
      terraintest::write_dem(dir + "/dem.tif", 60, 40, gt, "EPSG:32632", bumpy);
  prep::SceneFrame frame;
  frame.crs_wkt = terraintest::wkt_of("EPSG:32632");
  frame.origin_x = 500000;
  frame.origin_y = 4999600;
  prep::DemSampler dem(path, frame, 1.0, std::nullopt);
  dem.load(0, 0, 60, 40);
  const GdalBilinear oracle(path);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> ux(2.5, 597.5), uy(2.5, 397.5);
  for (int k = 0; k < 2000; ++k) {
    const prep::Point2 p{ux(rng), uy(rng)};
    const prep::Point2 px = dem.to_pixel(p);
    EXPECT_NEAR(px.x, p.x / 10, 1e-9);
    EXPECT_NEAR(px.y, (400 - p.y) / 10, 1e-9);
    EXPECT_NEAR(dem.height(px.x, px.y), oracle.at(p.x + 500000, p.y + 4999600), 1e-3)
        << p.x << " " << p.y;
  }
  // Edges: half a cell beyond the outermost centres GDAL uses the edge cell.
  for (const auto& q : {prep::Point2{0.3, 0.3}, prep::Point2{59.7, 0.4}, prep::Point2{0.26, 39.7},
                        prep::Point2{30.2, 39.74}})
    EXPECT_NEAR(dem.height(q.x, q.y), oracle.at_pixel(q.x, q.y), 1e-3) << q.x << " " << q.y;
  EXPECT_EQ(dem.stats().window_cells, 60u * 40u);
}

TEST(DemSampler, PlaneIsReproducedExactly) {
  // Bilinear interpolation reproduces a plane: analytic oracle.
  const std::string dir = terraintest::temp_dir("plane");
  const double gt[6] = {1000, 2, 0, 2000, 0, -2};
  auto plane = [](double x, double y) { return 5 + 0.3 * x - 0.7 * y; };
  const std::string path = terraintest::write_dem(
      dir + "/plane.tif", 50, 50, gt, "EPSG:32631",
      [&](int i, int j) { return plane(1000 + 2 * (i + 0.5), 2000 - 2 * (j + 0.5)); });
  prep::SceneFrame frame;  // empty CRS: the DEM's own
  prep::DemSampler dem(path, frame, 2.0, std::nullopt);
  dem.load(0, 0, 50, 50);
  for (double x = 1001; x < 1099; x += 3.7)
    for (double y = 1901; y < 1999; y += 4.1) {
      const prep::Point2 px = dem.to_pixel({x, y});
      EXPECT_NEAR(dem.height(px.x, px.y), 2.0 * plane(x, y), 1e-3);
    }
}

TEST(DemSampler, DemInGeographicCrsIsSampledAtTransformedPoints) {
  const std::string dir = terraintest::temp_dir("geo");
  // 1 arc-second cells around Monaco, EPSG:4326 (lat/lon authority order).
  const double gt[6] = {7.40, 1.0 / 3600, 0, 43.75, 0, -1.0 / 3600};
  const std::string path =
      terraintest::write_dem(dir + "/geo.tif", 150, 100, gt, "EPSG:4326", bumpy);
  const terraintest::MonacoFrame mf;
  prep::DemSampler dem(path, mf.frame(), 1.0, std::nullopt);
  dem.load(0, 0, 150, 100);
  const GdalBilinear oracle(path);
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> ulon(7.401, 7.440), ulat(43.7235, 43.749);
  for (int k = 0; k < 500; ++k) {
    const double lon = ulon(rng), lat = ulat(rng);
    const prep::Point2 p = mf.forward(lon, lat);
    const prep::Point2 px = dem.to_pixel(p);
    EXPECT_NEAR(px.x, (lon - 7.40) * 3600, 1e-6);
    EXPECT_NEAR(px.y, (43.75 - lat) * 3600, 1e-6);
    EXPECT_NEAR(dem.height(px.x, px.y), oracle.at(lon, lat), 1e-3);
  }
  // Cell size: 1" is ~30.9 m north-south and ~22.4 m east-west at 43.7 N.
  EXPECT_NEAR(dem.cell_size_metres(mf.forward(7.42, 43.735)), 22.36, 0.2);
}

TEST(DemSampler, NoDataTakesNearestValidCellAndIsCounted) {
  const std::string dir = terraintest::temp_dir("nodata");
  const double gt[6] = {0, 1, 0, 20, 0, -1};
  const double nodata = -9999;
  // Cell value 100*j + i; holes: (5,5) single, a 3x2 block at (10..12, 3..4).
  auto f = [&](int i, int j) {
    if ((i == 5 && j == 5) || (i >= 10 && i <= 12 && j >= 3 && j <= 4)) return nodata;
    return 100.0 * j + i;
  };
  const std::string path =
      terraintest::write_dem(dir + "/holes.tif", 20, 20, gt, "EPSG:32632", f, &nodata);
  {
    prep::DemSampler dem(path, {}, 1.0, std::nullopt);
    dem.load(0, 0, 20, 20);
    EXPECT_EQ(dem.stats().nodata_cells, 7u);
    bool touched = false;
    // The single hole takes its first 8-neighbour in scan order: (4, 4).
    EXPECT_DOUBLE_EQ(dem.height(5.5, 5.5, &touched), 404.0);
    EXPECT_TRUE(touched);
    // Block cell (11, 3): nearest valid by breadth-first distance is one
    // step away; the first in scan order to reach it is (10, 2) via (11, 2)?
    // Both (10,2),(11,2),(12,2) are 1 step away; the first dequeued valid
    // cell in scan order is (10, 2) -> 210.
    EXPECT_DOUBLE_EQ(dem.height(11.5, 3.5), 210.0);
    EXPECT_DOUBLE_EQ(dem.height(2.5, 2.5, &touched), 202.0);
    EXPECT_FALSE(touched);
    EXPECT_NE(dem.stats().fill_policy.find("nearest"), std::string::npos);
  }
  {
    prep::DemSampler dem(path, {}, 1.0, 42.0);
    dem.load(0, 0, 20, 20);
    EXPECT_DOUBLE_EQ(dem.height(5.5, 5.5), 42.0);
    EXPECT_DOUBLE_EQ(dem.height(11.5, 4.5), 42.0);
    EXPECT_EQ(dem.stats().nodata_cells, 7u);
    EXPECT_DOUBLE_EQ(dem.stats().min, 0.0);
    EXPECT_DOUBLE_EQ(dem.stats().max, 1919.0);
  }
}

TEST(DemSampler, SrtmInsideZipOpensAndMatchesGdal) {
  if (!terraintest::monaco_available()) GTEST_SKIP() << "missing " << terraintest::monaco_pbf();
  const terraintest::MonacoFrame mf;
  prep::DemSampler dem(terraintest::monaco_dem(), mf.frame(), 1.0, std::nullopt);
  EXPECT_NE(dem.stats().description.find("SRTMHGT"), std::string::npos) << dem.stats().description;
  const prep::Point2 a = dem.to_pixel(mf.forward(7.40, 43.72)),
                     b = dem.to_pixel(mf.forward(7.44, 43.75));
  dem.load(std::min(a.x, b.x), std::min(a.y, b.y), std::max(a.x, b.x), std::max(a.y, b.y));
  const GdalBilinear oracle(terraintest::monaco_dem());
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> ulon(7.40, 7.44), ulat(43.72, 43.75);
  int clean = 0;
  for (int k = 0; k < 300; ++k) {
    const double lon = ulon(rng), lat = ulat(rng);
    // This tile has voids near the coast; those are the fill policy's
    // business (MonacoTerrain tests), here only clean stencils count.
    bool touches_void = false;
    for (const auto& [i, j] : oracle.stencil(oracle.px(lon), oracle.py(lat)))
      touches_void = touches_void || oracle.invalid(i, j);
    if (touches_void) continue;
    ++clean;
    const prep::Point2 px = dem.to_pixel(mf.forward(lon, lat));
    EXPECT_NEAR(dem.height(px.x, px.y), oracle.at(lon, lat), 1e-3);
  }
  EXPECT_GT(clean, 200);
}

TEST(DemSampler, VrtAndFeetUnitsAreHonoured) {
  const std::string dir = terraintest::temp_dir("vrt");
  const double gt[6] = {0, 5, 0, 100, 0, -5};
  const std::string tif = terraintest::write_dem(dir + "/feet.tif", 20, 20, gt, "EPSG:32632",
                                                 [](int i, int j) { return 100.0 + i - j; });
  {
    GDALDatasetUniquePtr ds(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    ASSERT_TRUE(ds);
    ds->GetRasterBand(1)->SetUnitType("ft");
  }
  // A VRT over the GeoTIFF, made by GDAL itself.
  const std::string vrt = dir + "/feet.vrt";
  {
    GDALDatasetUniquePtr src(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("VRT");
    GDALDatasetUniquePtr out(
        drv->CreateCopy(vrt.c_str(), src.get(), FALSE, nullptr, nullptr, nullptr));
    ASSERT_TRUE(out);
  }
  prep::DemSampler dem(vrt, {}, 1.0, std::nullopt);
  EXPECT_NE(dem.stats().description.find("VRT"), std::string::npos) << dem.stats().description;
  dem.load(0, 0, 20, 20);
  const GdalBilinear oracle(vrt);
  for (double x = 3; x < 97; x += 7.3)
    for (double y = 3; y < 97; y += 6.1) {
      const prep::Point2 px = dem.to_pixel({x, y});
      EXPECT_NEAR(dem.height(px.x, px.y), 0.3048 * oracle.at(x, y), 1e-3);
    }
}

// A GeoTIFF written through GDAL with the band settings a DEM can carry:
// raw cell values f(i, j) of `type`, no CRS when `crs` is empty.
std::string write_band(const std::string& path, int w, int h, const double gt[6],
                       const std::string& crs, const std::function<double(int, int)>& f,
                       GDALDataType type, const double* nodata, double scale, double offset,
                       const char* unit) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  GDALDatasetUniquePtr ds(drv->Create(path.c_str(), w, h, 1, type, nullptr));
  if (!ds) throw std::runtime_error("cannot create " + path);
  double g[6];
  std::copy(gt, gt + 6, g);
  ds->SetGeoTransform(g);
  if (!crs.empty()) ds->SetProjection(terraintest::wkt_of(crs).c_str());
  GDALRasterBand* b = ds->GetRasterBand(1);
  if (nodata) b->SetNoDataValue(*nodata);
  b->SetScale(scale);
  b->SetOffset(offset);
  if (unit) b->SetUnitType(unit);
  std::vector<double> v(static_cast<size_t>(w) * h);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) v[static_cast<size_t>(j) * w + i] = f(i, j);
  if (b->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float64, 0, 0, nullptr) != CE_None)
    throw std::runtime_error("cannot write " + path);
  return path;
}

TEST(DemSampler, DemWithoutCrsIsAnErrorNamingTheFileUnlessACrsIsAssumed) {
  const std::string dir = terraintest::temp_dir("nocrs");
  const double gt[6] = {500000, 10, 0, 5000300, 0, -10};
  // A plane in metres: bilinear reproduces it, so the oracle is the plane.
  auto plane = [](double x, double y) { return 50 + 0.02 * (x - 500000) - 0.01 * (y - 5000000); };
  const std::string path = write_band(
      dir + "/nocrs.tif", 30, 30, gt, "",
      [&](int i, int j) { return plane(500000 + 10 * (i + 0.5), 5000300 - 10 * (j + 0.5)); },
      GDT_Float32, nullptr, 1, 0, nullptr);
  prep::SceneFrame frame;
  frame.crs_wkt = terraintest::wkt_of("EPSG:32632");
  frame.origin_x = 500000;
  frame.origin_y = 5000000;
  for (const prep::SceneFrame& f : {frame, prep::SceneFrame{}}) {
    try {
      prep::DemSampler dem(prep::DemSpec{path}, f);
      FAIL() << "a DEM without a CRS was accepted";
    } catch (const prep::input_error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("--assume-crs"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(prep::dem_footprint({path}), prep::input_error);
  EXPECT_THROW(prep::DemSampler(prep::DemSpec{path, "not a crs"}, frame), prep::input_error);

  prep::DemSampler dem(prep::DemSpec{path, "EPSG:32632"}, frame);
  EXPECT_NE(dem.stats().description.find("(assumed), same as scene"), std::string::npos)
      << dem.stats().description;
  dem.load(0, 0, 30, 30);
  for (double x = 20; x < 280; x += 17.3)
    for (double y = 20; y < 280; y += 13.1) {
      const prep::Point2 px = dem.to_pixel({x, y});
      EXPECT_NEAR(dem.height(px.x, px.y), plane(500000 + x, 5000000 + y), 1e-4) << x << " " << y;
    }
  const prep::DemFootprint fp = prep::dem_footprint({path, "EPSG:32632"});
  EXPECT_TRUE(fp.crs_assumed);
  EXPECT_DOUBLE_EQ(fp.bounds.xmin, 500000);
  EXPECT_DOUBLE_EQ(fp.bounds.ymin, 5000000);
  EXPECT_DOUBLE_EQ(fp.bounds.xmax, 500300);
  EXPECT_DOUBLE_EQ(fp.bounds.ymax, 5000300);
  OGRSpatialReference got, utm;
  got.importFromWkt(fp.crs_wkt.c_str());
  utm.importFromEPSG(32632);
  EXPECT_TRUE(got.IsSame(&utm));
  // A DEM with its own CRS ignores the assumed one.
  const std::string own = terraintest::write_dem(dir + "/own.tif", 5, 5, gt, "EPSG:32632",
                                                 [](int, int) { return 1.0; });
  EXPECT_FALSE(prep::dem_footprint({own, "EPSG:4326"}).crs_assumed);
}

TEST(DemSampler, BandScaleOffsetAndFeetGiveMetres) {
  const std::string dir = terraintest::temp_dir("units");
  const double gt[6] = {300000, 4, 0, 4000100, 0, -4};
  // Int16 raw r = 1000 + 3 i - 2 j; feet = 0.5 r + 100.
  auto raw = [](int i, int j) { return 1000.0 + 3 * i - 2 * j; };
  struct Case {
    const char* unit;
    double metres_per_unit;
  };
  for (const Case c : {Case{"ft", 0.3048}, Case{"US survey foot", 1200.0 / 3937.0}, Case{"m", 1.0},
                       Case{nullptr, 1.0}}) {
    const std::string path =
        write_band(dir + "/u" + std::to_string(int(c.metres_per_unit * 1e4)) + ".tif", 25, 25, gt,
                   "EPSG:32633", raw, GDT_Int16, nullptr, 0.5, 100, c.unit);
    prep::DemSampler dem(prep::DemSpec{path, "", 2.0, std::nullopt}, prep::SceneFrame{});
    dem.load(0, 0, 25, 25);
    for (double u = 0.5; u <= 24.5; u += 1.7)
      for (double v = 0.5; v <= 24.5; v += 2.3) {
        // The plane through the cell centres, continued bilinearly.
        const double r = 1000 + 3 * (u - 0.5) - 2 * (v - 0.5);
        EXPECT_NEAR(dem.height(u, v), 2.0 * c.metres_per_unit * (0.5 * r + 100), 1e-9)
            << (c.unit ? c.unit : "(none)") << " " << u << " " << v;
      }
    // A plane has no twist.
    EXPECT_NEAR(dem.max_twist(), 0.0, 1e-9);
  }
}

TEST(DemSampler, MaxTwistIsTheLargestCellTwistInMetres) {
  const std::string dir = terraintest::temp_dir("twist");
  const double gt[6] = {0, 1, 0, 30, 0, -1};
  // f = i j / 4 has twist 1/4 in every 2x2 block; one bump adds 2 there.
  const std::string path = terraintest::write_dem(
      dir + "/twist.tif", 30, 30, gt, "EPSG:32632",
      [](int i, int j) { return i * j / 4.0 + (i == 10 && j == 12 ? 2.0 : 0.0); });
  prep::DemSampler dem(prep::DemSpec{path, "", 3.0, std::nullopt}, prep::SceneFrame{});
  dem.load(0, 0, 30, 30);
  EXPECT_NEAR(dem.max_twist(), 3.0 * (0.25 + 2.0), 1e-9);
  const auto lat = dem.lattice();
  ASSERT_TRUE(lat);
  EXPECT_DOUBLE_EQ(lat->x0, 0.5);
  EXPECT_DOUBLE_EQ(lat->y0, 29.5);
  EXPECT_DOUBLE_EQ(lat->dx, 1);
  EXPECT_DOUBLE_EQ(lat->dy, -1);
}

TEST(DemSampler, LatticeIsOnlyGivenWhenTheDemGridIsAGridOfTheFrame) {
  const std::string dir = terraintest::temp_dir("lattice");
  const double gt[6] = {7.40, 1.0 / 3600, 0, 43.75, 0, -1.0 / 3600};
  const std::string geo = terraintest::write_dem(dir + "/geo.tif", 10, 10, gt, "EPSG:4326", bumpy);
  const terraintest::MonacoFrame mf;
  EXPECT_FALSE(prep::DemSampler(geo, mf.frame(), 1.0, std::nullopt).lattice());
  const double rot[6] = {1000, 2, 0.5, 2000, 0.5, -2};
  const std::string rotated =
      terraintest::write_dem(dir + "/rot.tif", 10, 10, rot, "EPSG:32632", bumpy);
  EXPECT_FALSE(prep::DemSampler(rotated, {}, 1.0, std::nullopt).lattice());
}

// The fill is the nearest valid cell of the raster, whatever window a caller
// reads: a void 150 cells wide, sampled through a window that holds no valid
// cell, takes the valid cells' value (the old window-bound search gave 0).
TEST(DemSampler, NoDataFillDoesNotDependOnTheWindowRead) {
  const std::string dir = terraintest::temp_dir("deepvoid");
  const double gt[6] = {0, 1, 0, 60, 0, -1};
  const double nodata = -9999;
  // Valid: columns 0..9 at 70 m plus a bump column 5; columns 10..199 void.
  auto f = [&](int i, int j) { return i < 10 ? (i == 5 ? 70.0 + j : 70.0) : nodata; };
  const std::string path =
      terraintest::write_dem(dir + "/void.tif", 200, 60, gt, "EPSG:32632", f, &nodata);
  prep::DemSampler near(path, {}, 1.0, std::nullopt), whole(path, {}, 1.0, std::nullopt);
  near.load(150, 20, 160, 30);  // 16-cell margin: columns 134..176, all void
  whole.load(0, 0, 200, 60);
  for (double u = 150; u <= 160; u += 0.7)
    for (double v = 20; v <= 30; v += 0.9) {
      // Nearest valid cells are in column 9 (140+ cells away), all 70 m.
      EXPECT_DOUBLE_EQ(near.height(u, v), 70.0) << u << " " << v;
      EXPECT_DOUBLE_EQ(near.height(u, v), whole.height(u, v)) << u << " " << v;
    }
  // Near the valid columns both windows agree cell by cell, bump included.
  prep::DemSampler edge(path, {}, 1.0, std::nullopt);
  edge.load(12, 5, 14, 50);
  for (double u = 12; u <= 14; u += 0.25)
    for (double v = 5; v <= 50; v += 0.75)
      EXPECT_DOUBLE_EQ(edge.height(u, v), whole.height(u, v)) << u << " " << v;
  EXPECT_EQ(near.stats().fill_policy, "nearest valid cell");
}

TEST(DemSampler, MissingFileIsAGdalError) {
  EXPECT_THROW(prep::DemSampler("/nonexistent/dem.tif", {}, 1.0, std::nullopt), prep::gdal_error);
}

}  // namespace
