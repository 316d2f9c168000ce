// prep/error.hpp — the toolchain's exception hierarchy and exit codes.
//
// Inside libprep every failure is an exception rooted in prep::error. Its
// message says where: stage, file, layer, feature id, field, bad value, e.g.
//   clean: roads.shp layer 'roads' fid 1832: ring has NaN coordinate
// The formats/ reader does not use these (it returns a status instead).
#pragma once

#include <stdexcept>
#include <string>

namespace prep {

// Exit codes of the decalprep tool. Stable: documented in docs/cli.md "Exit codes".
// Kept clear of 124–127 and 137 (timeout / shell / SIGKILL).
enum class ExitCode : int {
  ok = 0,
  internal = 1,       // a bug or an unexpected library failure
  usage = 2,          // bad command line or option value
  input = 3,          // unreadable/invalid input data, scene file, CRS
  partial = 4,        // --skip-failures dropped features; package written
  verify_failed = 5,  // `verify`/`info` found a corrupt or unsupported package
  resource = 6,       // --max-memory or a structure budget would be exceeded
  output = 7,         // the package could not be written
  render = 8,         // no EGL display/context, or a GL failure
  empty = 9,          // the build kept no feature from any layer (see --allow-empty)
  strict = 10,        // --strict turned a warning into an error
  killed = 11,        // batch: a scene was killed by a signal (summary.json names it)
  browser = 12,       // view --screenshot: no Chromium to draw with
  // A build or render stopped by SIGINT / SIGTERM exits 128 + the signal's
  // number, as a shell reports it, after removing what it had made.
  interrupted = 130,  // SIGINT
  terminated = 143,   // SIGTERM
};

class error : public std::runtime_error {
 public:
  explicit error(const std::string& what, ExitCode code = ExitCode::internal)
      : std::runtime_error(what), code_(code) {}
  ExitCode code() const noexcept { return code_; }

 private:
  ExitCode code_;
};

// Bad command line or option value.
struct usage_error : error {
  explicit usage_error(const std::string& w) : error(w, ExitCode::usage) {}
};
// Bad input data: a source GDAL cannot open, a feature that cannot be used.
struct input_error : error {
  explicit input_error(const std::string& w) : error(w, ExitCode::input) {}
};
// GDAL reported a failure (message carries CPLGetLastErrorMsg()).
struct gdal_error : error {
  explicit gdal_error(const std::string& w) : error(w, ExitCode::input) {}
};
// Scene file problems (message names the key and the line).
struct scene_error : error {
  explicit scene_error(const std::string& w) : error(w, ExitCode::input) {}
};
// A package could not be written.
struct output_error : error {
  explicit output_error(const std::string& w) : error(w, ExitCode::output) {}
};
// A package could not be read (wraps a formats/ status).
struct format_error : error {
  explicit format_error(const std::string& w) : error(w, ExitCode::verify_failed) {}
};
// A memory or structure budget would be exceeded.
struct resource_error : error {
  explicit resource_error(const std::string& w) : error(w, ExitCode::resource) {}
};
// The build kept nothing (exit 9), unless --allow-empty.
struct empty_error : error {
  explicit empty_error(const std::string& w) : error(w, ExitCode::empty) {}
};
// A warning that --strict makes an error (exit 10).
struct strict_error : error {
  explicit strict_error(const std::string& w) : error(w, ExitCode::strict) {}
};
// EGL/GL failure in the renderer.
struct render_error : error {
  explicit render_error(const std::string& w) : error(w, ExitCode::render) {}
};

}  // namespace prep
