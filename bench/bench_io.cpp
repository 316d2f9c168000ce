// bench_io — write and read throughput of .decals packages (MB/s of raw blob
// bytes) for codec none and zstd levels 1, 3, 9, on realistic blob data:
// int32 coordinates of random-walk lines (line_vertices), their per-vertex
// line index (line_vertex_line) and the (start, end) segment index pairs of
// the cell lists (cell_segments). 40 MiB raw per package.
//
// Write includes compression, checksums, and the atomic temp-file + fsync +
// rename of write_package. Read is Package::open with checksum verification
// (mmap for uncompressed packages; the file is in the page cache).
//
// Run (prints a table, writes CSV):
//   build/release/bench/bench_io --benchmark_out=bench/out/io.csv --benchmark_out_format=csv
// (create bench/out first). The `level` argument 0 means codec none.
//
// The level curve of whole models (bench/zstd_levels.py drives it):
//   bench_io --levels OUT.csv --scene FILE.toml [--scene ...] [--zstd 1,3,6,9,12,19]
//            [--threads N] [--repeat R]
// reads, cleans and builds each scene once (the real pipeline), then times
// write_model (stage 5 as the pipeline runs it: metadata, compression,
// checksums, the atomic write with fsync) at codec none and each zstd level,
// serial (tbb::global_control of 1 thread) and with N threads (default: all),
// the two alternating, median of R runs (default 3; 1 for runs over 10 s).
// One CSV row per scene, level and thread count: seconds, package bytes,
// raw bytes of the model's blobs (model_blobs: without the manifest entries
// and the metadata, which the package holds as well), raw / package, and
// what the (shared) machine gave at the time: `capacity`, the throughput of
// N independent single-threaded zstd jobs at once against one (the ceiling
// of the 1-thread / N-thread ratio; median of R, each beside a run pair),
// the 1-minute load average before the level's runs, and `predicted`, the
// ratio N idle cores would give (predicted_speedup; median of R; nan for
// codec none and runs over 10 s), and on the 1-thread rows `cpu_seconds`,
// the CPU time of the 1-thread runs (median of R), which the machine's load
// disturbs far less than their wall time.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "bench_scene.hpp"
#include "decal/reader.hpp"
#include "prep/model.hpp"
#include "prep/pipeline.hpp"
#include "prep/read.hpp"
#include "prep/write.hpp"

