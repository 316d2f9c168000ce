// Batch mode of `decalprep build` (prep/pipeline.hpp "batch mode"): several
// scene files -> one package each, every scene in its own forked process,
// and one summary JSON. The batch's exit code: 130 / 143 when SIGINT /
// SIGTERM stopped it; else that of the first failed scene (input order), a
// scene ended by a signal counting as 11 (killed); else 4 (partial) when
// skip_failures dropped features in some scene; 0 when all built.
#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "prep/error.hpp"
#include "prep/files.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/pipeline.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kPartial = static_cast<int>(ExitCode::partial);
constexpr int kKilled = static_cast<int>(ExitCode::killed);
// How long the stopped scenes get to clean up after the batch passed
// SIGINT/SIGTERM on, before SIGKILL.
constexpr auto kStopGrace = std::chrono::seconds(10);

// A scene in flight: its entry in the result and its process.
struct RunningScene {
  BatchScene* scene = nullptr;
  pid_t pid = -1;
  Clock::time_point start;
};

// ------------------------------------------------------------- signals --
// The first SIGINT/SIGTERM the batch received (0: none), and a pipe the
// handlers write a byte to so that the wait loop's poll() wakes up for a
// signal or an ended scene (SIGCHLD) with no race between checking and
// sleeping. The handlers only store an int and write(), which are
// async-signal-safe.
volatile sig_atomic_t g_stop_signal = 0;
int g_wake[2] = {-1, -1};

void wake_loop() {
  const int saved = errno;
  if (g_wake[1] >= 0) {
    const ssize_t n = ::write(g_wake[1], "x", 1);
    (void)n;  // a full pipe already wakes the loop
  }
  errno = saved;
}

extern "C" void on_stop_signal(int sig) {
  if (g_stop_signal == 0) g_stop_signal = sig;
  wake_loop();
}

extern "C" void on_child_ended(int) {
  wake_loop();
}

// Installs the batch's handlers for as long as it runs scenes and restores
// the previous ones after. SIGINT/SIGTERM that the process ignored when the
// batch began (nohup, a background job of a non-interactive shell) stay
// ignored, in the batch and in its scenes.
class BatchSignals {
 public:
  BatchSignals() {
    g_stop_signal = 0;
    if (::pipe2(g_wake, O_CLOEXEC | O_NONBLOCK) != 0)
      fail<error>(kBuildStage, "batch: cannot make a pipe: " + std::string(std::strerror(errno)),
                  ExitCode::internal);
    struct sigaction sa {};
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sa.sa_handler = on_stop_signal;
    hooked_int_ = hook(SIGINT, sa, old_int_);
    hooked_term_ = hook(SIGTERM, sa, old_term_);
    sa.sa_handler = on_child_ended;
    sa.sa_flags = SA_RESTART | SA_NOCLDSTOP;
    hooked_chld_ = ::sigaction(SIGCHLD, &sa, &old_chld_) == 0;
  }
  ~BatchSignals() {
    restore();
    ::close(g_wake[0]);
    ::close(g_wake[1]);
    g_wake[0] = g_wake[1] = -1;
  }
  BatchSignals(const BatchSignals&) = delete;
  BatchSignals& operator=(const BatchSignals&) = delete;

  // In a scene's process right after fork: the dispositions the process
  // had before the batch, and no wake pipe.
  void restore_in_child() {
    restore();
    ::close(g_wake[0]);
    ::close(g_wake[1]);
  }

  // Sleeps until a scene may have ended or a stop signal came, at most
  // `timeout_ms`.
  static void wait(int timeout_ms) {
    struct pollfd p {
      g_wake[0], POLLIN, 0
    };
    if (::poll(&p, 1, timeout_ms) > 0) {
      char buf[64];
      while (::read(g_wake[0], buf, sizeof buf) > 0) {
      }
    }
  }

 private:
  static bool hook(int sig, const struct sigaction& sa, struct sigaction& old) {
    if (::sigaction(sig, nullptr, &old) != 0) return false;
    if (old.sa_handler == SIG_IGN && !(old.sa_flags & SA_SIGINFO)) return false;
    return ::sigaction(sig, &sa, nullptr) == 0;
  }
  void restore() {
    if (hooked_int_) ::sigaction(SIGINT, &old_int_, nullptr);
    if (hooked_term_) ::sigaction(SIGTERM, &old_term_, nullptr);
    if (hooked_chld_) ::sigaction(SIGCHLD, &old_chld_, nullptr);
    hooked_int_ = hooked_term_ = hooked_chld_ = false;
  }
  struct sigaction old_int_ {
  }, old_term_{}, old_chld_{};
  bool hooked_int_ = false, hooked_term_ = false, hooked_chld_ = false;
};

