// prep/view.hpp — `decalprep view`: a small HTTP server for the browser
// viewer (web/). It serves the viewer page and the reader's modules
// (embedded in the binary at build time from web/), and the data of one
// package or one tileset, read by the page with HTTP Range requests.
//
// What it serves, and nothing else:
//   /                 the viewer page (web/viewer/index.html)
//   /config.json      {"kind": "package"|"tileset", "url": "/data/NAME",
//                      "terrain": "/data/STEM.terrain" (a package's terrain
//                      file, when there is one) | null,
//                      "backend": "auto"|"webgpu"|"webgl2" (the page's
//                      renderer; ?backend= in the page's URL overrides it),
//                      "screenshot": {...} (screenshot mode) | null}
//   /web/...          the embedded files of web/ (viewer, reader, and the
//                     two modules web/node_modules held at build time)
//   /data/NAME        for a package DIR/STEM.decals: DIR/STEM.decals and its
//                     side files, the regular files of DIR named STEM.<ext>
//                     (the report STEM.report.json, ...); for a tileset
//                     folder: any regular file under it, at any depth,
//                     except names that start with "." (the build's .work/)
// A /data/ path is refused (404) when a component is empty, ".", ".." or
// starts with ".", when it holds a backslash or a NUL, or when its real
// path (symbolic links resolved) is not inside the served folder. Folders
// are never listed. GET and HEAD answer a single byte range (206 with
// Content-Range, 416 with "bytes */SIZE" when it starts past the end); a
// request of several ranges gets the whole file (200), as RFC 9110 allows.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace prep::view {

// What a view serves.
struct ServeRoot {
  enum class Kind { package, tileset };
  Kind kind = Kind::package;
  std::filesystem::path dir;  // the served folder, a real path (no links, no "..")
  std::string stem;           // package: the file name without ".decals"
  std::string entry;          // the file the page loads, relative to dir
};

// Resolves PATH (a .decals file, a tileset folder or its tileset.json).
// Throws prep::input_error ("view: ...") when it is none of these.
ServeRoot resolve_root(const std::string& path);

// The real path of the file that /data/<rel> names (`rel` percent-decoded),
// or nullopt when the request must be refused (the rules above) or names
// no regular file.
std::optional<std::filesystem::path> resolve_data_path(const ServeRoot& root, std::string_view rel);

// The terrain file the page draws for `root` (formats/SPEC.md "Terrain
// files"): STEM.terrain beside a package, tileset.terrain in a tileset's
// folder, when the server serves it (resolve_data_path's rules); nullopt
// when there is none.
// /config.json names it, and `view --screenshot` places its camera over it.
std::optional<std::filesystem::path> page_terrain(const ServeRoot& root);

// A single byte range [first, last] of a file of `size` bytes.
struct ByteRange {
  uint64_t first = 0, last = 0;
};
enum class RangeAnswer {
  whole,          // no Range header, or one this server ignores (several ranges)
  partial,        // 206 with `range`
  unsatisfiable,  // 416
};
// Parses a Range header value ("bytes=A-B", "bytes=A-", "bytes=-N").
RangeAnswer parse_range(std::string_view header, uint64_t size, ByteRange& range);

// One embedded file of web/.
struct Asset {
  std::string_view path;  // URL path, "/web/viewer/index.html"
  std::string_view type;  // Content-Type
  std::string_view bytes;
};
// The embedded file at a URL path, or nullptr.
const Asset* find_asset(std::string_view url_path);

// How `decalprep view` is asked to serve.
struct ServeOptions {
  std::string path;                // the package or tileset
  std::string bind = "127.0.0.1";  // the address to listen on
  int port = 8080;                 // 0: a free port the system picks
  std::string backend = "auto";    // the page's renderer: auto, webgpu or webgl2
  // A tileset's GPU budget, decoded blob bytes (render --gpu-budget's
  // rule: the page coarsens the view's tiles to fit); 0: none.
  uint64_t gpu_budget = 0;
};

// Serves until the process is stopped (SIGINT/SIGTERM end it through
// prep/files.hpp with 130/143). Calls `on_listening` with the page's URL
// once the socket listens. Throws prep::input_error for a bad PATH and
// prep::usage_error when it cannot listen on bind:port.
void serve(const ServeOptions& options,
           const std::function<void(const std::string& url)>& on_listening);

// ------------------------------------------------------ screenshot mode --
// `decalprep view PATH --screenshot OUT.png`: the server runs on 127.0.0.1
// (a free port), a headless Chromium opens the page with ?shot=1, the page
// draws the config's camera once and POSTs the pixels back:
//   POST /__shot/frame    the final frame, W*H*4 bytes of RGBA8, row 0 at the top
//   POST /__shot/decals   the decal layer alone (when asked), the same size
//   POST /__shot/error    the page's failure, as text (at most 64 KiB)
// A POST from another address than 127.0.0.1, or of another size, is
// refused (403, 400) and the screenshot waits on.

struct ShotOptions {
  uint32_t width = 0, height = 0;
  // The config's "screenshot" value: a JSON object the page reads (size,
  // camera, albedo, decals, ramps; web/viewer).
  std::string config_json;
  std::string backend = "auto";  // the page's renderer: auto, webgpu or webgl2
  uint64_t gpu_budget = 0;       // as ServeOptions::gpu_budget
  bool decals = false;           // wait for /__shot/decals too
  std::string chromium;          // the browser's executable (find_chromium)
  double timeout_s = 120;
  bool verbose = false;  // Chromium's log and the page's console on stderr
  // Called with the POSTed pixels once Chromium is stopped.
  std::function<void(std::span<const uint8_t> rgba)> write_frame, write_decals;
  // Called after the writers with what the page POSTed to /__shot/stats
  // (JSON: the adapter and the frame times; untrusted text), if it did.
  std::function<void(const std::string& json)> on_stats;
  // Called last with what the server sent of the package's or tileset's
  // files (/data/...): the requests answered with a body, their bytes, and
  // each file sent with its bytes (relative to the served folder, in the
  // order first asked for, once however many requests it took).
  std::function<void(uint64_t requests, uint64_t bytes,
                     const std::vector<std::pair<std::string, uint64_t>>& files)>
      on_data;
};

// The Chromium to draw with: $DECALPREP_CHROMIUM when set (it must be an
// executable file), else `chromium` or `chromium-headless-shell` on PATH,
// else nullopt.
std::optional<std::string> find_chromium();

// Serves PATH as serve() does (with "screenshot" in /config.json), runs
// Chromium headless on the page in a process group of its own with a fresh
// --user-data-dir (removed afterwards), waits for the pixels, stops
// Chromium (the whole group) and the server, then calls the writers. Throws
// input_error for a bad PATH, render_error when the page POSTs an error
// (its text in the message), Chromium exits before the pixels come, or
// `timeout_s` passes; SIGINT/SIGTERM stop Chromium and end the process
// (130/143).
void screenshot(const std::string& path, const ShotOptions& opt);

}  // namespace prep::view
