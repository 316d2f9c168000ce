// Progress of the long stages (prep/progress.hpp). Workers only touch
// atomics (ProgressStage::add) or their own watch slot; one monitor thread
// per Progress does every periodic print, so output never comes from two
// threads at once and its rate is set by the monitor's clock, not by how
// often the workers count. Stage start/end lines and message() print from
// the calling thread under the same mutex as the monitor.
#include "prep/progress.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <exception>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep {

using Clock = std::chrono::steady_clock;

namespace {

double seconds(Clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

constexpr int kSlots = 256;  // items watched at once (more than any thread count here)

// "1234" or, for bytes, "12.3 MiB"; below 10 (rates) with one decimal.
std::string amount(double v, const std::string& unit) {
  char buf[64];
  if (unit == "bytes")
    std::snprintf(buf, sizeof buf, "%.1f MiB", v / (1024.0 * 1024.0));
  else if (v < 10 && v != std::floor(v))
    std::snprintf(buf, sizeof buf, "%.1f", v);
  else
    std::snprintf(buf, sizeof buf, "%.0f", v);
  return buf;
}

std::string duration_text(double s) {
  char buf[32];
  if (s < 60)
    std::snprintf(buf, sizeof buf, "%.1f s", s);
  else if (s < 3600)
    std::snprintf(buf, sizeof buf, "%d min %02d s", int(s / 60), int(s) % 60);
  else
    std::snprintf(buf, sizeof buf, "%d h %02d min", int(s / 3600), int(s / 60) % 60);
  return buf;
}

// v rounded to 1/per_unit (10: tenths), printed short: 3.195, not 3.1950000000000003.
double round_to(double v, double per_unit) {
  return std::round(v * per_unit) / per_unit;
}

}  // namespace

ProgressMode parse_progress_mode(std::string_view text, bool stderr_is_tty) {
  if (text == "auto") return stderr_is_tty ? ProgressMode::tty : ProgressMode::plain;
  if (text == "tty") return ProgressMode::tty;
  if (text == "plain") return ProgressMode::plain;
  if (text == "json") return ProgressMode::json;
  if (text == "none") return ProgressMode::none;
  fail<usage_error>(kNoStage, "--progress: expected auto, tty, plain, json or none, got \"" +
                                  std::string(text) + "\"");
}

struct ProgressStage::State {
  std::string name, unit;
  ProgressTotal kind = ProgressTotal::exact;
  std::atomic<uint64_t> done{0}, total{0};
  Clock::time_point start;
  Clock::time_point last_print;  // plain/json: the last periodic line (under Impl::mu)
};

namespace {

// What one watched item is; written by its worker, read by the monitor,
// both under `mu`. `busy` only hands the slot out.
struct Slot {
  std::atomic<bool> busy{false};
  std::mutex mu;
  bool live = false;
  char stage[32] = {};
  char layer[64] = {};
  int64_t fid = -1;
  uint64_t vertices = 0;
  const char* operation = "";
  Clock::time_point start, next_report;
};

struct Snapshot {
  uint64_t done = 0, total = 0;
  bool known_total = false;
  double elapsed = 0, rate = 0, eta = -1;  // eta < 0: unknown
};

Snapshot snapshot_of(const ProgressStage::State& s, Clock::time_point now) {
  Snapshot x;
  x.done = s.done.load(std::memory_order_relaxed);
  x.total = s.total.load(std::memory_order_relaxed);
  x.known_total = s.kind == ProgressTotal::exact || x.total > 0;
  if (x.known_total && x.total < x.done) x.total = x.done;  // an estimate that fell behind
  x.elapsed = seconds(now - s.start);
  x.rate = x.elapsed > 0 ? double(x.done) / x.elapsed : 0;
  if (x.known_total && x.rate > 0) x.eta = double(x.total - x.done) / x.rate;
  return x;
}

}  // namespace

struct Progress::Impl {
  ProgressOptions opt;
  std::mutex mu;  // output, `open`, State::last_print
  std::vector<std::shared_ptr<ProgressStage::State>> open;
  bool tty_line = false;  // a redrawable line is on screen
  Clock::time_point last_draw;
  std::array<Slot, kSlots> slots;
  std::condition_variable wake;
  bool stopping = false;
  std::thread monitor;

