// prep/progress.hpp — progress of the long stages of a build, on stderr.
//
// One Progress per build. Each stage opens a ProgressStage (name, total,
// unit) and counts work done with add(); a monitor thread owned by the
// Progress prints, so a worker in a parallel loop pays one relaxed atomic
// add and never blocks on output. Output modes:
//   tty    one line per stage, redrawn in place (carriage return) about five
//          times a second, left behind when the stage ends;
//   plain  one line per stage at most every plain_interval_s (5 s), plus one
//          when the stage ends (for logs and pipes);
//   json   one JSON object per line: {"event":"start"|"progress"|"end",
//          "stage","unit","done","total","rate","eta_s","elapsed_s"}, at most
//          every json_interval_s, the "end" object with done == total;
//   none   nothing (no thread).
// The watchdog: a worker that starts one item of slow, opaque work (a GEOS
// call on one feature) holds a ProgressWatch naming it; the monitor names
// every item held longer than watchdog_s, once when it passes watchdog_s and
// again every watchdog_s while it runs (layer, fid, vertex count, operation,
// seconds so far).
//
// Progress is output only: nothing a stage computes depends on it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

namespace prep {

enum class ProgressMode { none, tty, plain, json };

// "auto" | "tty" | "plain" | "json" | "none"; auto is tty when stderr is a
// terminal (`stderr_is_tty`), else plain. Throws usage_error otherwise.
ProgressMode parse_progress_mode(std::string_view text, bool stderr_is_tty);

struct ProgressOptions {
  ProgressMode mode = ProgressMode::none;
  double tty_interval_s = 0.2;    // tty: redraw period
  double plain_interval_s = 5.0;  // plain: at most one line per stage per period
  double json_interval_s = 1.0;   // json: at most one "progress" object per stage per period
  double watchdog_s = 30.0;       // name an item held longer than this; <= 0: off
  // Receives whole lines (with their '\n'; tty redraws start with '\r' and
  // have none). Empty: written to stderr and flushed.
  std::function<void(std::string_view)> write;
};

class ProgressStage;
class ProgressWatch;

class Progress {
 public:
  explicit Progress(ProgressOptions options);
  ~Progress();  // stops the monitor thread; open stages are left as they are
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  ProgressMode mode() const;
  // Prints one line of text (tty: above the stage line). In json mode the
  // caller passes a JSON object.
  void message(std::string_view line);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  friend class ProgressStage;
  friend class ProgressWatch;
};

// Whether a stage's total is known from the start (`exact`: the stage ends
// with done == total) or is a running estimate (`estimate`: set_total() may
// move it; the stage ends with total = done). A total of 0 with `estimate`
// means unknown so far.
enum class ProgressTotal { exact, estimate };

// One stage. A default-constructed stage, or one on a null or `none`
// Progress, is inert: every call is a no-op. add() and set_total() are
// thread-safe and cheap; finish() and the destructor belong to the thread
// that opened the stage. The destructor finishes the stage, except during
// exception unwinding, when the stage is abandoned (no "end" is printed).
class ProgressStage {
 public:
  ProgressStage() = default;
  ProgressStage(Progress* progress, std::string name, uint64_t total, std::string unit,
                ProgressTotal kind = ProgressTotal::exact);
  ~ProgressStage();
  ProgressStage(ProgressStage&& other) noexcept;
  ProgressStage& operator=(ProgressStage&& other) noexcept;

  bool active() const { return state_ != nullptr; }
  void add(uint64_t n = 1) noexcept;
  void set_total(uint64_t total) noexcept;
  // Prints the stage's end (done == total) and closes it. Idempotent.
  void finish();

  // Marks the calling thread as working on one item for the watchdog.
  // `layer` is copied (up to 63 bytes); `operation` must outlive the watch
  // (a string literal). Inert when the stage is or the watchdog is off.
  ProgressWatch watch(std::string_view layer, int64_t fid, uint64_t vertices,
                      const char* operation);

  struct State;

 private:
  void close(bool completed);
  Progress* progress_ = nullptr;
  std::shared_ptr<State> state_;
  int exceptions_ = 0;  // std::uncaught_exceptions() when opened
};

// RAII: one item in flight on one thread (ProgressStage::watch).
class ProgressWatch {
 public:
  ProgressWatch() = default;
  ~ProgressWatch();
  ProgressWatch(ProgressWatch&& other) noexcept;
  ProgressWatch& operator=(ProgressWatch&& other) noexcept;
  ProgressWatch(const ProgressWatch&) = delete;
  ProgressWatch& operator=(const ProgressWatch&) = delete;

  // The step the item is in now ("GEOS MakeValid"); a string literal.
  void operation(const char* op) noexcept;

 private:
  friend class ProgressStage;
  void release() noexcept;
  Progress::Impl* impl_ = nullptr;
  int slot_ = -1;
};

}  // namespace prep