namespace {

struct Data {
  std::vector<std::array<int32_t, 2>> vertices;
  std::vector<uint32_t> vertex_line;
  std::vector<std::array<uint32_t, 2>> segments;
  std::vector<prep::BlobInput> blobs;
  uint64_t raw_bytes = 0;
};

const Data& data() {
  static const Data d = [] {
    Data r;
    constexpr size_t kVertices = size_t(2) << 20;  // 16 MiB of ivec2
    std::mt19937_64 rng(12345);
    std::normal_distribution<double> step(0.0, 4000.0);  // ~4 m steps, in mm quanta
    double x = 0, y = 0;
    uint32_t line = 0;
    for (size_t i = 0; i < kVertices; ++i) {
      if (rng() % 64 == 0) {  // a new line starts somewhere else
        ++line;
        x = static_cast<double>(rng() % 20'000'000) - 1e7;
        y = static_cast<double>(rng() % 20'000'000) - 1e7;
      }
      x += step(rng);
      y += step(rng);
      r.vertices.push_back({static_cast<int32_t>(x), static_cast<int32_t>(y)});
      r.vertex_line.push_back(line);
    }
    // Cell lists: consecutive segments, each listed in one or two cells.
    for (uint32_t i = 0; i + 1 < kVertices; ++i) {
      r.segments.push_back({i, i + 1});
      if (rng() % 4 == 0) r.segments.push_back({i, i + 1});
    }
    r.segments.resize(kVertices);
    r.blobs = {
        {decal::BlobId::line_vertices, decal::ElementType::ivec2, 8, r.vertices.size(),
         std::as_bytes(std::span(r.vertices))},
        {decal::BlobId::line_vertex_line, decal::ElementType::u32, 4, r.vertex_line.size(),
         std::as_bytes(std::span(r.vertex_line))},
        {decal::BlobId::cell_segments, decal::ElementType::uvec2, 8, r.segments.size(),
         std::as_bytes(std::span(r.segments))},
    };
    for (const auto& b : r.blobs) r.raw_bytes += b.bytes.size();
    return r;
  }();
  return d;
}

std::string bench_dir() {
  static const std::string dir = [] {
    std::string t = (std::filesystem::temp_directory_path() / "bench_io-XXXXXX").string();
    if (!mkdtemp(t.data())) std::abort();
    return t;
  }();
  return dir;
}

prep::WriteOptions options(int64_t level) {
  return level == 0 ? prep::WriteOptions{prep::Codec::none, 0}
                    : prep::WriteOptions{prep::Codec::zstd, int(level)};
}

void BM_Write(benchmark::State& state) {
  const Data& d = data();
  const std::string path = bench_dir() + "/w" + std::to_string(state.range(0)) + ".decals";
  for (auto _ : state) prep::write_package(path, "{}", d.blobs, options(state.range(0)));
  state.SetBytesProcessed(static_cast<int64_t>(d.raw_bytes) * state.iterations());
  state.counters["ratio"] =
      static_cast<double>(d.raw_bytes) / static_cast<double>(std::filesystem::file_size(path));
  state.counters["MB/s"] = benchmark::Counter(
      static_cast<double>(d.raw_bytes) / 1e6 * state.iterations(), benchmark::Counter::kIsRate);
}

void BM_Read(benchmark::State& state) {
  const Data& d = data();
  const std::string path = bench_dir() + "/r" + std::to_string(state.range(0)) + ".decals";
  prep::write_package(path, "{}", d.blobs, options(state.range(0)));
  for (auto _ : state) {
    decal::Package p;
    const decal::Status s = decal::Package::open(path, p);
    if (!s) state.SkipWithError(s.message.c_str());
    benchmark::DoNotOptimize(p.blobs().data());
  }
  state.SetBytesProcessed(static_cast<int64_t>(d.raw_bytes) * state.iterations());
  state.counters["MB/s"] = benchmark::Counter(
      static_cast<double>(d.raw_bytes) / 1e6 * state.iterations(), benchmark::Counter::kIsRate);
}

// Both directions at the same zstd levels.
void zstd_levels(benchmark::internal::Benchmark* b) {
  b->ArgName("level")->Arg(0)->Arg(1)->Arg(3)->Arg(9)->Unit(benchmark::kMillisecond)->UseRealTime();
}
BENCHMARK(BM_Write)->Apply(zstd_levels);
BENCHMARK(BM_Read)->Apply(zstd_levels);

// ------------------------------------------------------------ --levels --

std::vector<int> int_list(const char* text) {
  std::vector<int> v;
  for (const char* p = text; *p;) {
    char* end = nullptr;
    v.push_back(int(std::strtol(p, &end, 10)));
    p = *end == ',' ? end + 1 : end;
    if (end == p && *p) break;
  }
  return v;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

double seconds_of(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// What the machine gives `n` independent single-threaded jobs at this
// moment, against one (the ceiling of the serial/parallel ratio on a shared
// machine): `n` copies of one zstd job (level 3 over `sample`) on `n`
// threads at once, throughput against one copy alone.
double parallel_capacity(std::span<const std::byte> sample, int n) {
  const auto job = [&] {
    std::vector<std::byte> dst(ZSTD_compressBound(sample.size()));
    ZSTD_CCtx* c = ZSTD_createCCtx();
    ZSTD_CCtx_setParameter(c, ZSTD_c_compressionLevel, 3);
    benchmark::DoNotOptimize(
        ZSTD_compress2(c, dst.data(), dst.size(), sample.data(), sample.size()));
    ZSTD_freeCCtx(c);
  };
  const double one = seconds_of(job);
  const double all = seconds_of([&] {
    std::vector<std::thread> t;
    for (int i = 0; i < n; ++i) t.emplace_back(job);
    for (std::thread& x : t) x.join();
  });
  return n * one / all;
}

// The 1-thread / N-thread ratio that N idle cores would give write_model,
// from serial times alone (so that it holds on a loaded machine): each
// blob's own job in the writer (one single-threaded ZSTD_compress2, XXH64)
// timed alone; those jobs scheduled as the writer does (largest first, each
// to the first free thread); the rest of the 1-thread time `serial_s`
// (layout, metadata, the file write and fsync) added unchanged.
double predicted_speedup(const std::vector<prep::BlobInput>& blobs, int level, int n,
                         double serial_s) {
  std::vector<std::span<const std::byte>> order;
  for (const prep::BlobInput& b : blobs)
    if (!b.bytes.empty()) order.push_back(b.bytes);
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a.size() > b.size(); });
  ZSTD_CCtx* c = ZSTD_createCCtx();
  std::vector<std::byte> dst;
  std::vector<double> free_at(size_t(std::max(1, n)), 0.0);
  double jobs = 0;
  for (const std::span<const std::byte> raw : order) {
    const double t = seconds_of([&] {
      dst.resize(ZSTD_compressBound(raw.size()));
      ZSTD_CCtx_reset(c, ZSTD_reset_session_and_parameters);
      ZSTD_CCtx_setParameter(c, ZSTD_c_compressionLevel, level);
      ZSTD_CCtx_setParameter(c, ZSTD_c_checksumFlag, 1);
      ZSTD_CCtx_setParameter(c, ZSTD_c_contentSizeFlag, 1);
      const size_t k = ZSTD_compress2(c, dst.data(), dst.size(), raw.data(), raw.size());
      benchmark::DoNotOptimize(XXH64(dst.data(), ZSTD_isError(k) ? 0 : k, 0));
    });
    jobs += t;
    *std::min_element(free_at.begin(), free_at.end()) += t;
  }
  ZSTD_freeCCtx(c);
  const double makespan = *std::max_element(free_at.begin(), free_at.end());
  return serial_s / (std::max(0.0, serial_s - jobs) + makespan);
}

// CPU seconds of the calling thread: with one thread allowed, write_model
// runs on it alone, so this is the writer's work whatever else the shared
// machine runs.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

double load_average() {
  double load = 0;
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf", &load) != 1) load = 0;
    std::fclose(f);
  }
  return load;
}

