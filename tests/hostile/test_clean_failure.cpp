// The per-feature failure of the clean stage (prep/feature_failure.hpp) on a
// real GEOS error, in process. GEOS 3.11 fails on no input we know of, so
// CleanOptions::test_geos_failure_fid makes GEOS reject fid 2's
// simplification tolerance ("Tolerance must be non-negative"): a real GEOS
// error through the real path. The shipped tool has no such hook.
//
// The input is the corpus's fail_* shape (three 10 m squares, fid 2 in the
// middle, lon/lat near Monaco, the default local frame), run through read,
// project and clean as `decalprep build FILE --kind polygon` runs them, and
// the report as the tool writes it (prep::report_json). What is asserted is
// what the tool must do (tests/hostile/README.md, "Per-feature failures"):
//   without skip_failures: input_error, exit code 3, the message naming the
//     layer, the fid and GEOS's error, and nothing is built;
//   with it: fid 2 is the only manifest entry, `dropped` with reason
//     "failed in clean: GEOS simplification failed: ...", read = kept +
//     clipped_away + dropped, one dropped entry per dropped feature and one
//     skipped failure (the tool exits 4); fids 1 and 3 are kept whole
//     (GEOS's area of their projected input squares).
#include <geos_c.h>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "prep/clean.hpp"
#include "prep/error.hpp"
#include "prep/feature_failure.hpp"
#include "prep/pipeline.hpp"
#include "prep/project.hpp"
#include "prep/read.hpp"
#include "test_support.hpp"

namespace {

using nlohmann::json;

constexpr double kLon0 = 7.42, kLat0 = 43.73;  // as tests/hostile/generate.py
constexpr double kMetre = 1.0 / 111320.0;      // ~1 m in degrees of latitude

// A square of half-size r around (cx, cy) metres east/north of the
// reference point, closed, as GeoJSON [lon, lat] pairs.
std::string square(double cx, double cy, double r) {
  const double dx = kMetre / std::cos(kLat0 * M_PI / 180.0);
  const double xs[] = {cx - r, cx + r, cx + r, cx - r, cx - r};
  const double ys[] = {cy - r, cy - r, cy + r, cy + r, cy - r};
  std::string s = "[[";
  char buf[96];
  for (int i = 0; i < 5; ++i) {
    std::snprintf(buf, sizeof buf, "%s[%.17g, %.17g]", i ? ", " : "", kLon0 + xs[i] * dx,
                  kLat0 + ys[i] * kMetre);
    s += buf;
  }
  return s + "]]";
}

std::string three_squares() {
  std::string fc = R"({"type": "FeatureCollection", "features": [)";
  const double cx[] = {5, 20, 35};
  for (int fid = 1; fid <= 3; ++fid)
    fc += std::string(fid > 1 ? ", " : "") + R"({"type": "Feature", "id": )" + std::to_string(fid) +
          R"(, "properties": {}, "geometry": {"type": "Polygon", "coordinates": )" +
          square(cx[fid - 1], 5, 5) + "}}";
  return fc + "]}";
}

prep::BuildSpec scene_of(const std::string& path, bool skip_failures) {
  prep::LayerSpec l;
  l.source = path;
  l.name = "layer0";  // the name the tool gives a file-less layer
  l.kind = prep::DecalKind::polygon;
  prep::BuildSpec s;
  s.layers.push_back(l);
  s.skip_failures = skip_failures;
  return s;
}

// Read, project, clean, as the pipeline runs them; `projected` keeps the
// projected input for the oracle.
prep::SceneFeatures clean_failing_fid_2(const prep::BuildSpec& s,
                                        prep::ProjectedFeatures* projected = nullptr) {
  prep::FeatureSet features = prep::read_scene(s);
  const prep::SceneFrame frame = prep::choose_frame(features, s.crs);
  prep::ProjectedFeatures p = prep::project(std::move(features), frame, s);
  if (projected) *projected = p;
  prep::CleanOptions options;
  options.test_geos_failure_fid = 2;
  return prep::clean(std::move(p), s, options);
}

const char* const kGeosError =
    "GEOS simplification failed: IllegalArgumentException: Tolerance must be non-negative";

TEST(CleanFailure, AGeosErrorStopsTheBuildNamingLayerFidAndError) {
  prep::test::TempDir dir;
  prep::test::write_text(dir.file("fail_clean_geos_error.geojson"), three_squares());
  try {
    clean_failing_fid_2(scene_of(dir.file("fail_clean_geos_error.geojson"), false));
    FAIL() << "a feature GEOS rejects did not stop the build";
  } catch (const prep::error& e) {
    EXPECT_EQ(static_cast<int>(e.code()), 3) << e.what();  // prep::ExitCode::input
    const std::string want =
        std::string("layer 'layer0' fid 2: ") + kGeosError + " (--skip-failures drops";
    EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("clean: ", 0), 0u) << e.what();
  }
}

