// bench_read — read + project + clean throughput (decalprep build --dry-run)
// against ogr2ogr -f FlatGeobuf of the same input, in the same run: the
// read-only floor. Inputs: the Liechtenstein and Monaco extracts, and a
// generated input of N vertices (default 10 million, FlatGeobuf, UTM 32N).
// Each command runs as a child process; wall time and peak RSS come from
// wait4(). Prints a Markdown table; target: decalprep <= 1.5x ogr2ogr.
//
// The two commands alternate (ours, ogr2ogr, ours, ...) and each keeps its
// best of R runs, so a burst of load on the shared machine hits both alike.
// Writes the table as CSV too (--csv, default DIR/read_floor.csv) and ends
// with one "ratio" line per input.
//
//   bench_read [--vertices N] [--data DIR] [--out DIR] [--tool PATH] [--repeat R] [--csv PATH]
//   (run from the repo root; DIR defaults: ../shared/data, bench/out/read)
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct RunStats {
  double wall_s = 0;
  double cpu_s = 0;  // user + system
  long peak_rss_kib = 0;
  int rc = -1;
};

// Runs argv as a child; wall time and the child's peak RSS.
RunStats run_child(const std::vector<std::string>& args, const std::string& log) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::fopen(log.c_str(), "w");
    if (f) {
      dup2(fileno(f), 1);
      dup2(fileno(f), 2);
    }
    execvp(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  struct rusage ru {};
  wait4(pid, &status, 0, &ru);
  RunStats s;
  s.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  s.peak_rss_kib = ru.ru_maxrss;
  s.cpu_s = double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
            1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  s.rc = WIFEXITED(status) ? WEXITSTATUS(status) : 128;
  return s;
}

RunStats best_of(int repeat, const std::vector<std::string>& args, const std::string& log,
                 const std::string& remove_before = "") {
  RunStats best;
  for (int i = 0; i < repeat; ++i) {
    if (!remove_before.empty()) fs::remove_all(remove_before);
    RunStats s = run_child(args, log);
    if (s.rc != 0) {
      std::fprintf(stderr, "command failed (rc %d), see %s\n", s.rc, log.c_str());
      std::exit(1);
    }
    if (i == 0 || s.wall_s < best.wall_s) best = s;
  }
  return best;
}

// Star-shaped polygons (valid by construction), ~200 vertices, some with a
// hole, in UTM 32N near Monaco; GeoJSON sequence, then FlatGeobuf via ogr2ogr.
void generate(const std::string& fgb, uint64_t vertices, const std::string& dir) {
  const std::string seq = dir + "/synthetic.geojsonl";
  {
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> u(0, 1);
    FILE* f = std::fopen(seq.c_str(), "w");
    uint64_t written = 0;
    int64_t id = 0;
    const double extent = 20000 * std::sqrt(double(vertices) / 1e7);
    while (written < vertices) {
      const double cx = 370000 + u(rng) * extent, cy = 4840000 + u(rng) * extent;
      const double r = 20 + 80 * u(rng);
      const int n = 150 + static_cast<int>(100 * u(rng));
      const bool hole = u(rng) < 0.3;
      std::fprintf(f,
                   "{\"type\":\"Feature\",\"id\":%lld,\"properties\":{},\"geometry\":{\"type\":"
                   "\"Polygon\",\"coordinates\":[[",
                   static_cast<long long>(id++));
      for (int i = 0; i <= n; ++i) {
        const double a = 2 * M_PI * (i % n) / n;
        const double rr = r * (0.8 + 0.2 * std::sin(7.0 * a + cx));
        std::fprintf(f, "%s[%.3f,%.3f]", i ? "," : "", cx + rr * std::cos(a),
                     cy + rr * std::sin(a));
      }
      written += n + 1;
      std::fprintf(f, "]");
      if (hole) {
        std::fprintf(f, ",[");
        for (int i = 0; i <= 16; ++i) {
          const double a = -2 * M_PI * (i % 16) / 16;
          std::fprintf(f, "%s[%.3f,%.3f]", i ? "," : "", cx + 0.3 * r * std::cos(a),
                       cy + 0.3 * r * std::sin(a));
        }
        std::fprintf(f, "]");
        written += 17;
      }
      std::fprintf(f, "]}}\n");
    }
    std::fclose(f);
  }
  RunStats s =
      run_child({"ogr2ogr", "-f", "FlatGeobuf", "-a_srs", "EPSG:32632", "-overwrite", fgb, seq},
                dir + "/generate.log");
  fs::remove(seq);
  if (s.rc != 0) {
    std::fprintf(stderr, "ogr2ogr failed generating %s\n", fgb.c_str());
    std::exit(1);
  }
}

uint64_t report_vertices(const std::string& report) {
  // "vertices_in": N in the totals (the last occurrence).
  std::ifstream in(report);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string t = ss.str();
  const std::string key = "\"vertices_in\": ";
  auto at = t.rfind(key);
  return at == std::string::npos ? 0 : std::strtoull(t.c_str() + at + key.size(), nullptr, 10);
}

struct Input {
  std::string name, source;
  std::vector<std::string> layers;  // empty: the first layer (synthetic)
  std::string crs;                  // scene frame; empty: local TM
};

}  // namespace

