// prep/view.hpp — `decalprep view`: a small HTTP server for the browser
// viewer (web/). It serves the viewer page and the reader's modules
// (embedded in the binary at build time from web/), and the data of one
// package or one tileset, read by the page with HTTP Range requests.
//
// What it serves, and nothing else:
//   /                 the viewer page (web/viewer/index.html)
//   /config.json      {"kind": "package"|"tileset", "url": "/data/NAME"}
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
#include <string>
#include <string_view>

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
};

// Serves until the process is stopped (SIGINT/SIGTERM end it through
// prep/files.hpp with 130/143). Calls `on_listening` with the page's URL
// once the socket listens. Throws prep::input_error for a bad PATH and
// prep::usage_error when it cannot listen on bind:port.
void serve(const ServeOptions& options,
           const std::function<void(const std::string& url)>& on_listening);

}  // namespace prep::view