TEST(CleanFailure, WithSkipFailuresTheFeatureIsDroppedAsFailedInCleanAndTheRestKept) {
  prep::test::TempDir dir;
  prep::test::write_text(dir.file("fail_clean_geos_error.geojson"), three_squares());
  prep::ProjectedFeatures projected;
  const prep::SceneFeatures sf =
      clean_failing_fid_2(scene_of(dir.file("fail_clean_geos_error.geojson"), true), &projected);

  // The manifest, entry for entry, as the report writes it.
  const json report = json::parse(prep::report_json(sf, "", {}, false));
  const json& entries = report["manifest"]["entries"];
  ASSERT_EQ(entries.size(), 1u) << entries.dump(1);
  const json& e = entries[0];
  EXPECT_EQ(e["fid"], 2);
  EXPECT_EQ(e["part"], -1);
  EXPECT_EQ(e["action"], "dropped");
  EXPECT_EQ(e["reason"].get<std::string>().rfind(std::string("failed in clean: ") + kGeosError, 0),
            0u)
      << e.dump();
  EXPECT_TRUE(e["area_before"].is_null() && e["area_after"].is_null()) << e.dump();
  // No silent loss; exit 4 exactly when a failure was skipped (the tool's
  // partial exit counts these entries: is_skipped_failure).
  const json& totals = report["manifest"]["totals"];
  EXPECT_EQ(totals["read"].get<uint64_t>(), 3u) << totals.dump();
  EXPECT_EQ(totals["kept"].get<uint64_t>(), 2u) << totals.dump();
  EXPECT_EQ(totals["clipped_away"].get<uint64_t>(), 0u) << totals.dump();
  EXPECT_EQ(totals["dropped"].get<uint64_t>(), 1u) << totals.dump();
  size_t skipped = 0;
  for (const prep::ManifestEntry& m : sf.manifest.entries) skipped += prep::is_skipped_failure(m);
  EXPECT_EQ(skipped, 1u);

  // The rest is kept whole: GEOS's area of each kept feature equals that of
  // its projected input square.
  GEOSContextHandle_t h = GEOS_init_r();
  auto area = [&](const prep::Ring& r) {
    GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h, static_cast<unsigned>(r.size() + 1), 2);
    for (size_t i = 0; i <= r.size(); ++i)
      GEOSCoordSeq_setXY_r(h, cs, static_cast<unsigned>(i), r[i % r.size()].x, r[i % r.size()].y);
    GEOSGeometry* g = GEOSGeom_createPolygon_r(h, GEOSGeom_createLinearRing_r(h, cs), nullptr, 0);
    double a = 0;
    GEOSArea_r(h, g, &a);
    GEOSGeom_destroy_r(h, g);
    return a;
  };
  std::map<int64_t, double> in, out;
  for (const prep::SourceFeature& f : projected.features.layers.at(0).features) {
    prep::Ring r = f.rings.at(0);
    if (r.size() > 1 && r.front().x == r.back().x && r.front().y == r.back().y) r.pop_back();
    in[f.fid] += area(r);
  }
  for (const prep::ScenePolygon& p : sf.polygons) out[p.fid] += area(p.shell);
  GEOS_finish_r(h);
  EXPECT_EQ(out.count(2), 0u) << "the failed feature was kept";
  for (int64_t fid : {1, 3}) {
    ASSERT_EQ(out.count(fid), 1u) << "fid " << fid << " not kept";
    EXPECT_NEAR(out[fid], in[fid], 1e-9 * in[fid]) << "fid " << fid;
    EXPECT_NEAR(in[fid], 100.0, 1.0) << "fid " << fid << ": not the 10 m square";
  }
}

// The shipped tool reads no test hook from its environment: with the
// variable the hook once was, the same input builds untouched.
TEST(CleanFailure, TheToolHasNoGeosFailureHook) {
  prep::test::TempDir dir;
  prep::test::write_text(dir.file("in.geojson"), three_squares());
  const std::string args = "build " + prep::test::shell_quote(dir.file("in.geojson")) +
                           " --kind polygon -o " + prep::test::shell_quote(dir.file("out.decals")) +
                           " --report " + prep::test::shell_quote(dir.file("report.json")) + " -q";
  const prep::test::ToolRun r = prep::test::run_tool(
      args, dir, {.env = "DECALPREP_TEST_GEOS_FAIL_FID=2 ", .split_stderr = true});
  ASSERT_EQ(r.rc, 0) << r.err;
  const json report = json::parse(prep::test::read_text(dir.file("report.json")));
  EXPECT_TRUE(report["manifest"]["entries"].empty()) << report["manifest"]["entries"].dump(1);
  EXPECT_EQ(report["manifest"]["totals"]["kept"].get<uint64_t>(), 3u);
}

}  // namespace
