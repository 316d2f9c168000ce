// prep/stage_error.hpp — the one place a failure message gets its prefix.
//
// Every libprep message starts with the stage or module that failed
// ("clean: ...", "dem: ..."; prep/error.hpp). The stage and module names are
// the constants below, and a source file throws through fail<E>(stage, what)
// with the one it reports as, so the names, the prefix and its form are
// written here and nowhere else. A note, a manifest reason or a line a tool
// prints with a stage prefix builds it with stage_message(). scripts/check-style
// (errors) reads the constants from this file and refuses a string literal in
// libprep/ or tools/ that starts with "<stage>: ", and any `throw` there
// other than `throw;`, a std:: exception and the one in fail() below.
#pragma once

#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include "prep/error.hpp"

namespace prep {

inline constexpr std::string_view kReadStage = "read";
inline constexpr std::string_view kProjectStage = "project";
inline constexpr std::string_view kTileStage = "tile";
inline constexpr std::string_view kBuildStage = "build";  // stage 4 (model) and the pipeline
inline constexpr std::string_view kTerrainStage = "terrain";
inline constexpr std::string_view kLodStage = "lod";
inline constexpr std::string_view kWriteStage = "write";
inline constexpr std::string_view kTilesetStage = "tileset";
inline constexpr std::string_view kReportStage = "report";
inline constexpr std::string_view kDemStage = "dem";
inline constexpr std::string_view kMemoryStage = "memory";
inline constexpr std::string_view kEvaluateStage = "evaluate";
inline constexpr std::string_view kRenderStage = "render";
inline constexpr std::string_view kCleanStage = "clean";
// The decalprep commands that are not stages of a build.
inline constexpr std::string_view kInfoStage = "info";
inline constexpr std::string_view kDumpStage = "dump";
// No prefix: the message says its place itself (a command-line option
// "--width: ...", a file and line "scene.toml:12: ...", a path), or it
// already carries one (a message passed on from another stage, or from a
// decal::Status of formats/).
inline constexpr std::string_view kNoStage = "";

// "<stage>: <what>" (just <what> for kNoStage): the form of every prefixed
// message.
inline std::string stage_message(std::string_view stage, std::string_view what) {
  std::string m;
  if (!stage.empty()) {
    m.reserve(stage.size() + 2 + what.size());
    m.append(stage).append(": ");
  }
  m.append(what);
  return m;
}

// Throws E (a prep::error) with the message stage_message(stage, what);
// `more` goes to E's constructor after the message (prep::error's ExitCode).
template <class E, class... More>
[[noreturn]] void fail(std::string_view stage, const std::string& what, More&&... more) {
  static_assert(std::is_base_of_v<error, E>, "fail<E>: E must derive from prep::error");
  throw E(stage_message(stage, what), std::forward<More>(more)...);
}

}  // namespace prep
