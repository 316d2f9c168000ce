// lod_oracle — the C++ LOD selection of a package for a list of views, as
// JSON, for tests/web/lod_agreement.py: for each view the parameters
// prep::render::lod_view gives (C, base, slope) and the segments
// decal::visible_segments keeps for them (the selection `render` and its GL
// pass use, tests/render/test_lod_gpu.cpp).
//
//   lod_oracle PACKAGE VIEWS.json HEIGHT TOLERANCE_PX
//
// VIEWS.json: [{"name", "eye": [x, y, z], "target": [x, y, z], "fov": deg}
//              | {"name", "topdown": [xmin, ymin, xmax, ymax]}, ...], metres
// relative to the package origin. The terrain range is flat (zmin = zmax =
// 0), as the views are drawn over flat ground.
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "decal/lod.hpp"
#include "decal/reader.hpp"
#include "prep/render.hpp"

namespace R = prep::render;

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: lod_oracle PACKAGE VIEWS.json HEIGHT TOLERANCE_PX\n");
    return 2;
  }
  decal::Package pkg;
  if (const decal::Status st = decal::Package::open(argv[1], pkg); !st) {
    std::fprintf(stderr, "lod_oracle: %s: %s\n", argv[1], st.message.c_str());
    return 1;
  }
  std::ifstream in(argv[2]);
  const nlohmann::json views = nlohmann::json::parse(in, nullptr, false);
  if (!views.is_array()) {
    std::fprintf(stderr, "lod_oracle: %s: not a JSON array\n", argv[2]);
    return 1;
  }
  const auto height = static_cast<uint32_t>(std::stoul(argv[3]));
  const double tolerance = std::stod(argv[4]);
  const auto points = pkg.array<decal::BlobId::lod_points>();
  const auto segments = pkg.array<decal::BlobId::lod_segments>();
  nlohmann::json out = nlohmann::json::array();
  for (const nlohmann::json& v : views) {
    R::Camera cam;
    if (v.contains("topdown")) {
      const auto e = v["topdown"];
      cam = R::topdown_camera({e[0], e[1], e[2], e[3]}, 0, 0);
    } else {
      cam.eye = {v["eye"][0], v["eye"][1], v["eye"][2]};
      cam.target = {v["target"][0], v["target"][1], v["target"][2]};
      cam.fov_y_deg = v["fov"];
    }
    const R::LodView lv = R::lod_view(cam, height, 0, 0, tolerance);
    const std::vector<uint32_t> visible =
        decal::visible_segments(points, segments, decal::LodCamera{lv.cx, lv.cy, lv.cz},
                                decal::LinearThreshold{lv.base, lv.slope});
    out.push_back({{"name", v["name"]},
                   {"view",
                    {{"cx", lv.cx}, {"cy", lv.cy}, {"cz", lv.cz}, {"base", lv.base},
                     {"slope", lv.slope}}},
                   {"segments", segments.size()},
                   {"points", points.size()},
                   {"visible", visible}});
  }
  std::printf("%s\n", out.dump().c_str());
  return 0;
}
