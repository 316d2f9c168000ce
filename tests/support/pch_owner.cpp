// The owner of the tests' precompiled header (tests/CMakeLists.txt): an
// executable compiled with the tests' flags, so every test can reuse it.
int main() {
  return 0;
}