  explicit Impl(ProgressOptions o) : opt(std::move(o)) {}

  void emit(std::string_view text) {
    if (opt.write) {
      opt.write(text);
    } else {
      std::fwrite(text.data(), 1, text.size(), stderr);
      std::fflush(stderr);
    }
  }

  // tty: the caller's line replaces the redrawn one.
  void clear_tty_line() {
    if (tty_line) emit("\r\x1b[K");
    tty_line = false;
  }

  std::string human(const ProgressStage::State& s, const Snapshot& x, bool end) const {
    std::string t = s.name;
    const bool tty = opt.mode == ProgressMode::tty;
    if (tty) t.resize(std::max<size_t>(t.size(), 16), ' ');
    t += tty ? " " : ": ";
    if (x.known_total) {
      const double pct = x.total > 0 ? 100.0 * double(x.done) / double(x.total) : 100.0;
      char p[32];
      std::snprintf(p, sizeof p, "%.0f%%", std::floor(pct));
      const std::string unit = s.unit == "bytes" ? "" : " " + s.unit;
      t += (s.unit == "bytes"
                ? amount(double(x.done), s.unit) + " of " + amount(double(x.total), s.unit)
                : amount(double(x.done), s.unit) + "/" + amount(double(x.total), s.unit) + unit);
      t += tty ? std::string("  ") + p : std::string(" (") + p + ")";
    } else {
      t += amount(double(x.done), s.unit) + (s.unit == "bytes" ? "" : " " + s.unit);
    }
    const std::string rate =
        amount(x.rate, s.unit) + (s.unit == "bytes" ? "/s" : " " + s.unit + "/s");
    if (end) {
      t += tty ? "  " + rate + "  done in " + duration_text(x.elapsed)
               : " in " + duration_text(x.elapsed) + ", " + rate;
    } else {
      t += (tty ? "  " : ", ") + rate;
      if (x.eta >= 0) t += (tty ? "  ETA " : ", ETA ") + duration_text(x.eta);
      t += (tty ? "  " : ", ") + duration_text(x.elapsed) + " elapsed";
    }
    return t;
  }

  std::string json(const ProgressStage::State& s, const Snapshot& x, const char* event) const {
    nlohmann::json j;
    j["event"] = event;
    j["stage"] = s.name;
    j["unit"] = s.unit;
    j["done"] = x.done;
    j["total"] = x.known_total ? nlohmann::json(x.total) : nlohmann::json(nullptr);
    j["rate"] = round_to(x.rate, 10);
    j["eta_s"] = x.eta >= 0 ? nlohmann::json(round_to(x.eta, 1000)) : nlohmann::json(nullptr);
    j["elapsed_s"] = round_to(x.elapsed, 1000);
    return j.dump() + "\n";
  }

  // Periodic output of one open stage (monitor thread, under mu).
  void periodic(ProgressStage::State& s, Clock::time_point now) {
    const Snapshot x = snapshot_of(s, now);
    switch (opt.mode) {
      case ProgressMode::tty:
        emit("\r" + human(s, x, false) + "\x1b[K");
        tty_line = true;
        break;
      case ProgressMode::plain: emit(human(s, x, false) + "\n"); break;
      case ProgressMode::json: emit(json(s, x, "progress")); break;
      case ProgressMode::none: break;
    }
  }

  void check_watchdog(Clock::time_point now) {
    if (!(opt.watchdog_s > 0)) return;
    const auto period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(opt.watchdog_s));
    for (Slot& slot : slots) {
      if (!slot.busy.load(std::memory_order_acquire)) continue;
      std::string line;
      {
        std::lock_guard<std::mutex> lock(slot.mu);
        if (!slot.live || now < slot.next_report) continue;
        slot.next_report += period;
        const double so_far = seconds(now - slot.start);
        if (opt.mode == ProgressMode::json) {
          nlohmann::json j = {{"event", "slow"},
                              {"stage", slot.stage},
                              {"layer", slot.layer},
                              {"fid", slot.fid},
                              {"vertices", slot.vertices},
                              {"operation", slot.operation},
                              {"seconds", round_to(so_far, 1000)}};
          line = j.dump() + "\n";
        } else {
          char buf[256];
          std::snprintf(buf, sizeof buf,
                        "%s: layer '%s' fid %lld (%llu vertices) has been in %s for %.0f s\n",
                        slot.stage, slot.layer, static_cast<long long>(slot.fid),
                        static_cast<unsigned long long>(slot.vertices), slot.operation, so_far);
          line = buf;
        }
      }
      clear_tty_line();
      emit(line);
    }
  }

