// The hostile-input corpus (tests/hostile/README.md). For every case that
// tests/hostile/generate.py writes, tests/hostile/expected.json says what
// `decalprep build` must do:
//   exit     the exit code (0 built, 4 partial with --skip-failures, 3 input, 6 resource);
//   message  (exit != 0) a substring of the error printed on stderr;
//   entries  (exit 0 or 4) the manifest entries of the --report JSON, exactly:
//            same number, each {fid, action, reason substring, area}; `area`
//            true means area_before/area_after must be given (the repair
//            changed the covered area by more than 1e-6 relative), false that
//            they must be null.
// Each case that builds is then sampled: the CPU evaluator on the written
// package against GEOS on the cleaned (repaired) geometry of the same scene,
// in the scene frame, skipping points within 2 mm of the oracle's boundary.
//   polygons: inside the union of the cleaned polygons (GEOS contains);
//   lines, round corners: distance to the centreline below / above hw;
//   lines, bevel corners: inside GEOS's bevel buffer (round caps) / farther
//     than hw from the centreline;
//   lines, miter corners: covered within hw of the centreline (a mitre join
//     only adds to the round join) and never beyond hw / sin(20°) (the mitre
//     limit), i.e. no exploding miter at 180° reversals.
// The corpus is generated at test time into the build tree (fixture
// hostile_corpus); HOSTILE_CORPUS overrides the folder (the --big run).
#include <geos_c.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <sstream>

#include "decal/reader.hpp"
#include "prep/evaluate.hpp"
#include "prep/features.hpp"
#include "prep/pipeline.hpp"
#include "prep/read.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json load_json(const fs::path& p) {
  std::ifstream in(p);
  if (!in) return json();
  return json::parse(in, nullptr, false);
}

fs::path corpus_dir() {
  const char* e = std::getenv("HOSTILE_CORPUS");
  return e ? fs::path(e) : fs::path(HOSTILE_CORPUS_DIR);
}

const json& expected() {
  static const json j = load_json(fs::path(DECALPREP_SOURCE_DIR) / "tests/hostile/expected.json");
  return j;
}

std::vector<std::string> case_names() {
  std::vector<std::string> names;
  for (auto it = expected().begin(); it != expected().end(); ++it)
    if (it.key().rfind("_", 0) != 0) names.push_back(it.key());
  return names;
}

using prep::test::shell_quote;

// Runs the tool in `dir`; stderr in ToolRun::err.
prep::test::ToolRun run_case(const std::vector<std::string>& args, const fs::path& dir) {
  std::string line;
  for (const auto& arg : args) line += (line.empty() ? "" : " ") + shell_quote(arg);
  return prep::test::run_tool(line, dir, {.split_stderr = true});
}

// The scene `decalprep build PATH <args>` describes (the options the corpus
// uses), for the in-process dry run that yields the cleaned geometry.
bool is_scene_file(const json& c) {
  const std::string p = c["path"].get<std::string>();
  return p.size() > 5 && p.compare(p.size() - 5, 5, ".toml") == 0;
}

prep::BuildSpec scene_of(const json& c) {
  // A scene-file case (several layers) is read as decalprep reads it.
  if (is_scene_file(c)) return prep::load_scene_file(c["path"].get<std::string>());
  prep::LayerSpec l;
  l.source = c["path"].get<std::string>();
  l.name = "layer0";
  l.kind = prep::parse_kind(c["kind"].get<std::string>());
  prep::BuildSpec s;
  const auto args = c["args"].get<std::vector<std::string>>();
  for (size_t i = 0; i < args.size(); i += 2) {
    if (args[i] == "--skip-failures") {
      s.skip_failures = true;
      --i;  // a flag: no value
      continue;
    }
    if (i + 1 >= args.size()) break;
    if (args[i] == "--width")
      l.style.width = std::stod(args[i + 1]);
    else if (args[i] == "--corner")
      l.style.corner = prep::parse_corner(args[i + 1]);
    else if (args[i] == "--crs")
      s.crs = args[i + 1];
    else if (args[i] == "--assume-crs")
      s.assume_crs = args[i + 1];
    else if (args[i] == "--resolution")
      s.resolution = std::stod(args[i + 1]);
    else if (args[i] == "--repair")
      s.repair = prep::parse_repair_method(args[i + 1]);
    else if (args[i] == "--max-memory")
      continue;  // a limit, not part of the scene
    else
      ADD_FAILURE() << "scene_of: option " << args[i] << " not mirrored by the test";
  }
  s.layers.push_back(l);
  return s;
}