int run_levels(int argc, char** argv) {
  std::string csv;
  std::vector<std::string> scenes;
  std::vector<int> levels{1, 3, 6, 9, 12, 19};
  int threads = int(tbb::info::default_concurrency()), repeat = 3;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--levels"))
      csv = argv[i + 1];
    else if (!std::strcmp(argv[i], "--scene"))
      scenes.push_back(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--zstd"))
      levels = int_list(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads"))
      threads = std::max(1, std::atoi(argv[i + 1]));
    else if (!std::strcmp(argv[i], "--repeat"))
      repeat = std::max(1, std::atoi(argv[i + 1]));
    else {
      std::fprintf(stderr, "bench_io: unknown option %s\n", argv[i]);
      return 2;
    }
  }
  if (csv.empty() || scenes.empty()) {
    std::fprintf(stderr, "bench_io --levels OUT.csv needs at least one --scene FILE.toml\n");
    return 2;
  }
  levels.insert(levels.begin(), 0);  // codec none first: the raw write floor
  FILE* out = std::fopen(csv.c_str(), "w");
  if (!out) {
    std::perror(csv.c_str());
    return 1;
  }
  std::fprintf(out,
               "scene,vertices,level,threads,seconds,bytes,raw_bytes,ratio,capacity,load1,"
               "predicted,cpu_seconds\n");
  for (const std::string& path : scenes) {
    using Clock = std::chrono::steady_clock;
    const prep::BuildSpec spec = prep::load_scene_file(path);
    prep::BuildRequest req;
    req.dry_run = true;
    const prep::SceneFeatures scene = prep::run_build(spec, req).scene;
    prep::ModelOptions mo = spec.model;
    mo.dem_assume_crs = spec.assume_crs;
    const prep::DecalModel model = prep::build_model(scene, mo, spec.dem);
    uint64_t raw = 0;
    std::span<const std::byte> sample;  // up to 8 MiB of the largest blob
    const std::vector<prep::BlobInput> blobs = prep::model_blobs(model);
    for (const prep::BlobInput& b : blobs) {
      raw += b.bytes.size();
      if (b.bytes.size() > sample.size())
        sample = b.bytes.first(std::min<size_t>(b.bytes.size(), 8 << 20));
    }
    const uint64_t vertices = bench::scene_vertices(scene);
    std::printf("\n%s: %llu vertices, %llu raw blob bytes (%.1f per vertex)\n", path.c_str(),
                (unsigned long long)vertices, (unsigned long long)raw,
                double(raw) / double(std::max<uint64_t>(vertices, 1)));
    std::printf("%6s %12s %12s %8s %10s %10s %8s %8s %6s %9s\n", "level", "bytes", "raw", "ratio",
                "1 thread s", "N thread s", "speedup", "capacity", "load", "predicted");
    const std::string pkg = bench_dir() + "/levels.decals";
    for (const int level : levels) {
      std::vector<double> t1, tn, cpu1, capacity, predicted;
      uint64_t bytes = 0;
      const double load = load_average();
      for (int r = 0; r < repeat; ++r) {
        capacity.push_back(parallel_capacity(sample, threads));
        for (std::vector<double>* times : {&t1, &tn}) {
          const tbb::global_control cap(tbb::global_control::max_allowed_parallelism,
                                        size_t(times == &t1 ? 1 : threads));
          const auto t0 = Clock::now();
          const double c0 = thread_cpu_seconds();
          prep::write_model(pkg, model, "", options(level));
          const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
          times->push_back(secs);
          if (times == &t1) cpu1.push_back(thread_cpu_seconds() - c0);
          bytes = std::filesystem::file_size(pkg);
          if (secs > 10) r = repeat;  // level 19 on 10^6 vertices: one run is enough
        }
        if (level > 0 && t1.back() < 10)
          predicted.push_back(predicted_speedup(blobs, level, threads, t1.back()));
      }
      const double s1 = median(t1), sn = median(tn), cap = median(capacity);
      const double pred = predicted.empty() ? std::nan("") : median(predicted);
      const double ratio = double(raw) / double(bytes);
      std::printf("%6s %12llu %12llu %8.2f %10.3f %10.3f %8.2f %8.2f %6.2f %9.2f\n",
                  level ? std::to_string(level).c_str() : "none", (unsigned long long)bytes,
                  (unsigned long long)raw, ratio, s1, sn, s1 / sn, cap, load, pred);
      std::fflush(stdout);
      for (const auto& [n, secs] : {std::pair{1, s1}, std::pair{threads, sn}})
        std::fprintf(out, "%s,%llu,%d,%d,%.4f,%llu,%llu,%.4f,%.3f,%.2f,%.3f,%.4f\n", path.c_str(),
                     (unsigned long long)vertices, level, n, secs, (unsigned long long)bytes,
                     (unsigned long long)raw, ratio, cap, load, pred,
                     n == 1 ? median(cpu1) : std::nan(""));
      std::fflush(out);
    }
  }
  std::fclose(out);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (!std::strcmp(argv[i], "--levels")) {
      const int rc = run_levels(argc, argv);
      std::filesystem::remove_all(bench_dir());
      return rc;
    }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::filesystem::remove_all(bench_dir());
  return 0;
}
