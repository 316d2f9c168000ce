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
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "decal/reader.hpp"
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

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::filesystem::remove_all(bench_dir());
  return 0;
}