struct Geos {
  GEOSContextHandle_t h = GEOS_init_r();
  ~Geos() { GEOS_finish_r(h); }
  GEOSGeometry* ring(const prep::Ring& r, bool linear) const {
    const bool close = linear;
    const unsigned n = unsigned(r.size() + (close ? 1 : 0));
    GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h, n, 2);
    for (unsigned i = 0; i < n; ++i) {
      const prep::Point2& p = r[i % r.size()];
      GEOSCoordSeq_setXY_r(h, cs, i, p.x, p.y);
    }
    return linear ? GEOSGeom_createLinearRing_r(h, cs) : GEOSGeom_createLineString_r(h, cs);
  }
  GEOSGeometry* polygon(const prep::ScenePolygon& p) const {
    std::vector<GEOSGeometry*> holes;
    for (const auto& r : p.holes) holes.push_back(ring(r, true));
    return GEOSGeom_createPolygon_r(h, ring(p.shell, true), holes.data(), unsigned(holes.size()));
  }
  GEOSGeometry* line(const prep::SceneLine& l) const {
    prep::Ring pts = l.points;
    if (l.closed) pts.push_back(pts.front());
    return ring(pts, false);
  }
  GEOSGeometry* unite(std::vector<GEOSGeometry*>& parts) const {
    if (parts.empty()) return GEOSGeom_createEmptyPolygon_r(h);
    // One polygon is its own union (a union of a 10^5-hole polygon takes minutes).
    if (parts.size() == 1) return parts[0];
    GEOSGeometry* coll = GEOSGeom_createCollection_r(h, GEOS_GEOMETRYCOLLECTION, parts.data(),
                                                     unsigned(parts.size()));
    GEOSGeometry* u = GEOSUnaryUnion_r(h, coll);
    GEOSGeom_destroy_r(h, coll);
    return u;
  }
};

// A region with its boundary, prepared, for point queries.
struct Region {
  const Geos& g;
  GEOSGeometry* area = nullptr;
  GEOSGeometry* boundary = nullptr;
  const GEOSPreparedGeometry* parea = nullptr;
  const GEOSPreparedGeometry* pbound = nullptr;
  Region(const Geos& geos, GEOSGeometry* a) : g(geos), area(a) {
    boundary = GEOSBoundary_r(g.h, area);
    parea = GEOSPrepare_r(g.h, area);
    pbound = GEOSPrepare_r(g.h, boundary);
  }
  ~Region() {
    GEOSPreparedGeom_destroy_r(g.h, parea);
    GEOSPreparedGeom_destroy_r(g.h, pbound);
    GEOSGeom_destroy_r(g.h, boundary);
    GEOSGeom_destroy_r(g.h, area);
  }
  Region(const Region&) = delete;
  // 1 inside, 0 outside, -1 within `band` of the boundary.
  int classify(GEOSGeometry* pt, double band) const {
    if (GEOSPreparedDistanceWithin_r(g.h, pbound, pt, band)) return -1;
    return GEOSPreparedContains_r(g.h, parea, pt) ? 1 : 0;
  }
};

struct SampleStats {
  size_t tested = 0, excluded = 0, wrong = 0;
  std::string first_wrong;
};

