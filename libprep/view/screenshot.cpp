// screenshot.cpp — `decalprep view --screenshot` (prep/view.hpp): the view
// server with three POST routes, and a headless Chromium on its page. The
// browser runs in a process group of its own (its GPU, renderer and utility
// processes inherit it), so stopping it is one kill of the group; its
// profile is a fresh temp folder, removed afterwards.
#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <csignal>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include "prep/error.hpp"
#include "prep/files.hpp"
#include "prep/stage_error.hpp"
#include "prep/view.hpp"
#include "server.hpp"

namespace prep::view {

namespace shot {
namespace {

namespace fs = std::filesystem;
using detail::kViewStage;

// What the page POSTed, guarded by `m`.
struct Received {
  std::mutex m;
  std::condition_variable cv;
  std::string frame, decals, error, notes, stats;
  bool have_frame = false, have_decals = false, failed = false;
};

constexpr size_t kMaxErrorText = size_t{64} * 1024;

bool executable_file(const std::string& p) {
  struct stat st {};
  return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(p.c_str(), X_OK) == 0;
}

// `name` in a folder of $PATH, or empty.
std::string on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/local/bin:/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':'))
    if (!dir.empty() && executable_file(dir + "/" + name)) return dir + "/" + name;
  return {};
}

// The POST routes: pixels of exactly `bytes` bytes from 127.0.0.1 only.
void add_post_routes(httplib::Server& server, Received& got, size_t bytes) {
  auto pixels = [&got, bytes](std::string Received::*slot, bool Received::*have) {
    return [&got, bytes, slot, have](const httplib::Request& req, httplib::Response& res) {
      if (req.remote_addr != "127.0.0.1") {
        res.status = 403;
        return;
      }
      if (req.body.size() != bytes) {
        res.status = 400;
        res.set_content("expected " + std::to_string(bytes) + " bytes (width * height * 4), got " +
                            std::to_string(req.body.size()) + "\n",
                        "text/plain");
        return;
      }
      const std::lock_guard lock(got.m);
      got.*slot = req.body;
      got.*have = true;
      got.cv.notify_all();
      res.set_content("ok\n", "text/plain");
    };
  };
  server.Post("/__shot/frame", pixels(&Received::frame, &Received::have_frame));
  server.Post("/__shot/decals", pixels(&Received::decals, &Received::have_decals));
  // A text route: from 127.0.0.1 only, `take` stores the body (at most
  // kMaxErrorText bytes) under the lock.
  auto text = [&got](auto take) {
    return [&got, take](const httplib::Request& req, httplib::Response& res) {
      if (req.remote_addr != "127.0.0.1") {
        res.status = 403;
        return;
      }
      const std::lock_guard lock(got.m);
      take(req.body.substr(0, kMaxErrorText));
      res.set_content("ok\n", "text/plain");
    };
  };
  server.Post("/__shot/error", text([&got](std::string body) {
                got.error = body.empty() ? "(no message)" : std::move(body);
                got.failed = true;
                got.cv.notify_all();
              }));
  // What the page says the frame leaves out (layers it does not draw), one
  // note per POST, sent before the frame; printed on stderr.
  server.Post("/__shot/note", text([&got](const std::string& body) {
                if (got.notes.size() < kMaxErrorText) got.notes += body + "\n";
              }));
  // The page's frame times (JSON, web/viewer/viewer.js), sent before the frame.
  server.Post("/__shot/stats", text([&got](std::string body) { got.stats = std::move(body); }));
  // The pixels of the largest frame, and no more.
  server.set_payload_max_length(std::max<size_t>(bytes, kMaxErrorText));
}

// A fresh folder for Chromium's profile.
fs::path make_profile_dir() {
  std::string templ = (fs::temp_directory_path() / "decalprep-chromium-XXXXXX").string();
  if (!::mkdtemp(templ.data()))
    fail<output_error>(kViewStage, "cannot create a temp folder for Chromium's profile (" + templ +
                                       "): " + std::strerror(errno));
  return templ;
}

