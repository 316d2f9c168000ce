// prep/stage_error.hpp — the one place a failure message gets its prefix.
//
// Every libprep message starts with the stage or module that failed
// ("clean: ...", "dem: ..."; prep/error.hpp). A source file names its stage
// once, as a constant, and throws through fail<E>(stage, what), so the prefix
// and its form are written here and nowhere else.
#pragma once

#include <string>
#include <string_view>
#include <type_traits>

#include "prep/error.hpp"

namespace prep {

// Throws E (a prep::error) with the message "<stage>: <what>".
template <class E>
[[noreturn]] void fail(std::string_view stage, const std::string& what) {
  static_assert(std::is_base_of_v<error, E>, "fail<E>: E must derive from prep::error");
  throw E(std::string(stage) + ": " + what);
}

}  // namespace prep