// Samples the scene box: a regular grid plus points scattered around every
// vertex of the cleaned geometry (where repairs and joins live).
std::vector<prep::Point2> sample_points(const prep::SceneFeatures& s, double margin) {
  double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
  std::vector<prep::Point2> verts;
  auto add = [&](const prep::Ring& r) {
    for (const auto& p : r) {
      x0 = std::min(x0, p.x), y0 = std::min(y0, p.y), x1 = std::max(x1, p.x),
      y1 = std::max(y1, p.y);
      verts.push_back(p);
    }
  };
  for (const auto& p : s.polygons) {
    add(p.shell);
    for (const auto& h : p.holes) add(h);
  }
  for (const auto& l : s.lines) add(l.points);
  std::vector<prep::Point2> pts;
  if (verts.empty()) return pts;
  x0 -= margin, y0 -= margin, x1 += margin, y1 += margin;
  const int n = 150;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      pts.push_back({x0 + (i + 0.5) * (x1 - x0) / n, y0 + (j + 0.5) * (y1 - y0) / n});
  std::mt19937_64 rng(8);
  const size_t stride = std::max<size_t>(1, verts.size() / 2000);
  std::normal_distribution<double> N(0, std::max(margin, 0.05) * 0.5);
  for (size_t v = 0; v < verts.size(); v += stride)
    for (int k = 0; k < 8; ++k) pts.push_back({verts[v].x + N(rng), verts[v].y + N(rng)});
  return pts;
}

// One line of the oracle. Round and miter lines contain the disc of radius
// hw around every centreline point (a mitre join only adds to the round
// join); bevel lines contain the inscribed GEOS bevel buffer. No line
// reaches beyond hw from its centreline (hw / sin(20°) for miter, the mitre
// limit). Distances are exact, unlike a polygonised round buffer.
struct LineOracle {
  const Geos& g;
  GEOSGeometry* centre = nullptr;
  const GEOSPreparedGeometry* pcentre = nullptr;
  std::unique_ptr<Region> bevel;  // bevel lines only
  double hw = 0, hw_out = 0;
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // centreline box
  LineOracle(const Geos& geos, const prep::SceneLine& l, decal::CornerStyle corner) : g(geos) {
    centre = g.line(l);
    pcentre = GEOSPrepare_r(g.h, centre);
    hw = 0.5 * l.width;
    hw_out =
        corner == decal::CornerStyle::miter ? hw / std::sin(20.0 * M_PI / 180.0) * (1 + 1e-9) : hw;
    if (corner == decal::CornerStyle::bevel)
      bevel = std::make_unique<Region>(
          g, GEOSBufferWithStyle_r(g.h, centre, hw, 64, GEOSBUF_CAP_ROUND, GEOSBUF_JOIN_BEVEL, 5));
    GEOSGeom_getXMin_r(g.h, centre, &x0);
    GEOSGeom_getYMin_r(g.h, centre, &y0);
    GEOSGeom_getXMax_r(g.h, centre, &x1);
    GEOSGeom_getYMax_r(g.h, centre, &y1);
  }
  ~LineOracle() {
    GEOSPreparedGeom_destroy_r(g.h, pcentre);
    GEOSGeom_destroy_r(g.h, centre);
  }
  LineOracle(const LineOracle&) = delete;
  // 1 must be covered, 0 must not be, -1 undecided (band or between bounds).
  int classify(GEOSGeometry* pt, double px, double py, double band) const {
    const double r = hw_out + band;
    if (px < x0 - r || px > x1 + r || py < y0 - r || py > y1 + r) return 0;
    double d = 0;
    GEOSPreparedDistance_r(g.h, pcentre, pt, &d);
    if (d > r) return 0;
    if (bevel) return bevel->classify(pt, band) == 1 ? 1 : -1;
    return d < hw - band ? 1 : -1;
  }
};

