// command.hpp — how a subcommand plugs into the decalprep tool.
//
// Each cmd_<name>.cpp defines one static CommandRegistrar. Its setup function
// adds a CLI11 subcommand and sets a callback that runs the command and
// stores its exit code with set_exit_code(). Errors are thrown as prep::error
// (see prep/error.hpp); main() prints them and maps them to exit codes.
#pragma once

#include <CLI/CLI.hpp>

#include <cstdarg>
#include <cstdio>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"

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

// Prints a line a command reports as a stage or command (a constant of
// prep/stage_error.hpp) on stderr: "<stage>: " and the printf-formatted
// rest, as one write, the same prefix fail<E>() gives what it throws.
[[gnu::format(printf, 2, 3)]] inline void print_stage(std::string_view stage, const char* format,
                                                      ...) {
  va_list args;
  va_start(args, format);
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, format, args);
  va_end(args);
  std::string text(n > 0 ? size_t(n) : 0, '\0');
  if (n > 0) std::vsnprintf(text.data(), text.size() + 1, format, again);
  va_end(again);
  std::fputs(prep::stage_message(stage, text).c_str(), stderr);
}

struct CommandRegistrar {
  CommandRegistrar(int order, CommandSetup setup) {
    command_registry().push_back({order, std::move(setup)});
  }
};

}  // namespace decalprep
