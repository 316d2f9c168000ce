// Opens and validates (decal::validate_indices, as every consumer does) each
// package named on the command line with the installed reader and prints "ok <path> <major>.<minor>
// <blobs>" or "error <path>: <message>". Exit status: 0 when every "valid_*" file opens and every
// other one is refused, 1 otherwise.
#include <cstdio>
#include <string>

#include "decal/inspect.hpp"
#include "decal/reader.hpp"

int main(int argc, char** argv) {
  int wrong = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string path = argv[i];
    const bool expect_ok = path.find("valid_") != std::string::npos;
    decal::Package pkg;
    decal::Status s = decal::Package::open(path, pkg);
    if (s) s = decal::validate_indices(pkg);
    if (s)
      std::printf("ok %s %u.%u %zu\n", path.c_str(), unsigned(pkg.major()), unsigned(pkg.minor()),
                  pkg.blobs().size());
    else
      std::printf("error %s\n", s.message.c_str());
    if (bool(s) != expect_ok) {
      std::printf("UNEXPECTED: %s %s\n", path.c_str(), expect_ok ? "was refused" : "was accepted");
      ++wrong;
    }
  }
  return wrong == 0 ? 0 : 1;
}
