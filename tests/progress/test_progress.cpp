// prep/progress.hpp on its own: the watchdog names a slow item (with a tiny
// threshold and a sleeping fake operation), plain mode rate-limits its
// lines, json lines parse and end with done == total, counting from many
// threads loses nothing, and a stage left by an exception prints no end.
// Times are measured with the test's own clock around each line written.
#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "prep/error.hpp"
#include "prep/progress.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

// Collects every line the Progress writes, with when it was written.
struct Capture {
  std::mutex mu;
  std::vector<std::string> lines;
  std::vector<Clock::time_point> at;

  std::function<void(std::string_view)> writer() {
    return [this](std::string_view text) {
      std::lock_guard<std::mutex> lock(mu);
      lines.emplace_back(text);
      at.push_back(Clock::now());
    };
  }
  // Options in `mode` that write into this capture; each test sets its own
  // intervals and watchdog on top.
  prep::ProgressOptions options(prep::ProgressMode mode) {
    prep::ProgressOptions po;
    po.mode = mode;
    po.write = writer();
    return po;
  }
  std::vector<std::string> containing(const std::string& what) {
    std::lock_guard<std::mutex> lock(mu);
    std::vector<std::string> out;
    for (const std::string& l : lines)
      if (l.find(what) != std::string::npos) out.push_back(l);
    return out;
  }
};

double seconds(Clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

TEST(Progress, AutoModeIsTtyOnATerminalAndPlainOtherwise) {
  EXPECT_EQ(prep::parse_progress_mode("auto", true), prep::ProgressMode::tty);
  EXPECT_EQ(prep::parse_progress_mode("auto", false), prep::ProgressMode::plain);
  EXPECT_EQ(prep::parse_progress_mode("json", true), prep::ProgressMode::json);
  EXPECT_EQ(prep::parse_progress_mode("none", false), prep::ProgressMode::none);
  EXPECT_THROW(prep::parse_progress_mode("loud", false), prep::usage_error);
}

TEST(Progress, WatchdogNamesAnItemThatStaysLongerThanTheThresholdAndRepeats) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::plain);
  po.plain_interval_s = 3600;  // no periodic lines: only the watchdog and the end
  po.watchdog_s = 0.05;
  const auto t0 = Clock::now();
  {
    prep::Progress progress(po);
    prep::ProgressStage stage(&progress, "clean", 2, "parts");
    {
      // A fast item: released well before the threshold, never named.
      prep::ProgressWatch fast = stage.watch("roads", 7, 12, "GEOS isValid");
    }
    stage.add();
    {
      // The slow fake operation: 0.4 s "in GEOS MakeValid".
      prep::ProgressWatch slow = stage.watch("buildings", 1832, 120000, "GEOS isValid");
      slow.operation("GEOS MakeValid");
      std::this_thread::sleep_for(400ms);
    }
    stage.add();
    // Reported while it ran, not after.
    const size_t named_while_running = out.containing("fid 1832").size();
    std::this_thread::sleep_for(200ms);
    EXPECT_EQ(out.containing("fid 1832").size(), named_while_running) << "named after it ended";
  }
  const double elapsed = seconds(Clock::now() - t0);
  const std::vector<std::string> named = out.containing("fid 1832");
  ASSERT_GE(named.size(), 2u) << "named once past 0.05 s, again every 0.05 s while it ran";
  // At most once per threshold while the item was held (0.4 s / 0.05 s).
  EXPECT_LE(named.size(), size_t(elapsed / 0.05) + 1);
  EXPECT_NE(named[0].find(
                "clean: layer 'buildings' fid 1832 (120000 vertices) has been in GEOS MakeValid"),
            std::string::npos)
      << named[0];
  EXPECT_TRUE(out.containing("fid 7").empty()) << "the fast item was named";
}