  void run() {
    const double interval = opt.mode == ProgressMode::tty     ? opt.tty_interval_s
                            : opt.mode == ProgressMode::plain ? opt.plain_interval_s
                                                              : opt.json_interval_s;
    double tick = std::min(0.1, interval / 2);
    if (opt.watchdog_s > 0) tick = std::min(tick, opt.watchdog_s / 4);
    tick = std::max(tick, 0.001);
    const auto tick_d =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(tick));
    const auto interval_d =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(interval));
    std::unique_lock<std::mutex> lock(mu);
    while (!stopping) {
      wake.wait_for(lock, tick_d);
      if (stopping) break;
      const Clock::time_point now = Clock::now();
      check_watchdog(now);
      if (open.empty()) continue;
      if (opt.mode == ProgressMode::tty) {
        // One line on screen: the stage opened last.
        if (now - last_draw >= interval_d) {
          periodic(*open.back(), now);
          last_draw = now;
        }
      } else {
        for (const auto& s : open) {
          if (now - s->last_print < interval_d) continue;
          periodic(*s, now);
          s->last_print = now;
        }
      }
    }
  }
};

Progress::Progress(ProgressOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  if (impl_->opt.mode != ProgressMode::none) impl_->monitor = std::thread([this] { impl_->run(); });
}

Progress::~Progress() {
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    impl_->stopping = true;
    impl_->clear_tty_line();
  }
  impl_->wake.notify_all();
  if (impl_->monitor.joinable()) impl_->monitor.join();
}

ProgressMode Progress::mode() const {
  return impl_->opt.mode;
}

void Progress::message(std::string_view line) {
  if (impl_->opt.mode == ProgressMode::none) return;
  std::lock_guard<std::mutex> lock(impl_->mu);
  impl_->clear_tty_line();
  std::string text(line);
  if (text.empty() || text.back() != '\n') text += '\n';
  impl_->emit(text);
}

// ---------------------------------------------------------------- stage --

ProgressStage::ProgressStage(Progress* progress, std::string name, uint64_t total, std::string unit,
                             ProgressTotal kind) {
  if (!progress || progress->mode() == ProgressMode::none) return;
  exceptions_ = std::uncaught_exceptions();
  progress_ = progress;
  state_ = std::make_shared<State>();
  state_->name = std::move(name);
  state_->unit = std::move(unit);
  state_->kind = kind;
  state_->total.store(total, std::memory_order_relaxed);
  state_->start = state_->last_print = Clock::now();
  Progress::Impl& im = *progress_->impl_;
  std::lock_guard<std::mutex> lock(im.mu);
  im.open.push_back(state_);
  if (im.opt.mode == ProgressMode::json)
    im.emit(im.json(*state_, snapshot_of(*state_, state_->start), "start"));
}

ProgressStage::~ProgressStage() {
  if (!state_) return;
  try {
    close(std::uncaught_exceptions() <= exceptions_);
  } catch (...) {
    // Progress is output only; a failed print must not end the build.
  }
}

ProgressStage::ProgressStage(ProgressStage&& other) noexcept
    : progress_(other.progress_), state_(std::move(other.state_)), exceptions_(other.exceptions_) {
  other.progress_ = nullptr;
}

ProgressStage& ProgressStage::operator=(ProgressStage&& other) noexcept {
  if (this != &other) {
    if (state_) close(std::uncaught_exceptions() <= exceptions_);
    progress_ = other.progress_;
    state_ = std::move(other.state_);
    exceptions_ = other.exceptions_;
    other.progress_ = nullptr;
  }
  return *this;
}

void ProgressStage::add(uint64_t n) noexcept {
  if (state_) state_->done.fetch_add(n, std::memory_order_relaxed);
}