// "SIGKILL" for SIGKILL; "signal N" for a number without a name.
std::string signal_name(int sig) {
  if (const char* abbrev = ::sigabbrev_np(sig)) return std::string("SIG") + abbrev;
  return "signal " + std::to_string(sig);
}

// ---------------------------------------------------------------- plan --

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

// Every file the scenes read that the batch can name before it starts: the
// scene files, and the sources and DEMs of those that parse (a scene that
// does not fails in its own process, with its own message).
std::vector<std::string> batch_inputs(const BatchRequest& request,
                                      const std::vector<std::string>& files) {
  std::vector<std::string> inputs = files;
  for (const std::string& file : files) {
    // A scene file that is a FIFO or a device would block the read; its
    // scene reports that itself.
    if (!special_file_kind(file).empty()) continue;
    try {
      SceneRequest r = request.scene;
      r.input = file;
      const BuildSpec scene = scene_spec(r);
      for (const LayerSpec& layer : scene.layers) inputs.push_back(layer.source);
      inputs.push_back(scene.dem);
      inputs.insert(inputs.end(), scene.dem_more.begin(), scene.dem_more.end());
    } catch (const error&) {
    }
  }
  return inputs;
}

// Plans the batch: the scene files, the output folder (created), and each
// scene's package, report and log paths, named after the scene file's stem.
// Every check runs before the folder is created, so a refusal writes nothing.
std::vector<BatchScene> plan_scenes(const BatchRequest& request, const std::string& summary) {
  if (request.output_dir.empty()) fail<usage_error>(kBuildStage, "batch mode needs -o OUTDIR");
  const std::vector<std::string> files = list_scene_files(request.inputs);
  struct stat st {};
  if (::stat(request.output_dir.c_str(), &st) == 0 && !S_ISDIR(st.st_mode)) {
    const std::string kind =
        S_ISREG(st.st_mode) ? std::string("a regular file") : special_file_kind(request.output_dir);
    fail<output_error>(kBuildStage, "batch output folder '" + request.output_dir +
                                        "' exists and is " + kind +
                                        ", not a folder (nothing was written)");
  }
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
  // The only files the batch writes: none may be a FIFO, a device, a folder
  // or one of the inputs (a log opened for writing would truncate it).
  const std::vector<std::string> inputs = batch_inputs(request, files);
  try {
    for (const BatchScene& s : scenes) {
      check_output_file(s.output, "batch package", inputs);
      check_output_file(s.report, "batch report", inputs);
      check_output_file(s.log, "batch log", inputs);
    }
    check_output_file(summary, "batch summary", inputs);
  } catch (const output_error& e) {
    fail<output_error>(kBuildStage, e.what());
  }
  std::error_code ec;
  fs::create_directories(request.output_dir, ec);
  if (!fs::is_directory(request.output_dir))
    fail<output_error>(kBuildStage, "cannot create output folder " + request.output_dir);
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

// --------------------------------------------------------------- scenes --

// One ordinary single-scene build, as `decalprep build SCENE.toml` with the
// batch's options; returns its exit code. Runs in the scene's process.
int build_one_scene(const BatchRequest& request, const BatchScene& item) {
  check_input_file(item.scene, "scene file");
  SceneRequest scene_request = request.scene;
  scene_request.input = item.scene;
  const BuildSpec scene = scene_spec(scene_request);
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

// Forks the scene's process. SIGINT/SIGTERM/SIGCHLD are blocked across the
// fork so that the child cannot take one through the batch's handlers
// before it has put the old ones back.
RunningScene start_scene(const BatchRequest& request, BatchScene& item, BatchSignals& signals) {
  RunningScene r{&item, -1, Clock::now()};
  sigset_t block, old;
  sigemptyset(&block);
  sigaddset(&block, SIGINT);
  sigaddset(&block, SIGTERM);
  sigaddset(&block, SIGCHLD);
  ::pthread_sigmask(SIG_BLOCK, &block, &old);
  const pid_t parent = ::getpid();
  r.pid = fork();
  if (r.pid == 0) {
    // Dies with the batch, whatever kills it; a batch that died before
    // prctl() is no longer the parent.
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) _exit(static_cast<int>(ExitCode::terminated));
    signals.restore_in_child();
    ::pthread_sigmask(SIG_SETMASK, &old, nullptr);
    scene_process(request, item);
  }
  const int fork_errno = errno;
  ::pthread_sigmask(SIG_SETMASK, &old, nullptr);
  if (r.pid < 0)
    fail<error>(kBuildStage, "batch: fork failed: " + std::string(std::strerror(fork_errno)),
                ExitCode::internal);
  return r;
}

// Records how a scene's process ended: exit code, signal, time, peak
// memory and (failed) error line.
void record_end(const RunningScene& r, int status, const struct rusage& ru) {
  BatchScene& s = *r.scene;
  s.seconds = std::chrono::duration<double>(Clock::now() - r.start).count();
  s.peak_rss_kb = ru.ru_maxrss;
  if (WIFSIGNALED(status)) {
    s.signal = WTERMSIG(status);
    s.exit_code = 128 + s.signal;
  } else {
    s.exit_code = WEXITSTATUS(status);
    // A scene that caught SIGINT/SIGTERM, cleaned up and exited 130/143
    // was stopped by that signal as much as one killed outright.
    if (s.exit_code == static_cast<int>(ExitCode::interrupted)) s.signal = SIGINT;
    if (s.exit_code == static_cast<int>(ExitCode::terminated)) s.signal = SIGTERM;
  }
  if (!s.failed()) return;
  const std::string line = error_line(s.log);
  if (s.signal == 0) {
    s.error = line;
  } else {
    s.error = "killed by " + signal_name(s.signal);
    if (!line.empty()) s.error += "; the log's last line: " + line;
  }
}

// Reaps one ended scene process without waiting. Returns its scene, or
// nullptr when none has ended (a process not in `running` is reaped and
// skipped).
BatchScene* reap_one(std::vector<RunningScene>& running) {
  for (;;) {
    int status = 0;
    struct rusage ru {};
    const pid_t done = ::wait4(-1, &status, WNOHANG, &ru);
    if (done <= 0) return nullptr;
    for (auto r = running.begin(); r != running.end(); ++r) {
      if (r->pid != done) continue;
      record_end(*r, status, ru);
      BatchScene* s = r->scene;
      running.erase(r);
      return s;
    }
  }
}

// Passes the batch's stop signal on to the running scenes and waits for
// them, SIGKILL after kStopGrace. A scene that still ends built or partial
// keeps that status.
void stop_scenes(std::vector<RunningScene>& running, int sig) {
  for (const RunningScene& r : running) ::kill(r.pid, sig);
  const auto deadline = Clock::now() + kStopGrace;
  bool killed = false;
  while (!running.empty()) {
    if (BatchScene* s = reap_one(running)) {
      if (s->failed()) s->interrupted = true;
      continue;
    }
    if (!killed && Clock::now() >= deadline) {
      for (const RunningScene& r : running) ::kill(r.pid, SIGKILL);
      killed = true;
    }
    BatchSignals::wait(100);
  }
}

// ------------------------------------------------------------- summary --

// The summary JSON (prep/pipeline.hpp run_batch). `counts` caches each
// finished scene's manifest totals, read from its report once.
class Summary {
 public:
  Summary(std::string path, size_t scenes) : path_(std::move(path)), counts_(scenes) {}

  // Replaces the summary file atomically: a temp file of a name no other
  // file has (mkstemp), renamed over it. Throws output_error.
  void write(const BatchResult& result, const char* state, const std::vector<bool>& started) {
    nlohmann::json summary;
    summary["state"] = state;
    if (result.signal != 0) summary["signal"] = signal_name(result.signal);
    summary["packages"] = nlohmann::json::array();
    size_t failed = 0, interrupted = 0, partial = 0, ended = 0;
    for (size_t i = 0; i < result.scenes.size(); ++i) {
      const BatchScene& s = result.scenes[i];
      nlohmann::json e{{"scene", s.scene}};
      if (s.exit_code == -1 && !s.interrupted) {
        // Not ended yet: only while the batch runs.
        e["status"] = started[i] ? "running" : "pending";
        e["log"] = s.log;
        summary["packages"].push_back(e);
        continue;
      }
      ++ended;
      e["status"] = s.status();
      e["exit_code"] = s.exit_code;
      e["seconds"] = s.seconds;
      e["peak_rss_mib"] = s.peak_rss_kb / 1024.0;
      if (s.signal != 0) e["signal"] = signal_name(s.signal);
      if (!s.failed()) {
        // Partial too: skip_failures dropped features; the package was written.
        e["output"] = s.output;
        e["report"] = s.report;
        if (!counts_[i]) {
          std::ifstream rin(s.report);
          const nlohmann::json r = nlohmann::json::parse(rin, nullptr, false);
          counts_[i] = r.is_object() && r.contains("manifest")
                           ? r["manifest"].value("totals", nlohmann::json())
                           : nlohmann::json();
        }
        if (!counts_[i]->is_null()) e["counts"] = *counts_[i];
        if (s.partial()) ++partial;
      } else {
        e["error"] = s.error;
        e["log"] = s.log;
        ++failed;
        if (s.interrupted) ++interrupted;
      }
      summary["packages"].push_back(e);
    }
    summary["built"] = ended - failed;
    summary["failed"] = failed;
    summary["partial"] = partial;
    summary["interrupted"] = interrupted;
    summary["jobs"] = result.jobs;
    replace(summary.dump(2) + "\n");
  }

 private:
  // Through a temp file of its own and a rename (write_text_file), so a
  // reader, or a batch stopped meanwhile, never leaves half a summary.
  void replace(const std::string& text) { write_text_file(path_, text); }
  std::string path_;
  std::vector<std::optional<nlohmann::json>> counts_;
};

// Runs every scene, at most `jobs` at once, started in input order, and
// rewrites the summary as each ends. Returns the signal that stopped the
// batch, 0 when every scene ran.
int run_scenes(const BatchRequest& request, BatchResult& result, Summary& summary) {
  std::vector<BatchScene>& scenes = result.scenes;
  std::vector<bool> started(scenes.size(), false);
  std::vector<RunningScene> running;
  size_t next = 0, finished = 0;
  std::fflush(nullptr);
  BatchSignals signals;
  summary.write(result, "running", started);
  while ((next < scenes.size() || !running.empty()) && g_stop_signal == 0) {
    while (running.size() < result.jobs && next < scenes.size() && g_stop_signal == 0) {
      started[next] = true;
      running.push_back(start_scene(request, scenes[next++], signals));
    }
    BatchScene* ended = reap_one(running);
    if (!ended) {
      BatchSignals::wait(1000);  // a bound, should SIGCHLD not have been hooked
      continue;
    }
    ++finished;
    if (g_stop_signal != 0) break;  // the scene is judged with the stop below
    if (request.on_scene_done) request.on_scene_done(*ended, finished, scenes.size());
    try {
      summary.write(result, "running", started);
    } catch (const output_error&) {
      // The summary at the end is the one that must be written; it throws.
    }
  }
  const int sig = g_stop_signal;
  if (sig == 0) return 0;
  stop_scenes(running, sig);
  for (BatchScene& s : scenes) {
    // Scenes never started, and those the signal reached first (a terminal's
    // Ctrl-C goes to the whole process group).
    if (s.exit_code == -1 || (s.failed() && (s.signal == SIGINT || s.signal == SIGTERM)))
      s.interrupted = true;
    if (!s.interrupted) continue;
    if (s.exit_code == -1)
      s.error = "not started: the batch was stopped by " + signal_name(sig);
    else
      s.error = "stopped with the batch by " + signal_name(sig);
  }
  return sig;
}

}  // namespace

BatchResult run_batch(const BatchRequest& request) {
  BatchResult result;
  result.summary = request.summary.empty()
                       ? (fs::path(request.output_dir) / "summary.json").string()
                       : request.summary;
  result.scenes = plan_scenes(request, result.summary);
  result.jobs = batch_jobs(request);
  Summary summary(result.summary, result.scenes.size());
  result.signal = run_scenes(request, result, summary);
  int first_fail = 0;
  for (BatchScene& s : result.scenes) {
    if (s.partial()) ++result.partial;
    if (!s.failed()) continue;
    ++result.failed;
    if (s.interrupted) ++result.interrupted;
    if (first_fail == 0) first_fail = s.signal != 0 ? kKilled : s.exit_code;
  }
  summary.write(result, result.signal != 0 ? "interrupted" : "finished",
                std::vector<bool>(result.scenes.size(), true));
  if (result.signal == SIGINT)
    result.exit_code = static_cast<int>(ExitCode::interrupted);
  else if (result.signal != 0)
    result.exit_code = static_cast<int>(ExitCode::terminated);
  else
    result.exit_code = first_fail != 0 ? first_fail : result.partial > 0 ? kPartial : 0;
  return result;
}

}  // namespace prep