void check_against_geos(const prep::SceneFeatures& scene, const decal::Package& pkg,
                        const std::string& name) {
  Geos g;
  const prep::StaticView view = prep::view_of(pkg);
  constexpr double kBand = 0.002;  // 2 mm
  double max_hw = 0;
  std::vector<GEOSGeometry*> polys;
  for (const auto& p : scene.polygons) polys.push_back(g.polygon(p));
  std::vector<std::unique_ptr<LineOracle>> lines;
  for (const auto& l : scene.lines) {
    lines.push_back(std::make_unique<LineOracle>(g, l, scene.layers[l.layer].style.corner));
    max_hw = std::max(max_hw, lines.back()->hw);
  }
  Region poly_region(g, g.unite(polys));
  const std::vector<prep::Point2> points = sample_points(scene, std::max(1.0, 3 * max_hw));
  if (points.empty()) {
    // Nothing was kept: the package must cover nothing.
    EXPECT_TRUE(scene.polygons.empty() && scene.lines.empty());
    return;
  }
  SampleStats st;
  for (const prep::Point2& p : points) {
    GEOSGeometry* pt = GEOSGeom_createPointFromXY_r(g.h, p.x, p.y);
    const int pc = poly_region.classify(pt, kBand);
    int lc = 0;  // 1 some line must cover, 0 no line may cover, -1 undecided
    for (const auto& l : lines) {
      const int c = l->classify(pt, p.x, p.y, kBand);
      if (c == 1) {
        lc = 1;
        break;
      }
      if (c == -1) lc = -1;
    }
    GEOSGeom_destroy_r(g.h, pt);
    const prep::EvalSample e = prep::evaluate(view, p.x, p.y);
    bool tested = false, ok = true;
    if (pc >= 0) {
      tested = true;
      ok = ok && (e.polygon_covered == (pc == 1));
    }
    if (lc >= 0) {
      tested = true;
      ok = ok && (e.line_covered == (lc == 1));
    }
    if (!tested) {
      ++st.excluded;
      continue;
    }
    ++st.tested;
    if (!ok && st.wrong++ == 0) {
      std::ostringstream m;
      m.precision(10);
      m << "(" << p.x << ", " << p.y << "): evaluator polygon " << e.polygon_covered << " line "
        << e.line_covered << "; GEOS polygon " << pc << " line " << lc;
      st.first_wrong = m.str();
    }
  }
  EXPECT_GT(st.tested, 10000u) << name;
  EXPECT_EQ(st.wrong, 0u) << name << ": " << st.wrong << " of " << st.tested
                          << " samples disagree with GEOS; first " << st.first_wrong;
}

class Hostile : public ::testing::TestWithParam<std::string> {};

