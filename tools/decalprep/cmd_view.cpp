// cmd_view.cpp — `decalprep view PACKAGE|TILESET [--bind ADDR] [--port N]`:
// serves the browser viewer and the data over HTTP (prep/view.hpp) until
// SIGINT or SIGTERM.
#include <cstdio>
#include <memory>
#include <string>

#include "command.hpp"
#include "prep/view.hpp"

namespace {

constexpr decalprep::CommandHelp kViewHelp{
    "view", "Serve a package or tileset to the browser viewer",
    "Serves the viewer page (web/, built into decalprep) and the data over HTTP, and prints\n"
    "the URL to open. Only the package and its side files (STEM.* next to STEM.decals), or the\n"
    "files under the tileset folder, are served; never a listing, a path with '..' or a link\n"
    "that leads out. Listens on 127.0.0.1 unless --bind says otherwise. Stop with Ctrl-C.\n"
    "Examples:\n  decalprep view city.decals\n  decalprep view country/ --port 0\n"
    "  decalprep view city.decals --bind 0.0.0.0 --port 8000"};

const decalprep::CommandRegistrar kView(70, kViewHelp, [](CLI::App* cmd) {
  auto opt = std::make_shared<prep::view::ServeOptions>();
  cmd->add_option("PATH", opt->path,
                  "the .decals package, or a tileset folder (or its tileset.json)")
      ->required();
  cmd->add_option("--bind", opt->bind,
                  "the address to listen on (default 127.0.0.1: this machine only)");
  cmd->add_option("--port", opt->port, "the port (default 8080; 0: a free one)")
      ->check(CLI::Range(0, 65535));
  cmd->callback([opt] {
    prep::view::serve(*opt, [](const std::string& url) {
      std::printf("decalprep view: serving on %s (Ctrl-C stops)\n", url.c_str());
      std::fflush(stdout);
    });
    decalprep::set_exit_code(prep::ExitCode::ok);
  });
});

}  // namespace