int main(int argc, char** argv) {
  uint64_t vertices = 10'000'000;
  std::string data = "../shared/data", out = "bench/out/read", tool;
  int repeat = 3;
  std::string csv_path;
  for (int i = 1; i + 1 < argc; i += 2) {
    std::string k = argv[i];
    if (k == "--vertices")
      vertices = std::strtoull(argv[i + 1], nullptr, 10);
    else if (k == "--data")
      data = argv[i + 1];
    else if (k == "--out")
      out = argv[i + 1];
    else if (k == "--tool")
      tool = argv[i + 1];
    else if (k == "--repeat")
      repeat = std::atoi(argv[i + 1]);
    else if (k == "--csv")
      csv_path = argv[i + 1];
  }
  if (tool.empty()) {
    // Next to this binary's build tree: build/<preset>/tools/decalprep/decalprep.
    tool = (fs::read_symlink("/proc/self/exe").parent_path().parent_path() /
            "tools/decalprep/decalprep")
               .string();
  }
  fs::create_directories(out);
  out = fs::absolute(out).string();
  if (csv_path.empty()) csv_path = out + "/read_floor.csv";
  std::ofstream csv(csv_path);
  csv << "input,vertices,wall_s,cpu_s,mvertices_per_s,rss_mib,ogr_wall_s,ogr_cpu_s,ogr_rss_mib,"
         "wall_ratio,cpu_ratio\n";
  std::vector<std::string> summary;

  std::vector<Input> inputs;
  for (auto [name, rel] :
       {std::pair{"liechtenstein", "liechtenstein/liechtenstein-2013-08-03.osm.pbf"},
        std::pair{"monaco", "monaco/monaco.osm.pbf"}}) {
    const std::string p = data + "/" + rel;
    if (fs::exists(p))
      inputs.push_back({name, fs::absolute(p).string(), {"multipolygons", "lines"}, ""});
    else
      std::fprintf(stderr, "skipping %s: %s missing\n", name, p.c_str());
  }
  const std::string fgb = out + "/synthetic-" + std::to_string(vertices) + ".fgb";
  if (!fs::exists(fgb)) {
    std::fprintf(stderr, "generating %s ...\n", fgb.c_str());
    generate(fgb, vertices, out);
  }
  const std::string syn = "synthetic " + std::to_string(vertices / 1'000'000) + "M";
  inputs.push_back({syn, fgb, {}, ""});
  // The same with the frame = the source CRS: no reprojection work, which
  // separates PROJ's share from read + clean.
  inputs.push_back({syn + " (frame = source CRS)", fgb, {}, "EPSG:32632"});

  std::printf(
      "| input | vertices | decalprep wall (s) | CPU (s) | Mvertices/s | peak RSS (MiB) | ogr2ogr "
      "wall (s) | CPU (s) | peak RSS (MiB) | wall ratio |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Input& in : inputs) {
    const std::string scene = out + "/scene.toml", report = out + "/report.json";
    {
      std::ofstream s(scene);
      s << "source = \"" << in.source << "\"\n";
      if (!in.crs.empty()) s << "crs = \"" << in.crs << "\"\n";
      if (in.layers.empty()) {
        s << "[[layer]]\nname = \"all\"\nkind = \"polygon\"\n";
      } else {
        s << "[[layer]]\nname = \"polygons\"\nlayer = \"multipolygons\"\nkind = \"polygon\"\n";
        s << "[[layer]]\nname = \"lines\"\nlayer = \"lines\"\nkind = \"line\"\n";
      }
    }
    std::vector<std::string> ogr = {"ogr2ogr",    "-f",           "FlatGeobuf",
                                    "-overwrite", out + "/floor", in.source};
    for (const auto& l : in.layers) ogr.push_back(l);
    RunStats ours, floor;
    for (int i = 0; i < repeat; ++i) {
      RunStats a = best_of(1, {tool, "build", scene, "--dry-run", "-q", "--report", report},
                           out + "/decalprep.log");
      RunStats b = best_of(1, ogr, out + "/ogr2ogr.log", out + "/floor");
      if (i == 0 || a.wall_s < ours.wall_s) ours = a;
      if (i == 0 || b.wall_s < floor.wall_s) floor = b;
    }
    const uint64_t v = report_vertices(report);
    const double ratio = ours.wall_s / floor.wall_s, cpu_ratio = ours.cpu_s / floor.cpu_s;
    std::printf("| %s | %llu | %.2f | %.2f | %.2f | %.0f | %.2f | %.2f | %.0f | %.2f |\n",
                in.name.c_str(), static_cast<unsigned long long>(v), ours.wall_s, ours.cpu_s,
                double(v) / ours.wall_s / 1e6, ours.peak_rss_kib / 1024.0, floor.wall_s,
                floor.cpu_s, floor.peak_rss_kib / 1024.0, ratio);
    std::fflush(stdout);
    char line[512];
    std::snprintf(line, sizeof line, "\"%s\",%llu,%.4f,%.4f,%.4f,%.1f,%.4f,%.4f,%.1f,%.3f,%.3f\n",
                  in.name.c_str(), static_cast<unsigned long long>(v), ours.wall_s, ours.cpu_s,
                  double(v) / ours.wall_s / 1e6, ours.peak_rss_kib / 1024.0, floor.wall_s,
                  floor.cpu_s, floor.peak_rss_kib / 1024.0, ratio, cpu_ratio);
    csv << line;
    csv.flush();
    std::snprintf(line, sizeof line, "ratio %s: %.2fx ogr2ogr wall (CPU %.2fx), target <= 1.5x: %s",
                  in.name.c_str(), ratio, cpu_ratio, ratio <= 1.5 ? "met" : "NOT met");
    summary.emplace_back(line);
  }
  std::printf("\n");
  for (const std::string& l : summary) std::printf("%s\n", l.c_str());
  std::printf("csv: %s\n", csv_path.c_str());
  return 0;
}
