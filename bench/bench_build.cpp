// bench_build — build time, peak RSS, package size and per-point query cost
// of the static decal structures, adaptive grid vs the thesis 500x500 grid in
// the same run. Prints a table; not a unit test.
//
//   bench_build [--vertices N] [--samples N] [--threads N] [--target T]
//               [--only parcels,roads,big] [--scene FILE.toml ...] [--grids 500,1000]
//
// Datasets:
//   parcels: 3*10^5 vertices of clustered star polygons (hole, island);
//   roads:   3*10^5 vertices of clustered polylines (round, miter, bevel);
//   big:     a clustered polygon set of ~N vertices (default 10^6;
//            --vertices 10000000 for the 10^7 figure: about 3 GB, minutes);
//   --scene: a scene file (samples/monaco/scene.toml,
//            bench/scenes/liechtenstein.toml), read and cleaned once through
//            the real pipeline; dynamic (terrain) lines are dropped, as they
//            are not part of the static structures measured here.
// With --scene and no --only, only the scenes run.
//
// Per dataset, one row per grid: the adaptive default first, then each
// --grids N (N x N cells; default 500, the thesis grid). "build s" is
// build_model alone (stage 4; reading and cleaning are printed once per
// scene); "peak MiB" is the process's peak RSS during that build and its
// sampling (VmHWM, reset through /proc/self/clear_refs before each build;
// the scene held in memory is included). "bytes" are the raw static blobs
// (what a renderer uploads; BENCH_BLOBS=1 lists them). Query cost: covered
// points sampled uniformly over the grid, counters of prep::evaluate. The
// last line per dataset gives adaptive / 500x500 ratios of bytes and mean
// tests (all counters summed).
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bench_scene.hpp"
#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "prep/pipeline.hpp"
#include "prep/read.hpp"
#include "prep/write.hpp"

namespace {

prep::LayerSpec layer(const char* name, prep::DecalKind kind, decal::CornerStyle corner) {
  prep::LayerSpec l;
  l.name = name;
  l.kind = kind;
  l.style.corner = corner;
  l.style.color.rgba = 0xc0406080u;
  return l;
}

prep::Ring star(std::mt19937_64& rng, double cx, double cy, double r0, double r1, int n, bool cw) {
  std::uniform_real_distribution<double> rad(r0, r1), jit(-0.3, 0.3);
  prep::Ring r;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * (i + 0.5 + jit(rng)) / n, rr = rad(rng);
    r.push_back({cx + rr * std::cos(a), cy + rr * std::sin(a)});
  }
  if (cw) std::reverse(r.begin(), r.end());
  return r;
}

// A synthetic scene of `layers` and features from `add(s, fid)`, called
// with fid 0, 1, ... until the features hold `vertices`; each call adds one
// feature to s and returns its vertex count.
template <class Add>
prep::SceneFeatures generate(uint64_t vertices, std::vector<prep::LayerSpec> layers, Add&& add) {
  prep::SceneFeatures s;
  s.layers = std::move(layers);
  for (uint64_t v = 0, fid = 0; v < vertices; ++fid) v += add(s, int64_t(fid));
  return s;
}

// Clustered polygons: a city-like density gradient (most polygons near the
// centre) so that the adaptive grid has something to adapt to.
prep::SceneFeatures parcels(uint64_t vertices, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0, 1);
  std::uniform_int_distribution<int> nv(6, 40);
  const auto add = [&](prep::SceneFeatures& s, int64_t fid) -> uint64_t {
    const double cx = 3000 * N(rng), cy = 2000 * N(rng);
    const double size = 8 + 30 * std::abs(N(rng));
    prep::ScenePolygon p;
    p.shell = star(rng, cx, cy, 0.6 * size, size, fid % 50 == 0 ? 400 : nv(rng), false);
    if (fid % 3 == 0) p.holes.push_back(star(rng, cx, cy, 0.15 * size, 0.3 * size, nv(rng), true));
    const uint64_t v = p.shell.size() + (p.holes.empty() ? 0 : p.holes[0].size());
    p.fid = fid;
    p.area = size * size;
    s.polygons.push_back(std::move(p));
    return v;
  };
  return generate(vertices, {layer("parcels", prep::DecalKind::polygon, decal::CornerStyle::round)},
                  add);
}

