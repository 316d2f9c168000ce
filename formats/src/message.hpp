// formats/src/message.hpp — printf-style message text for the reader's
// failures (reader.cpp, validate.cpp). Not installed.
#pragma once

#include <cstdio>
#include <string>

namespace decal::detail {

// The message f formats with args, cut at 511 bytes.
inline std::string fmt(const char* f, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

}  // namespace decal::detail
