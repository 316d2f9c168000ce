// Helpers of the render smoke tests (running the tool is in tests/support):
// reading raw decal layers and world files, and the pixel agreement of two
// layers.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace render_test {

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