TEST_P(Hostile, BehavesAsExpected) {
  const std::string name = GetParam();
  const json cases = load_json(corpus_dir() / "cases.json");
  ASSERT_TRUE(cases.is_array()) << "no corpus at " << corpus_dir()
                                << " (run tests/hostile/generate.py)";
  const json* c = nullptr;
  for (const json& x : cases)
    if (x["name"] == name) c = &x;
  const json& want = expected()[name];
  if (!c) {
    if (want.value("big", false))
      GTEST_SKIP() << name << ": big case, generated only with --big (label stress)";
    FAIL() << name << " is in expected.json but the generator did not write it";
  }
  const fs::path out = fs::path(HOSTILE_OUT_DIR) / name;
  fs::create_directories(out);
  const fs::path pkg_path = out / "out.decals", report_path = out / "report.json";
  fs::remove(pkg_path);
  fs::remove(report_path);
  std::vector<std::string> args{"build",    (*c)["path"].get<std::string>(),
                                "-o",       pkg_path.string(),
                                "--report", report_path.string(),
                                "-q"};
  if (!is_scene_file(*c)) {
    args.push_back("--kind");
    args.push_back((*c)["kind"].get<std::string>());
  }
  for (const auto& a : (*c)["args"]) args.push_back(a.get<std::string>());
  const prep::test::ToolRun r = run_case(args, out);
  const int want_exit = want.at("exit").get<int>();
  ASSERT_EQ(r.rc, want_exit) << name << " stderr: " << r.err;
  constexpr int kPartial = 4;  // prep::ExitCode::partial: --skip-failures dropped features
  if (want_exit != 0 && want_exit != kPartial) {
    const std::string msg = want.at("message").get<std::string>();
    EXPECT_NE(r.err.find(msg), std::string::npos) << name << ": stderr lacks \"" << msg << "\":\n"
                                                  << r.err;
    EXPECT_FALSE(fs::exists(pkg_path)) << name << ": a failed build left a package";
    return;
  }
  // The manifest, entry for entry.
  const json report = load_json(report_path);
  ASSERT_TRUE(report.is_object()) << name << ": no report";
  const json& got = report["manifest"]["entries"];
  const json& exp = want.at("entries");
  ASSERT_EQ(got.size(), exp.size()) << name << ": manifest entries " << got.dump(1);
  std::vector<bool> used(got.size(), false);
  for (const json& e : exp) {
    bool found = false;
    for (size_t i = 0; i < got.size() && !found; ++i) {
      const json& x = got[i];
      if (used[i] || x["fid"] != e["fid"] || x["action"] != e["action"]) continue;
      if (x["reason"].get<std::string>().find(e["reason"].get<std::string>()) == std::string::npos)
        continue;
      const bool has_area = !x["area_before"].is_null() && !x["area_after"].is_null();
      if (has_area != e.value("area", false)) continue;
      used[i] = found = true;
    }
    EXPECT_TRUE(found) << name << ": no manifest entry " << e.dump() << " in " << got.dump(1);
  }
  // No silent loss (ARCHITECTURE.md "Guarantees" 4): every feature read is kept, clipped
  // away or dropped, and each drop has its entry.
  const json& totals = report["manifest"]["totals"];
  EXPECT_EQ(totals["read"].get<uint64_t>(), totals["kept"].get<uint64_t>() +
                                                totals["clipped_away"].get<uint64_t>() +
                                                totals["dropped"].get<uint64_t>())
      << name << ": totals " << totals.dump();
  size_t dropped_entries = 0, failure_entries = 0;
  // The failure reason as formats/SPEC.md words it, with one of its stages.
  static const std::regex failure_reason("^failed in (read|project|clean|build): .+");
  for (const json& x : got) {
    if (x["action"] != "dropped" || x["part"] != -1) continue;
    ++dropped_entries;
    if (std::regex_search(x["reason"].get<std::string>(), failure_reason)) ++failure_entries;
  }
  EXPECT_EQ(totals["dropped"].get<size_t>(), dropped_entries)
      << name << ": totals " << totals.dump();
  // Exit 4 exactly when --skip-failures dropped a failing feature.
  EXPECT_EQ(report.value("skipped_failures", size_t(0)), failure_entries) << name;
  EXPECT_EQ(want_exit == kPartial, failure_entries > 0) << name;
  if (want.contains("notes")) {
    const std::string notes = report["manifest"]["notes"].dump();
    for (const auto& n : want["notes"])
      EXPECT_NE(notes.find(n.get<std::string>()), std::string::npos) << name << ": notes " << notes;
  }

  // The cleaned geometry of the same scene, in process, for the oracle.
  prep::BuildRequest dry;
  dry.dry_run = true;
  const prep::BuildResult cleaned = prep::run_build(scene_of(*c), dry);
  // Repairs that change the area: area_after is the area of what was kept
  // (GEOS on the cleaned polygons of that feature).
  Geos g;
  for (const json& x : got) {
    if (x["area_after"].is_null() || x["action"] != "repaired") continue;
    double sum = 0;
    for (const auto& p : cleaned.scene.polygons) {
      if (p.fid != x["fid"].get<int64_t>()) continue;
      GEOSGeometry* gp = g.polygon(p);
      double a = 0;
      GEOSArea_r(g.h, gp, &a);
      GEOSGeom_destroy_r(g.h, gp);
      sum += a;
    }
    const double after = x["area_after"].get<double>(), before = x["area_before"].get<double>();
    EXPECT_NEAR(sum, after, 1e-6 * after + 1e-9) << name << ": area_after vs the kept polygons";
    EXPECT_GT(std::fabs(after - before), 1e-6 * std::fabs(before))
        << name << ": area recorded but unchanged";
  }
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(pkg_path.string(), pkg)) << name << ": package does not open";
  check_against_geos(cleaned.scene, pkg, name);
}

INSTANTIATE_TEST_SUITE_P(Corpus, Hostile, ::testing::ValuesIn(case_names()),
                         [](const ::testing::TestParamInfo<std::string>& i) { return i.param; });

// Every generated case has an expectation, so a new case cannot go untested.
TEST(HostileCorpus, EveryGeneratedCaseHasAnExpectation) {
  const json cases = load_json(corpus_dir() / "cases.json");
  ASSERT_TRUE(cases.is_array()) << "no corpus at " << corpus_dir();
  for (const json& x : cases)
    EXPECT_TRUE(expected().contains(x["name"].get<std::string>()))
        << x["name"] << " has no expectation";
}

}  // namespace