prep::SceneFeatures roads(uint64_t vertices, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0, 1);
  std::uniform_real_distribution<double> U(0, 1);
  const auto add = [&](prep::SceneFeatures& s, int64_t fid) -> uint64_t {
    prep::SceneLine l;
    double x = 3000 * N(rng), y = 2000 * N(rng), a = 2 * M_PI * U(rng);
    const int n = 2 + int(40 * U(rng));
    for (int k = 0; k < n; ++k) {
      l.points.push_back({x, y});
      const double len = 5 + 40 * U(rng);
      x += len * std::cos(a);
      y += len * std::sin(a);
      a += 0.6 * N(rng);
      l.length += len;
    }
    l.layer = uint32_t(fid % 3);
    l.width = 3 + 10 * U(rng);
    l.fid = fid;
    const uint64_t v = l.points.size();
    s.lines.push_back(std::move(l));
    return v;
  };
  return generate(vertices,
                  {layer("round", prep::DecalKind::line, decal::CornerStyle::round),
                   layer("miter", prep::DecalKind::line, decal::CornerStyle::miter),
                   layer("bevel", prep::DecalKind::line, decal::CornerStyle::bevel)},
                  add);
}

// Raw static blob bytes; `index` receives the grid-dependent part (cell
// lists and per-cell BVHs), the rest is geometry (lines, quad-trees).
uint64_t static_bytes(const prep::DecalModel& m, uint64_t& index) {
  uint64_t b = 0;
  index = 0;
  const bool detail = std::getenv("BENCH_BLOBS") != nullptr;
  for (const prep::BlobInput& blob : prep::model_blobs(m, false)) {
    const std::string name(decal::find_blob_info(blob.id)->name);
    b += blob.bytes.size();
    if (name.rfind("cell_", 0) == 0 || name.find("_bvh_") != std::string::npos)
      index += blob.bytes.size();
    if (detail) std::printf("   %-20s %12zu\n", name.c_str(), blob.bytes.size());
  }
  return b;
}

struct Stat {
  double mean = 0, p99 = 0;
};
Stat stat(std::vector<uint32_t>& v) {
  if (v.empty()) return {};
  double s = 0;
  for (uint32_t x : v) s += x;
  std::sort(v.begin(), v.end());
  return {s / double(v.size()), double(v[std::min(v.size() - 1, size_t(0.99 * double(v.size())))])};
}

uint32_t g_target = 0;
std::vector<uint32_t> g_grids{500};

// Peak RSS (VmHWM) of this process in MiB; reset_peak_rss() starts a new
// measurement (Linux >= 4.0: "5" > /proc/self/clear_refs).
double peak_rss_mib() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}
void reset_peak_rss() {
  malloc_trim(0);
  std::ofstream("/proc/self/clear_refs") << "5";
}

struct Row {
  uint64_t bytes = 0;
  double mean_all = 0;
};

Row measure(const prep::SceneFeatures& scene, const prep::ModelOptions& o, uint64_t nv,
            uint64_t samples) {
  reset_peak_rss();
  const auto t0 = std::chrono::steady_clock::now();
  const prep::DecalModel m = prep::build_model(scene, o);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  uint64_t index = 0;
  const uint64_t bytes = static_bytes(m, index);
  const prep::StaticView v = prep::view_of(m);
  std::mt19937_64 rng(77);
  const double x0 = m.grid.origin_x * decal::kQuantumMetres,
               y0 = m.grid.origin_y * decal::kQuantumMetres;
  const double w = double(m.grid.cell_w) * m.grid.nx * decal::kQuantumMetres;
  const double h = double(m.grid.cell_h) * m.grid.ny * decal::kQuantumMetres;
  std::uniform_real_distribution<double> X(x0, x0 + w), Y(y0, y0 + h);
  std::vector<uint32_t> bvh, qt, edge, seg, all;
  // Sample covered points: uniformly over the grid, keeping covered ones.
  for (uint64_t i = 0; i < samples * 200 && bvh.size() < samples; ++i) {
    prep::EvalCounters c;
    const prep::EvalSample s = prep::evaluate(v, X(rng), Y(rng), &c);
    if (!s.line_covered && !s.polygon_covered) continue;
    bvh.push_back(uint32_t(c.bvh_nodes));
    qt.push_back(uint32_t(c.qt_nodes));
    edge.push_back(uint32_t(c.edge_tests));
    seg.push_back(uint32_t(c.segment_tests));
    all.push_back(uint32_t(c.bvh_nodes + c.qt_nodes + c.edge_tests + c.segment_tests));
  }
  const size_t covered = bvh.size();
  Stat sb = stat(bvh), sq = stat(qt), se = stat(edge), ss = stat(seg), sa = stat(all);
  char grid[32];
  std::snprintf(grid, sizeof grid, "%ux%u", m.grid.nx, m.grid.ny);
  std::printf(
      "%-10s %9llu %8.2f %8.1f %11llu %9.1f %8zu | %8.2f %5.0f | %8.2f %5.0f | %8.2f %5.0f | %8.2f "
      "%5.0f | %8.2f %5.0f  index %.1f B/v\n",
      grid, (unsigned long long)m.grid.nx * m.grid.ny, secs, peak_rss_mib(),
      (unsigned long long)bytes, double(bytes) / double(nv), covered, sb.mean, sb.p99, sq.mean,
      sq.p99, se.mean, se.p99, ss.mean, ss.p99, sa.mean, sa.p99, double(index) / double(nv));
  std::fflush(stdout);
  return {bytes, sa.mean};
}