TEST(Progress, WatchdogInJsonNamesLayerFidVerticesOperationAndSeconds) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::json);
  po.json_interval_s = 3600;
  po.watchdog_s = 0.05;
  {
    prep::Progress progress(po);
    prep::ProgressStage stage(&progress, "clean", 1, "parts");
    prep::ProgressWatch slow = stage.watch("water \"bay\"", -3, 9, "GEOS MakeValid (structure)");
    std::this_thread::sleep_for(250ms);
  }
  const std::vector<std::string> slow = out.containing("\"slow\"");
  ASSERT_FALSE(slow.empty());
  const nlohmann::json j = nlohmann::json::parse(slow[0]);
  EXPECT_EQ(j["stage"], "clean");
  EXPECT_EQ(j["layer"], "water \"bay\"");
  EXPECT_EQ(j["fid"], -3);
  EXPECT_EQ(j["vertices"], 9);
  EXPECT_EQ(j["operation"], "GEOS MakeValid (structure)");
  EXPECT_GE(j["seconds"].get<double>(), 0.05);
}

TEST(Progress, WatchdogOffWhenTheThresholdIsZero) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::plain);
  po.watchdog_s = 0;
  {
    prep::Progress progress(po);
    prep::ProgressStage stage(&progress, "clean", 1, "parts");
    prep::ProgressWatch w = stage.watch("l", 1, 3, "GEOS MakeValid");
    std::this_thread::sleep_for(150ms);
  }
  EXPECT_TRUE(out.containing("has been in").empty());
}

TEST(Progress, PlainModePrintsAtMostOneLinePerIntervalPlusTheEnd) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::plain);
  po.plain_interval_s = 0.2;
  const uint64_t total = 1000;
  Clock::time_point t0, t1;
  {
    prep::Progress progress(po);
    {
      // Shorter than the interval: only its end line.
      prep::ProgressStage quick(&progress, "project", 5, "parts");
      quick.add(5);
    }
    t0 = Clock::now();
    prep::ProgressStage stage(&progress, "clean", total, "parts");
    // Counted far more often than lines may be printed: every ~1 ms for 1 s.
    for (uint64_t i = 0; i < total; ++i) {
      stage.add();
      if (i % 10 == 0) std::this_thread::sleep_for(10ms);
    }
    while (Clock::now() - t0 < 1s) std::this_thread::sleep_for(10ms);
    stage.finish();
    t1 = Clock::now();
  }
  const std::vector<std::string> quick = out.containing("project");
  ASSERT_EQ(quick.size(), 1u);
  EXPECT_EQ(quick[0].rfind("project: 5/5 parts (100%) in ", 0), 0u) << quick[0];
  std::vector<Clock::time_point> periodic;
  std::string end;
  {
    std::lock_guard<std::mutex> lock(out.mu);
    for (size_t i = 0; i < out.lines.size(); ++i) {
      if (out.lines[i].rfind("clean: ", 0) != 0) continue;
      EXPECT_EQ(out.lines[i].find('\r'), std::string::npos);
      EXPECT_EQ(out.lines[i].back(), '\n');
      if (out.lines[i].find(" elapsed") != std::string::npos)
        periodic.push_back(out.at[i]);
      else
        end = out.lines[i];
    }
  }
  const double run = seconds(t1 - t0);
  ASSERT_GE(periodic.size(), 2u) << "a 1 s stage with a 0.2 s interval printed fewer than 2 lines";
  EXPECT_LE(periodic.size(), size_t(run / 0.2) + 1);
  // The first line no sooner than one interval after the start, and the
  // lines at least one interval apart (5 ms: the capture's own clock reads).
  EXPECT_GE(seconds(periodic[0] - t0), 0.2 - 0.005);
  for (size_t i = 1; i < periodic.size(); ++i)
    EXPECT_GE(seconds(periodic[i] - periodic[i - 1]), 0.2 - 0.005)
        << "lines " << i - 1 << " and " << i;
  EXPECT_EQ(end.rfind("clean: 1000/1000 parts (100%) in ", 0), 0u) << end;
}

