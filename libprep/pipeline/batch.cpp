// Batch mode of `decalprep build` (prep/pipeline.hpp "batch mode"): several
// scene files -> one package each, every scene in its own forked process,
// and one summary JSON. The batch's exit code is that of the first failed
// scene (input order), else 4 (partial) when skip_failures dropped features
// in some scene, 0 when all built.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "prep/error.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/pipeline.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kPartial = static_cast<int>(ExitCode::partial);

// A scene in flight: its entry in the result and its process.
struct RunningScene {
  BatchScene* scene = nullptr;
  pid_t pid = -1;
  Clock::time_point start;
};

// What a failed scene's log says: the scene's error line ("decalprep: ..."),
// else the last line that is not progress (plain: a '%' or "elapsed" at the
// end; json: an object), such as the watchdog's naming of a feature a killed
// scene was stuck on.
std::string error_line(const std::string& log_path) {
  std::FILE* f = std::fopen(log_path.c_str(), "r");
  if (!f) return "";
  std::string all, line, last;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) all.append(buf, n);
  std::fclose(f);
  std::istringstream in(all);
  std::string error;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line.rfind("decalprep: ", 0) == 0) error = line;
    const bool progress = line.find('%') != std::string::npos || line.front() == '{' ||
                          (line.size() >= 8 && line.compare(line.size() - 8, 8, " elapsed") == 0);
    if (!progress) last = line;
  }
  return error.empty() ? last : error;
}

// The scene files, in input order; a folder gives its *.toml sorted by name.
std::vector<std::string> list_scene_files(const std::vector<std::string>& inputs) {
  std::vector<std::string> scenes;
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      std::vector<std::string> found;
      for (const auto& e : fs::directory_iterator(in))
        if (e.path().extension() == ".toml") found.push_back(e.path().string());
      std::sort(found.begin(), found.end());
      if (found.empty())
        fail<usage_error>(kBuildStage, "folder " + in + " has no *.toml scene files");
      scenes.insert(scenes.end(), found.begin(), found.end());
    } else if (in.ends_with(".toml")) {
      scenes.push_back(in);
    } else {
      fail<usage_error>(kBuildStage,
                        "batch mode takes scene files (.toml) or folders of them; got " + in);
    }
  }
  return scenes;
}

// Plans the batch: the scene files, the output folder (created), and each
// scene's package, report and log paths, named after the scene file's stem.
std::vector<BatchScene> plan_scenes(const BatchRequest& request) {
  if (request.output_dir.empty()) fail<usage_error>(kBuildStage, "batch mode needs -o OUTDIR");
  const std::vector<std::string> files = list_scene_files(request.inputs);
  std::error_code ec;
  fs::create_directories(request.output_dir, ec);
  if (!fs::is_directory(request.output_dir))
    fail<output_error>(kBuildStage, "cannot create output folder " + request.output_dir);
  std::vector<BatchScene> scenes(files.size());
  std::set<std::string> stems;
  const fs::path dir(request.output_dir);
  for (size_t i = 0; i < files.size(); ++i) {
    const std::string stem = fs::path(files[i]).stem().string();
    if (!stems.insert(stem).second)
      fail<usage_error>(kBuildStage, "two scenes would both write " + stem + ".decals; rename one");
    scenes[i].scene = files[i];
    scenes[i].output = (dir / (stem + ".decals")).string();
    scenes[i].report = (dir / (stem + ".report.json")).string();
    scenes[i].log = (dir / (stem + ".log")).string();
  }
  return scenes;
}

// request.jobs, lowered (max_memory is per scene) to no more scenes side by
// side than the memory the kernel reports available holds at that limit each.
unsigned batch_jobs(const BatchRequest& request) {
  unsigned jobs = std::max(1u, request.jobs);
  if (request.max_memory.empty()) return jobs;
  const uint64_t per_job = parse_memory_size(request.max_memory);
  uint64_t available_kb = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string key, unit;
  uint64_t value = 0;
  while (meminfo >> key >> value >> unit)
    if (key == "MemAvailable:") available_kb = value;
  if (available_kb == 0) return jobs;
  const uint64_t fit = std::max<uint64_t>(1, available_kb * 1024 / per_job);
  if (fit >= jobs) return jobs;
  if (request.on_jobs_lowered)
    request.on_jobs_lowered(jobs, unsigned(fit), available_kb / 1048576.0);
  return unsigned(fit);
}

// One ordinary single-scene build, as `decalprep build SCENE.toml` with the
// batch's options; returns its exit code. Runs in the scene's process.
int build_one_scene(const BatchRequest& request, const BatchScene& item) {
  SceneRequest scene_request = request.scene;
  scene_request.input = item.scene;
  const SceneSpec scene = scene_spec(scene_request);
  BuildRequest build = request.build;
  build.output = item.output;
  build.report = item.report;
  build.max_memory = request.max_memory.empty() ? 0 : parse_memory_size(request.max_memory);
  // The log gets the scene's progress (plain lines unless json), and the
  // watchdog's lines.
  ProgressOptions po;
  po.mode = request.scene_progress;
  Progress progress(po);
  build.progress = &progress;
  const BuildResult result = run_build(scene, build);
  return static_cast<int>(build_exit_code(scene, result));
}

