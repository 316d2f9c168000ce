// terrain_dump FILE: a terrain file as the C++ reader (prep::render::
// decode_terrain) reads it, as JSON (numbers with 17 digits, so that they
// read back bit for bit), for the JavaScript reader's test
// (tests/web/terrain_test.mjs). Exit 5 with the message on a refusal
// (read_terrain_file: an unreadable file, or decode_terrain's checks).
#include <cmath>
#include <cstdio>

#include "prep/error.hpp"
#include "prep/render.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: terrain_dump FILE\n");
    return 2;
  }
  try {
    const prep::render::TerrainFile t = prep::render::read_terrain_file(argv[1]);
    const prep::render::Heightfield& h = t.mesh;
    auto num = [](double v) { std::printf(std::isfinite(v) ? "%.17g" : "null", v); };
    std::printf("{\"nx\": %u, \"ny\": %u", h.nx, h.ny);
    for (const auto& [name, v] : prep::render::terrain_fields(t)) {
      std::printf(", \"%s\": ", name);
      num(v);
    }
    std::printf(", \"surface_error_bound\": ");
    num(h.surface_error_bound);
    std::printf(", \"z\": [");
    for (size_t k = 0; k < h.z.size(); ++k) {
      if (k) std::printf(",");
      num(h.z[k]);
    }
    std::printf("]}\n");
  } catch (const prep::error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 5;
  }
  return 0;
}
