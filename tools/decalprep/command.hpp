// command.hpp — how a subcommand plugs into the decalprep tool.
//
// Each cmd_<name>.cpp defines one static CommandRegistrar: the command's
// CommandHelp (name, description, --help footer) and a function that adds
// its options and sets a callback that runs the command and stores its exit
// code with set_exit_code(). Errors are thrown as prep::error
// (see prep/error.hpp); main() prints them and maps them to exit codes.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

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

// What --help says of a command: its name and one line in the list of
// commands, and the footer under its options (what the options cannot say,
// and examples; main() appends the exit codes). An empty footer adds none.
struct CommandHelp {
  const char* name;
  const char* description;
  const char* footer = "";
};

// Adds the options of a command to `cmd`, its subcommand, and sets its
// callback.
using CommandOptions = std::function<void(CLI::App* cmd)>;

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

// A package's metadata (formats/SPEC.md "Metadata"), parsed; a format_error
// "<stage>: <path>: metadata is not valid JSON: ..." when it is not JSON.
inline nlohmann::json parse_metadata(std::string_view text, const std::string& path,
                                     std::string_view stage) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    prep::fail<prep::format_error>(stage, path + ": metadata is not valid JSON: " + e.what());
  }
}

struct CommandRegistrar {
  // Registers the subcommand `help` describes, at `order` in --help, with
  // the options and callback `options` adds.
  CommandRegistrar(int order, CommandHelp help, CommandOptions options) {
    command_registry().push_back({order, [help, options = std::move(options)](CLI::App& app) {
                                    CLI::App* cmd = app.add_subcommand(help.name, help.description);
                                    if (*help.footer) cmd->footer(help.footer);
                                    options(cmd);
                                  }});
  }
};

}  // namespace decalprep