void ProgressStage::set_total(uint64_t total) noexcept {
  if (state_) state_->total.store(total, std::memory_order_relaxed);
}

void ProgressStage::finish() {
  if (state_) close(true);
}

void ProgressStage::close(bool completed) {
  std::shared_ptr<State> s = std::move(state_);
  Progress::Impl& im = *progress_->impl_;
  progress_ = nullptr;
  std::lock_guard<std::mutex> lock(im.mu);
  im.open.erase(std::remove(im.open.begin(), im.open.end(), s), im.open.end());
  if (!completed) {
    im.clear_tty_line();  // an error message follows; leave no half line
    return;
  }
  // The end: done == total. An exact total is the work the stage set out to
  // do (items it skipped count as done); an estimate becomes what was done.
  const uint64_t done = s->done.load(std::memory_order_relaxed);
  const uint64_t total = s->total.load(std::memory_order_relaxed);
  const uint64_t final_count = s->kind == ProgressTotal::estimate ? done : std::max(done, total);
  s->done.store(final_count, std::memory_order_relaxed);
  s->total.store(final_count, std::memory_order_relaxed);
  const Snapshot x = snapshot_of(*s, Clock::now());
  switch (im.opt.mode) {
    case ProgressMode::tty:
      im.emit("\r" + im.human(*s, x, true) + "\x1b[K\n");
      im.tty_line = false;
      break;
    case ProgressMode::plain: im.emit(im.human(*s, x, true) + "\n"); break;
    case ProgressMode::json: im.emit(im.json(*s, x, "end")); break;
    case ProgressMode::none: break;
  }
}

// ---------------------------------------------------------------- watch --

ProgressWatch ProgressStage::watch(std::string_view layer, int64_t fid, uint64_t vertices,
                                   const char* operation) {
  ProgressWatch w;
  if (!state_) return w;
  Progress::Impl& im = *progress_->impl_;
  if (!(im.opt.watchdog_s > 0)) return w;
  // Start the search where this thread found a free slot last time.
  thread_local int hint = 0;
  for (int k = 0; k < kSlots; ++k) {
    const int i = (hint + k) % kSlots;
    Slot& slot = im.slots[size_t(i)];
    bool expected = false;
    if (slot.busy.load(std::memory_order_relaxed) ||
        !slot.busy.compare_exchange_strong(expected, true, std::memory_order_acquire))
      continue;
    hint = i;
    std::lock_guard<std::mutex> lock(slot.mu);
    std::snprintf(slot.stage, sizeof slot.stage, "%s", state_->name.c_str());
    const size_t n = std::min(layer.size(), sizeof slot.layer - 1);
    std::memcpy(slot.layer, layer.data(), n);
    slot.layer[n] = 0;
    slot.fid = fid;
    slot.vertices = vertices;
    slot.operation = operation;
    slot.start = Clock::now();
    slot.next_report = slot.start + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(im.opt.watchdog_s));
    slot.live = true;
    w.impl_ = &im;
    w.slot_ = i;
    return w;
  }
  return w;  // every slot taken: this item goes unwatched
}

ProgressWatch::~ProgressWatch() {
  release();
}

void ProgressWatch::release() noexcept {
  if (!impl_) return;
  Slot& slot = impl_->slots[size_t(slot_)];
  {
    std::lock_guard<std::mutex> lock(slot.mu);
    slot.live = false;
  }
  slot.busy.store(false, std::memory_order_release);
  impl_ = nullptr;
  slot_ = -1;
}

ProgressWatch::ProgressWatch(ProgressWatch&& other) noexcept
    : impl_(other.impl_), slot_(other.slot_) {
  other.impl_ = nullptr;
  other.slot_ = -1;
}

ProgressWatch& ProgressWatch::operator=(ProgressWatch&& other) noexcept {
  if (this != &other) {
    release();
    impl_ = other.impl_;
    slot_ = other.slot_;
    other.impl_ = nullptr;
    other.slot_ = -1;
  }
  return *this;
}

void ProgressWatch::operation(const char* op) noexcept {
  if (!impl_) return;
  Slot& slot = impl_->slots[size_t(slot_)];
  std::lock_guard<std::mutex> lock(slot.mu);
  slot.operation = op;
}

}  // namespace prep
