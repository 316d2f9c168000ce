// cmd_terrain.cpp — `decalprep terrain PACKAGE|TILESET [--dem DEM] [-o OUT]`:
// writes the terrain mesh `render` draws (prep::render::make_terrain) as a
// terrain file (formats/SPEC.md "Terrain files") beside the package, for
// readers without GDAL (the browser). A tileset gets one per tile package
// and DIR/tileset.terrain, the mesh `render DIR` draws.
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "command.hpp"
#include "decal/reader.hpp"
#include "prep/files.hpp"
#include "prep/progress.hpp"
#include "prep/render.hpp"
#include "prep/tile.hpp"

namespace {
// The command's own names (the unity build joins the cmd_*.cpp files).
namespace terrain_cmd {

namespace R = prep::render;
namespace fs = std::filesystem;
using prep::kTerrainStage;

struct TerrainArgs {
  std::string path, output, progress;
  std::vector<std::string> dem;  // --dem, repeated for a mosaic
  bool json = false, quiet = false;
};

// One terrain file to write: what it is made of and where it goes.
struct Target {
  std::string package;  // the package, or the tileset folder
  std::string output;
  bool named = false;  // the user's -o
};

// STEM.terrain beside STEM.decals (any other name: its extension replaced).
std::string beside(const std::string& package) {
  return fs::path(package).replace_extension(".terrain").string();
}

// The output rule (prep/files.hpp) plus one of this command's own: a file
// it did not name with -o is replaced only when it is a terrain file, one
// this command wrote, so a stray STEM.terrain of something else survives.
void check_target(const Target& t, const std::vector<std::string>& inputs) {
  prep::check_output_file(t.output, "terrain file", inputs);
  if (t.named || !fs::exists(t.output)) return;
  std::array<char, 8> head{};
  std::ifstream in(t.output, std::ios::binary);
  in.read(head.data(), head.size());
  if (!in || std::memcmp(head.data(), R::kTerrainMagic.data(), head.size()) != 0)
    prep::fail<prep::output_error>(
        kTerrainStage, "'" + t.output +
                           "' exists and is not a terrain file; it is left as it is (name it "
                           "with -o to replace it)");
}

// The DEM `render` uses for this package: --dem with the package's surface
// settings, else the DEM its metadata records.
prep::DemSpec choose_dem(const std::string& metadata, const std::string& package,
                         const std::vector<std::string>& user_dem) {
  prep::DemSpec dem = R::recorded_dem(metadata, package);
  if (!user_dem.empty()) {
    dem.path = user_dem[0];
    dem.more_paths.assign(user_dem.begin() + 1, user_dem.end());
    dem.named_by_package = false;
  }
  if (dem.path.empty())
    prep::fail<prep::usage_error>(
        kTerrainStage,
        package + ": the package records no DEM (build_options.dem); pass --dem DEM");
  return dem;
}

// The files the terrain is made from, which no output may be.
std::vector<std::string> terrain_inputs(const std::string& source, const prep::DemSpec& dem) {
  std::vector<std::string> in{source, dem.path};
  in.insert(in.end(), dem.more_paths.begin(), dem.more_paths.end());
  return in;
}

void open_package(const std::string& path, decal::Package& pkg) {
  if (const decal::Status s = decal::Package::open(path, pkg); !s)
    prep::fail<prep::format_error>(prep::kNoStage, s.message);
}

uint64_t digest(const std::string& path) {
  std::string why;
  const auto d = prep::file_digest(path, &why);
  if (!d) prep::fail<prep::input_error>(kTerrainStage, "cannot read '" + path + "': " + why);
  return d->xxh64;
}

// What was written, for the summary line (or --json).
struct Written {
  std::string path;
  R::TerrainFile terrain;
  uint64_t bytes = 0;
};

Written write_terrain(const Target& t, const R::TerrainFile& terrain) {
  const std::string bytes = R::encode_terrain(terrain);
  prep::write_file_atomically(t.output, bytes, "terrain file");
  return {t.output, terrain, bytes.size()};
}

// A package: the mesh over its extent in its frame (render's open_scene).
Written package_terrain(const Target& t, const std::vector<std::string>& user_dem) {
  decal::Package pkg;
  open_package(t.package, pkg);
  const R::DecalSource src = R::source_of(pkg);
  const prep::DemSpec dem = choose_dem(std::string(pkg.metadata_json()), t.package, user_dem);
  check_target(t, terrain_inputs(t.package, dem));
  return write_terrain(t, R::make_terrain(dem, src.frame, src.extent, digest(t.package)));
}

// A tileset: the mesh over the index's extent in the tileset frame, with
// the first tile's DEM (render's open_scene for a tileset).
Written tileset_terrain(const Target& t, const prep::TilesetIndex& ix,
                        const std::vector<std::string>& user_dem) {
  std::string metadata, first;
  if (!ix.tiles.empty()) {
    first = t.package + "/" + ix.tiles.front().file;
    decal::Package pkg;
    open_package(first, pkg);
    metadata = std::string(pkg.metadata_json());
  }
  const prep::DemSpec dem = choose_dem(metadata, first.empty() ? t.package : first, user_dem);
  check_target(t, terrain_inputs(t.package + "/tileset.json", dem));
  const double ox = ix.frame.origin_x, oy = ix.frame.origin_y;
  const prep::Extent e{ix.extent.xmin - ox, ix.extent.ymin - oy, ix.extent.xmax - ox,
                       ix.extent.ymax - oy};
  return write_terrain(t, R::make_terrain(dem, ix.frame, e, digest(t.package + "/tileset.json")));
}

std::vector<Written> run_tileset(const TerrainArgs& a) {
  if (!a.output.empty())
    prep::fail<prep::usage_error>(kTerrainStage,
                                  "-o names one file; a tileset gets one terrain file beside "
                                  "each tile package and " +
                                      a.path + "/tileset.terrain");
  const prep::TilesetIndex ix = prep::read_tileset_index(a.path);
  std::vector<Target> tiles;
  for (const prep::TileEntry& e : ix.tiles)
    tiles.push_back({a.path + "/" + e.file, beside(a.path + "/" + e.file)});
  for (const prep::TileLevel& l : ix.levels)
    for (const prep::TileEntry& e : l.tiles)
      tiles.push_back({a.path + "/" + e.file, beside(a.path + "/" + e.file)});
  // Every target checked before the first is written.
  for (const Target& t : tiles) prep::check_output_file(t.output, "terrain file", {t.package});
  const Target whole{a.path, a.path + "/tileset.terrain"};
  prep::check_output_file(whole.output, "terrain file", {a.path + "/tileset.json"});

  prep::ProgressOptions po;
  po.mode = prep::parse_progress_mode(!a.progress.empty() ? a.progress
                                      : a.quiet           ? "none"
                                                          : "auto",
                                      isatty(STDERR_FILENO) != 0);
  prep::Progress progress(po);
  prep::ProgressStage stage(&progress, "terrain", tiles.size() + 1, "files");
  std::vector<Written> out;
  out.push_back(tileset_terrain(whole, ix, a.dem));
  stage.add();
  for (const Target& t : tiles) {
    out.push_back(package_terrain(t, a.dem));
    stage.add();
  }
  stage.finish();
  return out;
}

nlohmann::ordered_json to_json(const Written& w) {
  const R::Heightfield& h = w.terrain.mesh;
  nlohmann::ordered_json j = {{"path", w.path}, {"bytes", w.bytes}, {"nx", h.nx}, {"ny", h.ny}};
  // x0, y0, dx, dy, zmin, zmax by their SPEC names; the origin as a pair.
  for (const auto& [name, v] : R::terrain_fields(w.terrain))
    if (std::string_view(name).substr(0, 6) != "origin") j[name] = v;
  j["origin"] = {w.terrain.origin_x, w.terrain.origin_y};
  j["source_xxh64"] = prep::hex64(w.terrain.source_xxh64);
  // JSON has no infinity: null when the mesh has no bound.
  j["surface_error_bound_m"] = std::isfinite(h.surface_error_bound)
                                   ? nlohmann::ordered_json(h.surface_error_bound)
                                   : nlohmann::ordered_json(nullptr);
  return j;
}

void run(const TerrainArgs& a) {
  std::vector<Written> out;
  if (prep::is_tileset(a.path)) {
    out = run_tileset(a);
  } else {
    const Target t{a.path, a.output.empty() ? beside(a.path) : a.output, !a.output.empty()};
    out.push_back(package_terrain(t, a.dem));
  }
  if (a.json) {
    nlohmann::ordered_json files = nlohmann::ordered_json::array();
    for (const Written& w : out) files.push_back(to_json(w));
    std::printf("%s\n", nlohmann::ordered_json{{"files", files}}.dump(2).c_str());
    return;
  }
  if (a.quiet) return;
  for (const Written& w : out) {
    const R::Heightfield& h = w.terrain.mesh;
    std::printf("%s: %ux%u vertices every %.3f x %.3f m, heights %.3f..%.3f m, %llu bytes\n",
                w.path.c_str(), h.nx, h.ny, h.dx, h.dy, h.zmin, h.zmax,
                static_cast<unsigned long long>(w.bytes));
  }
}

}  // namespace terrain_cmd

constexpr decalprep::CommandHelp kTerrainHelp{
    "terrain", "Write the terrain mesh render draws as a .terrain file (for the browser)",
    "The file is STEM.terrain beside STEM.decals unless -o names it; an existing file there is\n"
    "replaced only when it is a terrain file. A tileset gets TILE.terrain beside every tile\n"
    "package and DIR/tileset.terrain. The mesh is the one `render --dem DEM` draws with --fit,\n"
    "--eye/--target or an --extent inside the package (formats/SPEC.md \"Terrain files\").\n"
    "Examples:\n"
    "  decalprep terrain city.decals                   # city.terrain, the build's DEM\n"
    "  decalprep terrain city.decals --dem dem.tif -o city.terrain\n"
    "  decalprep terrain city.tiles/"};

const decalprep::CommandRegistrar kTerrain(65, kTerrainHelp, [](CLI::App* cmd) {
  auto args = std::make_shared<terrain_cmd::TerrainArgs>();
  cmd->add_option("package", args->path, "Package (.decals) or tileset directory")->required();
  cmd->add_option("--dem", args->dem,
                  "DEM raster (any GDAL path); default: the DEM the package was built with; "
                  "repeat it to mosaic several")
      ->allow_extra_args(false);
  cmd->add_option("-o,--output", args->output,
                  "Output file (default: STEM.terrain beside the package; not for a tileset)");
  cmd->add_flag("--json", args->json, "Print what was written as JSON");
  cmd->add_flag("-q,--quiet", args->quiet, "Print nothing on success");
  cmd->add_option("--progress", args->progress,
                  "Tileset progress on stderr: auto|tty|plain|json|none (default auto; none "
                  "with -q)");
  cmd->callback([args] {
    terrain_cmd::run(*args);
    decalprep::set_exit_code(prep::ExitCode::ok);
  });
});

}  // namespace
