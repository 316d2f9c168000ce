// decalprep — GIS vector data to GPU-ready decal packages.
// Thin main: parses the command line and dispatches to the registered
// subcommands (cmd_*.cpp). Exit codes: prep::ExitCode (README "Exit codes").
#include <algorithm>
#include <cstdio>
#include <exception>
#include <iostream>

#include "command.hpp"

namespace {

constexpr const char* kFooter = R"(Examples:
  decalprep build scene.toml -o city.decals --report city.report.json
  decalprep build roads.shp -o roads.decals --kind line --width 4 --corner miter
  decalprep info city.decals --json
  decalprep verify city.decals
  decalprep render city.decals --fit --size 640x360 -o city.png

Exit codes:
  0 ok, 1 internal error, 2 usage, 3 input, 4 partial (--skip-failures),
  5 corrupt or unsupported package, 6 resource (--max-memory, budgets), 7 output,
  8 render)";

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"decalprep: GIS vector data to GPU-ready decal packages"};
  app.footer(kFooter);
  app.set_version_flag("--version", std::string("decalprep ") + DECALPREP_VERSION);
  app.require_subcommand(1);

  auto& registry = decalprep::command_registry();
  std::ranges::stable_sort(registry, {}, &decalprep::CommandEntry::order);
  for (auto& entry : registry) entry.setup(app);

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
