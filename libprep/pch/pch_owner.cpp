// The owner of libprep's precompiled header (libprep/CMakeLists.txt): a
// static library compiled with the stage libraries' flags, so each stage
// that includes nlohmann-json can reuse it.
namespace prep::detail {
int pch_owner_anchor() {
  return 0;
}
}  // namespace prep::detail
