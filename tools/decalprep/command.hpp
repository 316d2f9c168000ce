// command.hpp — how a subcommand plugs into the decalprep tool.
//
// Each cmd_<name>.cpp defines one static CommandRegistrar. Its setup function
// adds a CLI11 subcommand and sets a callback that runs the command and
// stores its exit code with set_exit_code(). Errors are thrown as prep::error
// (see prep/error.hpp); main() prints them and maps them to exit codes.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

#include "prep/error.hpp"

namespace decalprep {

using CommandSetup = std::function<void(CLI::App& app)>;

struct CommandEntry {
  int order;  // position in --help
  CommandSetup setup;
};

inline std::vector<CommandEntry>& command_registry() {
  static std::vector<CommandEntry> registry;
  return registry;
}

inline int& exit_code_slot() {
  static int code = 0;
  return code;
}
inline void set_exit_code(prep::ExitCode c) {
  exit_code_slot() = static_cast<int>(c);
}
inline void set_exit_code(int c) {
  exit_code_slot() = c;
}

// The command line as given (main() fills it before parsing), for commands
// that write command lines of their own (build --plan).
inline std::vector<std::string>& command_line() {
  static std::vector<std::string> args;
  return args;
}

struct CommandRegistrar {
  CommandRegistrar(int order, CommandSetup setup) {
    command_registry().push_back({order, std::move(setup)});
  }
};

}  // namespace decalprep