// Starts Chromium on `url` in a process group of its own. Its stdout and
// stderr go to `log` (or to this process's stderr with --verbose).
pid_t start_chromium(const ShotOptions& shot, const std::string& url, const fs::path& profile,
                     const fs::path& log) {
  const std::vector<std::string> args{
      shot.chromium,
      "--headless",
      "--no-sandbox",
      "--enable-unsafe-webgpu",
      "--enable-unsafe-swiftshader",
      "--user-data-dir=" + profile.string(),
      "--window-size=" + std::to_string(shot.width) + "," + std::to_string(shot.height),
      "--no-first-run",
      "--no-default-browser-check",
      "--disable-extensions",
      "--enable-logging=stderr",
      "--v=0",
      url};
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const int out = shot.verbose
                      ? STDERR_FILENO
                      : ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  const int null_in = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  if (out < 0 || null_in < 0)
    fail<output_error>(kViewStage, "cannot open " + log.string() + " or /dev/null for Chromium");
  const pid_t pid = ::fork();
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec.
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);  // watch_interrupts() blocked them
    ::dup2(null_in, STDIN_FILENO);
    ::dup2(out, STDOUT_FILENO);
    ::dup2(out, STDERR_FILENO);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  const int fork_errno = errno;
  if (out != STDERR_FILENO) ::close(out);
  ::close(null_in);
  if (pid < 0)
    fail<error>(kViewStage,
                std::string("cannot start Chromium: fork: ") + std::strerror(fork_errno),
                ExitCode::browser);
  ::setpgid(pid, pid);  // as the child does: whichever runs first
  return pid;
}

// Stops Chromium's whole process group: SIGTERM, then SIGKILL after 3 s.
// Returns once the browser process is reaped.
void stop_chromium(pid_t pid, bool& reaped) {
  ::kill(-pid, SIGTERM);
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  while (!reaped && std::chrono::steady_clock::now() < until) {
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid) reaped = true;
    if (!reaped) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ::kill(-pid, SIGKILL);  // what is left of the group
  if (!reaped) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    reaped = true;
  }
}

// The last `n` lines of a text file, indented, or empty.
std::string tail_lines(const fs::path& file, size_t n) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    lines.push_back(line);
    if (lines.size() > n) lines.erase(lines.begin());
  }
  std::string out;
  for (const std::string& l : lines) out += "\n  " + l;
  return out;
}

std::string exit_text(int status) {
  if (WIFEXITED(status)) return "with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return "killed by signal " + std::to_string(WTERMSIG(status));
  return "";
}

// How the wait ended.
enum class Outcome { pixels, page_error, exited, timeout };

// Waits for the pixels, the page's error, Chromium's exit or the timeout.
Outcome wait_for_page(const ShotOptions& shot, Received& got, pid_t pid, bool& reaped,
                      int& status) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(shot.timeout_s);
  std::unique_lock lock(got.m);
  while (true) {
    if (got.failed) return Outcome::page_error;
    if (got.have_frame && (!shot.decals || got.have_decals)) return Outcome::pixels;
    if (std::chrono::steady_clock::now() >= deadline) return Outcome::timeout;
    if (!reaped && ::waitpid(pid, &status, WNOHANG) == pid) reaped = true;
    // A page that POSTed just before the browser ended still counts.
    if (reaped) {
      got.cv.wait_for(lock, std::chrono::milliseconds(200));
      if (got.failed) return Outcome::page_error;
      if (got.have_frame && (!shot.decals || got.have_decals)) return Outcome::pixels;
      return Outcome::exited;
    }
    got.cv.wait_for(lock, std::chrono::milliseconds(100));
  }
}

// Removes Chromium's profile folder; what cannot be removed is left.
void remove_profile(const fs::path& profile) {
  std::error_code ec;
  fs::remove_all(profile, ec);
}

}  // namespace
}  // namespace shot