void run(const std::string& name, const prep::SceneFeatures& scene, uint64_t samples,
         unsigned threads) {
  const uint64_t nv = bench::scene_vertices(scene);
  std::printf("\n== %s: %zu polygons, %zu lines, %llu input vertices\n", name.c_str(),
              scene.polygons.size(), scene.lines.size(), (unsigned long long)nv);
  std::printf("%-10s %9s %8s %8s %11s %9s %8s | %-14s | %-14s | %-14s | %-14s | %-14s\n", "grid",
              "cells", "build s", "peak MiB", "bytes", "B/vertex", "covered", "BVH mean/p99",
              "QT mean/p99", "edges mean/p99", "segs mean/p99", "all mean/p99");
  prep::ModelOptions o;
  o.threads = threads;
  if (g_target) o.target_per_cell = g_target;
  const Row adaptive = measure(scene, o, nv, samples);
  for (uint32_t n : g_grids) {
    o.grid_nx = o.grid_ny = n;
    const Row fixed = measure(scene, o, nv, samples);
    std::printf("adaptive / %ux%u: bytes %.3f, mean tests %.3f\n", n, n,
                double(adaptive.bytes) / double(fixed.bytes), adaptive.mean_all / fixed.mean_all);
  }
  std::fflush(stdout);
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  uint64_t big = 1'000'000, samples = 200'000;
  unsigned threads = 0;
  std::vector<std::string> only, scenes;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--vertices"))
      big = std::stoull(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--samples"))
      samples = std::stoull(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads"))
      threads = unsigned(std::stoul(argv[i + 1]));
    else if (!std::strcmp(argv[i], "--target"))
      g_target = uint32_t(std::stoul(argv[i + 1]));
    else if (!std::strcmp(argv[i], "--only"))
      only = split(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--scene"))
      scenes.push_back(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--grids")) {
      g_grids.clear();
      for (const std::string& g : split(argv[i + 1])) g_grids.push_back(uint32_t(std::stoul(g)));
    } else {
      std::fprintf(stderr, "bench_build: unknown option %s\n", argv[i]);
      return 2;
    }
  }
  if (only.empty() && scenes.empty()) only = {"parcels", "roads", "big"};
  auto want = [&](const char* n) { return std::find(only.begin(), only.end(), n) != only.end(); };
  for (const std::string& path : scenes) {
    const auto t0 = std::chrono::steady_clock::now();
    prep::BuildRequest req;
    req.dry_run = true;
    prep::SceneFeatures scene = prep::run_build(prep::load_scene_file(path), req).scene;
    scene.dynamic_lines.clear();
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("\nread + clean %s: %.2f s, peak RSS so far %.1f MiB\n", path.c_str(), secs,
                peak_rss_mib());
    run(path, scene, samples, threads);
  }
  if (want("parcels")) run("parcels (clustered polygons)", parcels(300'000, 1), samples, threads);
  if (want("roads")) run("roads (clustered lines)", roads(300'000, 2), samples, threads);
  if (want("big")) run("big polygon set", parcels(big, 3), samples, threads);
  return 0;
}
