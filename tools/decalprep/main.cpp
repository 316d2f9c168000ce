// decalprep — GIS vector data to GPU-ready decal packages.
// Thin main: parses the command line and dispatches to the registered
// subcommands (cmd_*.cpp). Exit codes: prep::ExitCode (docs/cli.md "Exit codes").
#include <algorithm>
#include <cstdio>
#include <exception>
#include <iostream>

#include "command.hpp"
#include "decal/format.hpp"
#include "prep/render.hpp"
#include "prep/tile.hpp"

namespace {

constexpr const char* kExitCodes = R"(Exit codes:
  0 ok, 1 internal error, 2 usage, 3 input, 4 partial (--skip-failures),
  5 corrupt or unsupported package, 6 resource (--max-memory, budgets), 7 output
  (a target that is not a regular file, or is an input, is refused), 8 render,
  9 empty: build kept no feature (--allow-empty writes the package, exit 0),
  10 --strict made a warning an error (build: a layer that read nothing, heights
  outside the DEM; render: a view or DEM that does not cover), 11 a batch scene
  was killed by a signal, 130/143 stopped by SIGINT/SIGTERM (what the build made
  is removed))";

constexpr const char* kExamples = R"(Examples:
  decalprep build scene.toml -o city.decals --report city.report.json
  decalprep build roads.shp -o roads.decals --kind line --width 4 --corner miter
  decalprep info city.decals --json
  decalprep verify city.decals
  decalprep render city.decals --fit --size 640x360 -o city.png)";

// --version: the program's version (CMake's project version, the one place
// it is set) and the versions of the formats it writes and reads.
std::string version_text() {
  auto v = [](int major, int minor) { return std::to_string(major) + "." + std::to_string(minor); };
  return std::string("decalprep ") + DECALPREP_VERSION +
         "\ndecal packages (formats/SPEC.md): writes " +
         v(decal::kVersionMajor, decal::kVersionMinor) + ", reads " +
         std::to_string(decal::kVersionMajor) + ".x" + "\ntilesets (tileset.json): writes " +
         v(prep::kTilesetMajor, prep::kTilesetMinor) + " (" +
         v(prep::kTilesetMajor, prep::kTilesetMinorLevels) + " with overview levels), reads " +
         std::to_string(prep::kTilesetMajor) + ".x" + "\nterrain files: writes " +
         v(prep::render::kTerrainFileMajor, prep::render::kTerrainFileMinor) + ", reads " +
         std::to_string(prep::render::kTerrainFileMajor) + ".x";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"decalprep: GIS vector data to GPU-ready decal packages"};
  app.footer(std::string(kExamples) + "\n\n" + kExitCodes);
  app.set_version_flag("--version", version_text());
  app.require_subcommand(1);

  auto& registry = decalprep::command_registry();
  std::ranges::stable_sort(registry, {}, &decalprep::CommandEntry::order);
  for (auto& entry : registry) entry.setup(app);
  // Every command's --help ends with the exit codes, --allow-empty's and
  // --strict's among them.
  for (CLI::App* sub : app.get_subcommands({}))
    sub->footer(sub->get_footer().empty() ? std::string(kExitCodes)
                                          : sub->get_footer() + "\n\n" + kExitCodes);

  decalprep::command_line().assign(argv, argv + argc);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int rc = app.exit(e);
    // CLI11 returns 0 for --help/--version; anything else is a usage error.
    return rc == 0 ? 0 : static_cast<int>(prep::ExitCode::usage);
  } catch (const prep::error& e) {
    std::fprintf(stderr, "decalprep: %s\n", e.what());
    return static_cast<int>(e.code());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "decalprep: out of memory\n");
    return static_cast<int>(prep::ExitCode::resource);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "decalprep: internal error: %s\n", e.what());
    return static_cast<int>(prep::ExitCode::internal);
  }
  return decalprep::exit_code_slot();
}
