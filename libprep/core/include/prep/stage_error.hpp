// prep/stage_error.hpp — the one place a failure message gets its prefix.
//
// Every libprep message starts with the stage or module that failed
// ("clean: ...", "dem: ..."; prep/error.hpp). The stage and module names are
// the constants below, and a source file throws through fail<E>(stage, what)
// with the one it reports as, so the names, the prefix and its form are
// written here and nowhere else.
#pragma once

#include <string>
#include <string_view>
#include <type_traits>

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

// Throws E (a prep::error) with the message "<stage>: <what>".
template <class E>
[[noreturn]] void fail(std::string_view stage, const std::string& what) {
  static_assert(std::is_base_of_v<error, E>, "fail<E>: E must derive from prep::error");
  throw E(std::string(stage) + ": " + what);
}

}  // namespace prep
