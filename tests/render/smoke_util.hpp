// Helpers of the render smoke tests (running the tool is in tests/support):
// the Monaco sample package they share, reading raw decal layers and world
// files, and the pixel agreement of two layers.
#pragma once

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace render_test {

// ctest runs every test in its own process, two at a time: the first one
// builds a package under an exclusive lock, later ones reuse it when it is
// newer than the tool binary that would build it.
struct BuildLock {
  int fd;
  explicit BuildLock(const std::filesystem::path& p)
      : fd(::open(p.c_str(), O_CREAT | O_RDWR, 0644)) {
    if (fd >= 0) ::flock(fd, LOCK_EX);
  }
  ~BuildLock() {
    if (fd >= 0) ::close(fd);
  }
  BuildLock(const BuildLock&) = delete;
  BuildLock& operator=(const BuildLock&) = delete;
};

// render-out/NAME/pPID: a directory of this test process's own, for a test
// file whose tests build and rewrite the same files (ctest runs them two at
// a time, each in its own process). Removed by remove_process_dir.
inline std::filesystem::path process_dir(const std::string& name) {
  const auto d = std::filesystem::current_path() / "render-out" / name /
                 ("p" + std::to_string(static_cast<long>(::getpid())));
  std::filesystem::create_directories(d);
  return d;
}
inline void remove_process_dir(const std::filesystem::path& d) {
  std::error_code ec;
  std::filesystem::remove_all(d, ec);
}

inline bool fresh(const std::filesystem::path& pkg) {
  std::error_code ec;
  return std::filesystem::exists(pkg) && std::filesystem::last_write_time(pkg, ec) >
                                             std::filesystem::last_write_time(DECALPREP_TOOL, ec);
}

// The Monaco sample scene's package, render-out/smoke/monaco.decals, built
// once (under render-out/smoke/monaco.lock) by whichever render test needs
// it first; "" with the reason in `why` when it cannot be built.
inline std::string monaco_package(std::string* why) {
  namespace fs = std::filesystem;
  const std::string pbf = prep::test::monaco_sample("monaco.osm.pbf");
  if (!fs::exists(pbf)) {
    if (why) *why = "Monaco sample missing: " + pbf;
    return "";
  }
  const fs::path dir = fs::current_path() / "render-out" / "smoke";
  fs::create_directories(dir);
  const fs::path pkg = dir / "monaco.decals";
  BuildLock lock(dir / "monaco.lock");
  if (!fresh(pkg)) {
    const auto r = prep::test::run_tool("build " + std::string(DECALPREP_SOURCE_DIR) +
                                        "/samples/monaco/scene.toml -o " + pkg.string() + " -q");
    if (r.rc != 0) {
      if (why) *why = "decalprep build failed (rc " + std::to_string(r.rc) + "): " + r.output;
      return "";
    }
  }
  return pkg.string();
}

// A scene file in UTM 32N (no simplification) of layers NAME reading
// NAME.geojson beside it: (name, kind, further keys, one per line).
inline std::string utm_scene_toml(std::initializer_list<std::array<const char*, 3>> layers) {
  std::string s = "crs = \"EPSG:32632\"\nresolution = 0\n";
  for (const auto& [name, kind, keys] : layers)
    s += std::string("[[layer]]\nname = \"") + name + "\"\nsource = \"" + name +
         ".geojson\"\nkind = \"" + kind + "\"\n" + keys;
  return s;
}

// Builds DIR/s.toml, one layer "a" reading DIR/a.geojson in UTM 32N with
// the further keys `extra` (one per line), into DIR/s.decals: the refusal
// tests of the scene keys.
inline prep::test::ToolRun build_layer_a(const std::filesystem::path& dir,
                                         const std::string& extra) {
  std::ofstream(dir / "s.toml") << "crs = \"EPSG:32632\"\n[[layer]]\nname = \"a\"\nsource = "
                                   "\"a.geojson\"\n" +
                                       extra;
  return prep::test::run_tool("build " + (dir / "s.toml").string() + " -o " +
                              (dir / "s.decals").string() + " -q");
}

// Writes DIR/scene.toml (utm_scene_toml of `layers`) and builds it into
// DIR/NAME: the package's path, or "" with the tool's output in `why`.
inline std::string build_utm_scene(const std::filesystem::path& dir, const std::string& name,
                                   std::initializer_list<std::array<const char*, 3>> layers,
                                   std::string& why) {
  std::ofstream(dir / "scene.toml") << utm_scene_toml(layers);
  const std::string pkg = (dir / name).string();
  const auto r =
      prep::test::run_tool("build " + (dir / "scene.toml").string() + " -o " + pkg + " -q");
  if (r.rc != 0) why = r.output;
  return r.rc == 0 ? pkg : "";
}

inline std::vector<float> read_raw(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
  std::vector<float> v(bytes.size() / 4);
  std::memcpy(v.data(), bytes.data(), v.size() * 4);
  return v;
}

struct Agreement {
  size_t considered = 0, agree = 0;
  double ratio() const { return considered ? double(agree) / double(considered) : 0.0; }
};

// Pixels where either layer has coverage agree when every straight-alpha
// RGBA channel is within 2/255 (colour only compared where alpha > 0).
inline Agreement agreement(const std::vector<float>& a, const std::vector<float>& b) {
  Agreement r;
  const double tol = 2.0 / 255.0 + 1e-6;
  for (size_t p = 0; p + 3 < a.size() && p + 3 < b.size(); p += 4) {
    if (a[p + 3] <= 0 && b[p + 3] <= 0) continue;
    ++r.considered;
    bool ok = std::abs(a[p + 3] - b[p + 3]) <= tol;
    for (int c = 0; c < 3 && ok; ++c) ok = std::abs(a[p + c] - b[p + c]) <= tol;
    r.agree += ok;
  }
  return r;
}

// A world file (.pgw beside a rendered PNG): pixel size and rotation terms,
// and the centre of the upper-left pixel; `ok` false when it did not read.
struct WorldFile {
  double dx = 0, r1 = 0, r2 = 0, dy = 0, x0 = 0, y0 = 0;
  bool ok = false;
};

inline WorldFile read_world_file(const std::filesystem::path& path) {
  WorldFile w;
  std::ifstream in(path);
  in >> w.dx >> w.r1 >> w.r2 >> w.dy >> w.x0 >> w.y0;
  w.ok = bool(in);
  return w;
}

}  // namespace render_test