// The scene's process: its stderr goes to the log, and a failure ends it with
// the line and exit code `decalprep` itself would give.
[[noreturn]] void scene_process(const BatchRequest& request, const BatchScene& item) {
  if (std::FILE* log = std::freopen(item.log.c_str(), "w", stderr)) (void)log;
  int code = static_cast<int>(ExitCode::internal);
  try {
    code = build_one_scene(request, item);
  } catch (const error& e) {
    std::fprintf(stderr, "decalprep: %s\n", e.what());
    code = static_cast<int>(e.code());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "decalprep: out of memory\n");
    code = static_cast<int>(ExitCode::resource);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "decalprep: internal error: %s\n", e.what());
  }
  std::fflush(nullptr);
  _exit(code);
}

RunningScene start_scene(const BatchRequest& request, BatchScene& item) {
  RunningScene r{&item, -1, Clock::now()};
  r.pid = fork();
  if (r.pid < 0) throw error("build: fork failed", ExitCode::internal);
  if (r.pid == 0) scene_process(request, item);
  return r;
}

// Waits for any scene's process to end and records its exit code, time,
// peak memory and (failed) error line. Returns the scene, nullptr for a
// process that is not one of ours, nullopt when there is none to wait for.
std::optional<BatchScene*> collect_one(std::vector<RunningScene>& running) {
  int status = 0;
  struct rusage ru {};
  const pid_t done = wait4(-1, &status, 0, &ru);
  if (done < 0) return std::nullopt;
  for (auto r = running.begin(); r != running.end(); ++r) {
    if (r->pid != done) continue;
    BatchScene& s = *r->scene;
    s.seconds = std::chrono::duration<double>(Clock::now() - r->start).count();
    s.peak_rss_kb = ru.ru_maxrss;
    s.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (s.failed()) s.error = error_line(s.log);
    running.erase(r);
    return &s;
  }
  return nullptr;
}

// Runs every scene, at most `jobs` at once, started in input order.
void run_scenes(const BatchRequest& request, std::vector<BatchScene>& scenes, unsigned jobs) {
  std::vector<RunningScene> running;
  size_t next = 0, finished = 0;
  std::fflush(nullptr);
  while (next < scenes.size() || !running.empty()) {
    while (running.size() < jobs && next < scenes.size())
      running.push_back(start_scene(request, scenes[next++]));
    const std::optional<BatchScene*> ended = collect_one(running);
    if (!ended) break;
    if (*ended == nullptr) continue;
    ++finished;
    if (request.on_scene_done) request.on_scene_done(**ended, finished, scenes.size());
  }
}

// The summary JSON (prep/pipeline.hpp run_batch) at result.summary.
void write_summary(const BatchResult& result) {
  nlohmann::json summary;
  for (const BatchScene& s : result.scenes) {
    nlohmann::json e{{"scene", s.scene},
                     {"status", s.status()},
                     {"exit_code", s.exit_code},
                     {"seconds", s.seconds},
                     {"peak_rss_mib", s.peak_rss_kb / 1024.0}};
    if (!s.failed()) {
      // Partial too: skip_failures dropped features; the package was written.
      e["output"] = s.output;
      e["report"] = s.report;
      std::ifstream rin(s.report);
      const nlohmann::json r = nlohmann::json::parse(rin, nullptr, false);
      if (r.is_object() && r.contains("manifest"))
        e["counts"] = r["manifest"].value("totals", nlohmann::json());
    } else {
      e["error"] = s.error;
      e["log"] = s.log;
    }
    summary["packages"].push_back(e);
  }
  summary["built"] = result.scenes.size() - result.failed;
  summary["failed"] = result.failed;
  summary["partial"] = result.partial;
  summary["jobs"] = result.jobs;
  std::ofstream out(result.summary);
  out << summary.dump(2) << "\n";
  if (!out) fail<output_error>(kBuildStage, "cannot write the batch summary " + result.summary);
}

}  // namespace

BatchResult run_batch(const BatchRequest& request) {
  BatchResult result;
  result.scenes = plan_scenes(request);
  result.jobs = batch_jobs(request);
  run_scenes(request, result.scenes, result.jobs);
  int first_fail = 0;
  for (BatchScene& s : result.scenes) {
    if (s.partial()) ++result.partial;
    if (!s.failed()) continue;
    if (s.exit_code == -1) s.error = error_line(s.log);  // never collected
    ++result.failed;
    if (first_fail == 0) first_fail = s.exit_code;
  }
  result.summary = request.summary.empty()
                       ? (fs::path(request.output_dir) / "summary.json").string()
                       : request.summary;
  write_summary(result);
  result.exit_code = first_fail != 0 ? first_fail : result.partial > 0 ? kPartial : 0;
  return result;
}

}  // namespace prep
