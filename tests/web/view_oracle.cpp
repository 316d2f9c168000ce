// view_oracle — what decalprep's C++ renderer chooses for a list of views,
// as JSON, for the browser's tests (tests/web):
//
//   view_oracle lod PACKAGE VIEWS.json HEIGHT TOLERANCE_PX
//     per view the parameters prep::render::lod_view gives (C, base,
//     slope) and the LOD segments decal::visible_segments keeps for them
//     (the selection `render` and its GL pass use; lod_agreement.py);
//   view_oracle tiles TILESET_DIR VIEWS.json WIDTH HEIGHT GPU_BUDGET
//     per view the tiles prep::render::select_tiles draws, with each tile's
//     decoded blob bytes from its header (decal::read_package_sizes), as
//     `render --gpu-budget` selects them (0: no budget; tile_select_test.mjs),
//     or the error a view's budget gets.
//
// VIEWS.json: [{"name", "eye": [x, y, z], "target": [x, y, z], "fov": deg,
// "near": m} | {"name", "topdown": [xmin, ymin, xmax, ymax]}, ...], metres
// relative to the package (tileset frame) origin, over flat ground at
// height 0 (zmin = zmax = 0).
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "decal/lod.hpp"
#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "prep/tile.hpp"

namespace R = prep::render;

namespace {

R::Camera camera_of(const nlohmann::json& v) {
  if (v.contains("topdown")) {
    const auto& e = v["topdown"];
    return R::topdown_camera({e[0], e[1], e[2], e[3]}, 0, 0);
  }
  R::Camera cam;
  cam.eye = {v["eye"][0], v["eye"][1], v["eye"][2]};
  cam.target = {v["target"][0], v["target"][1], v["target"][2]};
  cam.fov_y_deg = v["fov"];
  if (v.contains("near")) cam.near = v["near"];
  return cam;
}

int lod(const char* package, const nlohmann::json& views, uint32_t height, double tolerance) {
  decal::Package pkg;
  if (const decal::Status st = decal::Package::open(package, pkg); !st) {
    std::fprintf(stderr, "view_oracle: %s: %s\n", package, st.message.c_str());
    return 1;
  }
  const auto points = pkg.array<decal::BlobId::lod_points>();
  const auto segments = pkg.array<decal::BlobId::lod_segments>();
  nlohmann::json out = nlohmann::json::array();
  for (const nlohmann::json& v : views) {
    const R::LodView lv = R::lod_view(camera_of(v), height, 0, 0, tolerance);
    const std::vector<uint32_t> visible =
        decal::visible_segments(points, segments, decal::LodCamera{lv.cx, lv.cy, lv.cz},
                                decal::LinearThreshold{lv.base, lv.slope});
    out.push_back(
        {{"name", v["name"]},
         {"view",
          {{"cx", lv.cx}, {"cy", lv.cy}, {"cz", lv.cz}, {"base", lv.base}, {"slope", lv.slope}}},
         {"segments", segments.size()},
         {"points", points.size()},
         {"visible", visible}});
  }
  std::printf("%s\n", out.dump().c_str());
  return 0;
}

int tiles(const std::string& dir, const nlohmann::json& views, uint32_t width, uint32_t height,
          uint64_t budget) {
  const prep::TilesetIndex index = prep::read_tileset_index(dir);
  R::TileSelectOptions opt;
  opt.gpu_budget = budget;
  opt.blob_bytes = [&dir](int, const prep::TileEntry& t) {
    decal::PackageSizes sizes;
    if (const decal::Status s = decal::read_package_sizes(dir + "/" + t.file, sizes); !s)
      throw std::runtime_error(s.message);
    return sizes.raw_bytes;
  };
  nlohmann::json out = nlohmann::json::array();
  for (const nlohmann::json& v : views) {
    R::TileSelection s;
    try {
      s = R::select_tiles(index, camera_of(v), width, height, 0, 0, opt);
    } catch (const prep::error& e) {  // a budget even the coarsest tiles exceed
      out.push_back({{"name", v["name"]}, {"error", e.what()}});
      continue;
    }
    nlohmann::json drawn = nlohmann::json::array();
    for (const R::SelectedTile& t : s.tiles)
      drawn.push_back({t.level, t.entry->key.x, t.entry->key.y, t.blob_bytes});
    out.push_back({{"name", v["name"]},
                   {"tiles", drawn},
                   {"blob_bytes", s.blob_bytes},
                   {"package_bytes", s.package_bytes},
                   {"full_detail_bytes", s.full_detail_bytes},
                   {"full_detail_tiles", s.full_detail_tiles},
                   {"coarsened", s.coarsened}});
  }
  std::printf("%s\n", out.dump().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (!((mode == "lod" && argc == 6) || (mode == "tiles" && argc == 7))) {
    std::fprintf(stderr,
                 "usage: view_oracle lod PACKAGE VIEWS.json HEIGHT TOLERANCE_PX\n"
                 "       view_oracle tiles TILESET_DIR VIEWS.json WIDTH HEIGHT GPU_BUDGET\n");
    return 2;
  }
  std::ifstream in(argv[3]);
  const nlohmann::json views = nlohmann::json::parse(in, nullptr, false);
  if (!views.is_array()) {
    std::fprintf(stderr, "view_oracle: %s: not a JSON array\n", argv[3]);
    return 1;
  }
  try {
    if (mode == "lod")
      return lod(argv[2], views, static_cast<uint32_t>(std::stoul(argv[4])), std::stod(argv[5]));
    return tiles(argv[2], views, static_cast<uint32_t>(std::stoul(argv[4])),
                 static_cast<uint32_t>(std::stoul(argv[5])), std::stoull(argv[6]));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "view_oracle: %s\n", e.what());
    return 1;
  }
}
