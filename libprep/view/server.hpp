// server.hpp — the parts of the `decalprep view` server (view.cpp) that the
// screenshot mode (screenshot.cpp) builds on; private to libprep/view.
#pragma once

#include <httplib.h>

#include <algorithm>
#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "prep/view.hpp"

namespace prep::view::detail {

inline constexpr std::string_view kViewStage = "view";

// The body of /config.json: {"kind", "url", "terrain": URL of the terrain
// file (page_terrain) or null, "backend": `backend` (auto, webgpu or
// webgl2), "gpuBudget": `gpu_budget` (0: none), "screenshot":
// `screenshot_json` (a JSON value; empty: null)}.
std::string config_json(const ServeRoot& root, std::string_view screenshot_json,
                        std::string_view backend, uint64_t gpu_budget);

// What the server sent of the package's or tileset's files (/data/...):
// the requests answered with a body, the body bytes, and the files sent
// with their bytes (each once, in the order first asked for). Thread-safe.
struct DataTally {
  std::mutex m;
  uint64_t requests = 0, bytes = 0;
  std::vector<std::pair<std::string, uint64_t>> files;

  void add(const std::string& file, uint64_t sent) {
    const std::lock_guard lock(m);
    requests += 1;
    bytes += sent;
    const auto it = std::find_if(files.begin(), files.end(),
                                 [&file](const auto& f) { return f.first == file; });
    if (it == files.end())
      files.emplace_back(file, sent);
    else
      it->second += sent;
  }
};

// Adds the GET routes of prep/view.hpp: /, /config.json (`config`), /web/...
// and /data/... of `root`, counted in `tally` when given.
void add_routes(httplib::Server& server, const ServeRoot& root, const std::string& config,
                DataTally* tally = nullptr);

// Binds `server` to bind:port (0: a free port); returns the port. Throws
// usage_error when it cannot.
int bind_server(httplib::Server& server, const std::string& bind, int port);

}  // namespace prep::view::detail