TEST(Progress, JsonLinesParseAndTheEndHasDoneEqualTotalWhenCountedFromManyThreads) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::json);
  po.json_interval_s = 0.01;
  constexpr int kThreads = 8;
  constexpr uint64_t kPerThread = 200000;
  {
    prep::Progress progress(po);
    // An estimated total ends as the count itself, so the end shows whether
    // any add() was lost.
    prep::ProgressStage stage(&progress, "build.cells", kThreads * kPerThread, "items",
                              prep::ProgressTotal::estimate);
    std::vector<std::thread> workers;
    for (int t = 0; t < kThreads; ++t)
      workers.emplace_back([&] {
        for (uint64_t i = 0; i < kPerThread; ++i) stage.add();
      });
    for (std::thread& w : workers) w.join();
  }
  ASSERT_GE(out.lines.size(), 2u);
  uint64_t last_done = 0;
  for (const std::string& l : out.lines) {
    ASSERT_EQ(l.back(), '\n');
    const nlohmann::json j = nlohmann::json::parse(l);  // throws on a broken line
    EXPECT_EQ(j["stage"], "build.cells");
    EXPECT_EQ(j["total"], kThreads * kPerThread);
    EXPECT_GE(j["done"].get<uint64_t>(), last_done) << "done went backwards";
    last_done = j["done"].get<uint64_t>();
  }
  const nlohmann::json first = nlohmann::json::parse(out.lines.front());
  const nlohmann::json end = nlohmann::json::parse(out.lines.back());
  EXPECT_EQ(first["event"], "start");
  EXPECT_EQ(end["event"], "end");
  EXPECT_EQ(end["done"], kThreads * kPerThread);
}

TEST(Progress, AnEstimatedTotalEndsAsWhatWasDone) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::json);
  {
    prep::Progress progress(po);
    prep::ProgressStage stage(&progress, "read", 0, "features", prep::ProgressTotal::estimate);
    stage.add(40);
    stage.set_total(100);  // an estimate that turns out high
    stage.add(30);
  }
  const nlohmann::json start = nlohmann::json::parse(out.lines.front());
  EXPECT_TRUE(start["total"].is_null()) << "unknown total";
  const nlohmann::json end = nlohmann::json::parse(out.lines.back());
  EXPECT_EQ(end["done"], 70);
  EXPECT_EQ(end["total"], 70);
}

TEST(Progress, AStageLeftByAnExceptionPrintsNoEnd) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::json);
  {
    prep::Progress progress(po);
    try {
      prep::ProgressStage stage(&progress, "clean", 10, "parts");
      stage.add(3);
      throw prep::input_error("clean: fid 1: bad");
    } catch (const prep::input_error&) {
    }
  }
  for (const std::string& l : out.lines) EXPECT_EQ(l.find("\"end\""), std::string::npos) << l;
}

TEST(Progress, TtyModeRedrawsOneLineWithCarriageReturnsAndEndsItWithANewline) {
  Capture out;
  prep::ProgressOptions po = out.options(prep::ProgressMode::tty);
  po.tty_interval_s = 0.02;
  {
    prep::Progress progress(po);
    prep::ProgressStage stage(&progress, "write", 4 << 20, "bytes");
    stage.add(1 << 20);
    std::this_thread::sleep_for(150ms);
    stage.add(3 << 20);
    stage.finish();
    progress.message("a message after the stage");
  }
  ASSERT_GE(out.lines.size(), 3u);
  for (size_t i = 0; i + 2 < out.lines.size(); ++i) {
    EXPECT_EQ(out.lines[i].front(), '\r') << out.lines[i];
    EXPECT_EQ(out.lines[i].back(), 'K') << "a redraw ends with clear-to-end-of-line";
  }
  const std::string& end = out.lines[out.lines.size() - 2];
  EXPECT_NE(end.find("4.0 MiB of 4.0 MiB  100%"), std::string::npos) << end;
  EXPECT_EQ(end.back(), '\n');
  EXPECT_EQ(out.lines.back(), "a message after the stage\n");
}

TEST(Progress, NoneModeAndANullProgressAreInert) {
  prep::ProgressOptions po;
  po.mode = prep::ProgressMode::none;
  po.write = [](std::string_view) { ADD_FAILURE() << "none mode wrote"; };
  prep::Progress progress(po);
  prep::ProgressStage a(&progress, "read", 1, "features");
  prep::ProgressStage b(nullptr, "read", 1, "features");
  EXPECT_FALSE(a.active());
  EXPECT_FALSE(b.active());
  a.add();
  prep::ProgressWatch w = a.watch("l", 1, 1, "GEOS MakeValid");
  progress.message("nothing");
}

}  // namespace