std::optional<std::string> find_chromium() {
  if (const char* env = std::getenv("DECALPREP_CHROMIUM"); env && *env) {
    if (shot::executable_file(env)) return std::string(env);
    return std::nullopt;
  }
  for (const char* name : {"chromium", "chromium-headless-shell"})
    if (std::string p = shot::on_path(name); !p.empty()) return p;
  return std::nullopt;
}

void screenshot(const std::string& path, const ShotOptions& opt) {
  using namespace shot;
  const ServeRoot root = resolve_root(path);
  if (opt.width == 0 || opt.height == 0) fail<usage_error>(kViewStage, "screenshot: empty size");
  const size_t bytes = size_t(opt.width) * opt.height * 4;
  httplib::Server server;
  detail::DataTally tally;
  detail::add_routes(server, root,
                     detail::config_json(root, opt.config_json, opt.backend, opt.gpu_budget),
                     &tally);
  Received got;
  add_post_routes(server, got, bytes);
  const int port = detail::bind_server(server, "127.0.0.1", 0);
  watch_interrupts();  // before the server's thread: every thread blocks SIGINT/SIGTERM
  std::thread listening([&server] { server.listen_after_bind(); });
  const fs::path profile = make_profile_dir();
  const fs::path log = profile / "chromium.log";
  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/?shot=1";
  std::printf("decalprep view: screenshot of %s with %s\n", url.c_str(), opt.chromium.c_str());
  std::fflush(stdout);
  pid_t pid = -1;
  const OnInterrupt cleanup("stopped Chromium and removed its temp profile", [&pid, &profile] {
    if (pid > 0) ::kill(-pid, SIGKILL);
    remove_profile(profile);
  });
  bool reaped = false;
  int status = 0;
  // However this ends: Chromium stopped, the server stopped and the
  // profile removed, once (now() on the way out of a normal run, the
  // destructor when something throws).
  struct Teardown {
    std::function<void()> steps;
    void now() {
      if (steps) std::exchange(steps, nullptr)();
    }
    ~Teardown() { now(); }
  } teardown{[&] {
    if (pid > 0) stop_chromium(pid, reaped);
    server.stop();
    listening.join();
    remove_profile(profile);
  }};
  pid = start_chromium(opt, url, profile, log);
  const Outcome outcome = wait_for_page(opt, got, pid, reaped, status);
  const std::string chromium_tail = opt.verbose ? "" : tail_lines(log, 20);
  teardown.now();
  const std::string last_lines =
      chromium_tail.empty() ? "" : "; Chromium's last lines:" + chromium_tail;
  switch (outcome) {
    case Outcome::page_error: fail<render_error>(kViewStage, "the page failed: " + got.error);
    case Outcome::exited:
      fail<render_error>(kViewStage, "Chromium (" + opt.chromium + ") exited " + exit_text(status) +
                                         " before the page sent its pixels" + last_lines);
    case Outcome::timeout:
      fail<render_error>(kViewStage, "no pixels from the page after " +
                                         std::to_string(int(opt.timeout_s)) + " s (--timeout)" +
                                         last_lines);
    case Outcome::pixels: break;
  }
  const auto span_of = [](const std::string& s) {
    return std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(s.data()), s.size());
  };
  opt.write_frame(span_of(got.frame));
  if (opt.decals && opt.write_decals) opt.write_decals(span_of(got.decals));
  std::stringstream notes(got.notes);
  for (std::string line; std::getline(notes, line);)
    if (!line.empty()) std::fprintf(stderr, "decalprep view: note: %s\n", line.c_str());
  if (opt.on_stats && !got.stats.empty()) opt.on_stats(got.stats);
  if (opt.on_data) {
    const std::lock_guard lock(tally.m);
    opt.on_data(tally.requests, tally.bytes, tally.files);
  }
}

}  // namespace prep::view
