// c_api_hostile_test — the C API (decal/decal.h, libdecal) on the checked-in
// seed packages and on hostile variants made here from the valid ones, from
// a path and from memory. Run under ASan+UBSan in the fuzz build (ctest
// label fuzz-smoke) and plainly in the others.
//
//   valid seeds       open (path and memory) and decode, and what the C API
//                     hands out equals the C++ reader's blobs (forwarding),
//                     also once the caller's bytes given to
//                     decal_open_memory are overwritten and freed;
//   broken_* seeds    are refused with a status and a message (the major
//                     version and the unknown required flag as
//                     DECAL_ERROR_UNSUPPORTED_VERSION);
//   every truncation  of a valid seed (each prefix) is refused;
//   every bit flip    of a valid seed (one per byte) is refused: a checksum,
//                     a reserved field or zero padding covers every byte;
//   resealed flips    (checksums recomputed, tests/formats/reseal.hpp) get
//                     the C++ reader's verdict (Package + validate_indices),
//                     and what opens decodes to the reader's bytes;
//   arguments         NULL pointers, unknown flags, a missing file, a
//                     directory, a too-small buffer give their documented
//                     status and leave the caller's memory alone.
//
// Usage: c_api_hostile_test <fuzz/corpus/read> <scratch directory>
// Prints one line per group and every failure; exit 0 when none failed.
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "decal/decal.h"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "reseal.hpp"

namespace fs = std::filesystem;

namespace {

int g_failures = 0;

#define EXPECT(cond, ...)                                         \
  do {                                                            \
    if (!(cond)) {                                                \
      ++g_failures;                                               \
      std::printf("FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond); \
      std::printf(__VA_ARGS__);                                   \
      std::printf("\n");                                          \
    }                                                             \
  } while (0)

using Bytes = std::vector<std::byte>;

Bytes read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::vector<char> c((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Bytes b(c.size());
  if (!c.empty()) std::memcpy(b.data(), c.data(), c.size());
  return b;
}

void write_file(const fs::path& p, const Bytes& b) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// Inflation kept small: a hostile variant must not make the test allocate
// gigabytes (ASan would report that as a failure of its own).
decal_open_options options() {
  decal_open_options o{};
  o.max_raw_size = uint64_t(64) << 20;
  return o;
}

// Reads every blob of `p` through decal_blob_read and decal_blob_data and
// checks that both give the same bytes of the announced size. Returns them.
std::vector<Bytes> decode_all(const decal_package* p, const std::string& label) {
  std::vector<Bytes> out;
  for (uint32_t i = 0; i < decal_blob_count(p); ++i) {
    decal_blob_info info{};
    decal_error e{};
    EXPECT(decal_blob_info_at(p, i, &info, &e) == DECAL_OK, "%s blob %u: %s", label.c_str(), i,
           e.message);
    EXPECT(info.raw_size == info.count * info.stride, "%s blob %u: raw size", label.c_str(), i);
    size_t needed = 0;
    EXPECT(decal_blob_read(p, i, nullptr, 0, &needed, nullptr) ==
               (info.raw_size ? DECAL_ERROR_BUFFER_TOO_SMALL : DECAL_OK),
           "%s blob %u: size query", label.c_str(), i);
    EXPECT(needed == info.raw_size, "%s blob %u: needed %zu", label.c_str(), i, needed);
    Bytes bytes(needed);
    EXPECT(decal_blob_read(p, i, bytes.data(), bytes.size(), &needed, &e) == DECAL_OK,
           "%s blob %u: %s", label.c_str(), i, e.message);
    const void* data = nullptr;
    size_t size = 1;
    EXPECT(decal_blob_data(p, i, &data, &size, &e) == DECAL_OK, "%s blob %u: %s", label.c_str(), i,
           e.message);
    EXPECT(size == bytes.size() && (size == 0 || std::memcmp(data, bytes.data(), size) == 0),
           "%s blob %u: decal_blob_data differs from decal_blob_read", label.c_str(), i);
    out.push_back(std::move(bytes));
  }
  return out;
}

// What the C++ reader makes of `bytes`: opened and index-checked, or not.
bool cpp_accepts(const Bytes& bytes, decal::Package& pkg) {
  decal::OpenOptions o;
  o.max_raw_bytes = options().max_raw_size;
  decal::Status s = decal::Package::from_memory(bytes, pkg, o);
  if (s) s = decal::validate_indices(pkg);
  return bool(s);
}

// The C API's package equals the C++ reader's: table, metadata, bytes.
void expect_forwarded(const decal_package* p, const decal::Package& ref, const std::string& label) {
  const auto blobs = ref.blobs();
  EXPECT(decal_blob_count(p) == blobs.size(), "%s: %u blobs, reader %zu", label.c_str(),
         decal_blob_count(p), blobs.size());
  uint32_t major = 0, minor = 0;
  EXPECT(decal_package_version(p, &major, &minor, nullptr) == DECAL_OK && major == ref.major() &&
             minor == ref.minor(),
         "%s: version", label.c_str());
  EXPECT(decal_package_flags(p) == ref.flags(), "%s: flags", label.c_str());
  const char* text = nullptr;
  size_t size = 0;
  EXPECT(decal_metadata(p, &text, &size, nullptr) == DECAL_OK &&
             std::string_view(text, size) == ref.metadata_json() && text[size] == '\0',
         "%s: metadata", label.c_str());
  const std::vector<Bytes> decoded = decode_all(p, label);
  for (size_t i = 0; i < blobs.size() && i < decoded.size(); ++i) {
    const decal::BlobView& b = blobs[i];
    decal_blob_info info{};
    decal_blob_info_at(p, uint32_t(i), &info, nullptr);
    EXPECT(info.index == i && info.id == b.id && b.name == info.name &&
               info.element_type == uint32_t(b.type) && info.stride == b.stride &&
               info.count == b.count && info.codec == uint32_t(b.codec) &&
               info.stored_size == b.stored_bytes && info.known == (b.known() ? 1u : 0u),
           "%s blob %zu: info differs from the reader's", label.c_str(), i);
    EXPECT(decoded[i].size() == b.bytes.size() &&
               std::equal(decoded[i].begin(), decoded[i].end(), b.bytes.begin()),
           "%s blob %zu: bytes differ from the reader's", label.c_str(), i);
    uint32_t found = ~0u;
    EXPECT(decal_find_blob(p, b.name.c_str(), &found, nullptr) == DECAL_OK && found == i,
           "%s: find '%s'", label.c_str(), b.name.c_str());
    EXPECT(decal_find_blob_id(p, b.id, &found, nullptr) == DECAL_OK && found == i, "%s: find id %u",
           label.c_str(), b.id);
  }
}

// A refusal: a failure status, no package, a message, and the code in *code.
bool refused(decal_status s, const decal_package* p, const decal_error& e, const char* how,
             const std::string& label) {
  EXPECT(s != DECAL_OK && p == nullptr && e.code == s && e.message[0] != '\0',
         "%s (%s) was not refused properly: %s", label.c_str(), how, decal_status_name(s));
  return s != DECAL_OK;
}

decal_status open_memory(const Bytes& b, decal_package** p, decal_error* e) {
  const decal_open_options o = options();
  return decal_open_memory(b.data(), b.size(), &o, p, e);
}

decal_status open_path(const fs::path& path, decal_package** p, decal_error* e) {
  const decal_open_options o = options();
  return decal_open_file(path.c_str(), &o, p, e);
}

// A variant that must be refused, from memory and (when `also_path`) from
// a file in `scratch`. Returns the memory status.
decal_status expect_refused(const Bytes& b, bool also_path, const fs::path& scratch,
                            const std::string& label) {
  auto* p = reinterpret_cast<decal_package*>(1);
  decal_error e{};
  const decal_status s = open_memory(b, &p, &e);
  if (!refused(s, p, e, "memory", label)) decal_close(p);
  if (also_path) {
    write_file(scratch / "variant.decals", b);
    p = reinterpret_cast<decal_package*>(1);
    const decal_status sp = open_path(scratch / "variant.decals", &p, &e);
    if (!refused(sp, p, e, "path", label)) decal_close(p);
    EXPECT(sp == s, "%s: path gives %s, memory %s", label.c_str(), decal_status_name(sp),
           decal_status_name(s));
  }
  return s;
}

// decal_open_memory copies: the caller's bytes may be overwritten and freed
// at once (ASan would report a read of freed memory).
void check_memory_is_copied(const fs::path& path, const Bytes& bytes, const decal::Package& ref) {
  const std::string label = path.filename().string() + " (caller's bytes freed)";
  auto* copy = new std::byte[bytes.size()];
  std::memcpy(copy, bytes.data(), bytes.size());
  decal_package* p = nullptr;
  const decal_open_options o = options();
  const decal_status s = decal_open_memory(copy, bytes.size(), &o, &p, nullptr);
  std::memset(copy, 0xFF, bytes.size());
  delete[] copy;
  EXPECT(s == DECAL_OK, "%s: %s", label.c_str(), decal_status_name(s));
  if (s == DECAL_OK) expect_forwarded(p, ref, label);
  decal_close(p);
}

void check_valid_seed(const fs::path& path, const Bytes& bytes) {
  const std::string label = path.filename().string();
  decal::Package ref;
  EXPECT(cpp_accepts(bytes, ref), "%s: the C++ reader refuses a valid seed", label.c_str());
  for (int from_path = 0; from_path < 2; ++from_path) {
    for (uint32_t flags : {0u, unsigned(DECAL_OPEN_NO_MMAP)}) {
      decal_package* p = nullptr;
      decal_error e{};
      decal_open_options o = options();
      o.flags = flags;
      const decal_status s = from_path ? decal_open_file(path.c_str(), &o, &p, &e)
                                       : decal_open_memory(bytes.data(), bytes.size(), &o, &p, &e);
      EXPECT(s == DECAL_OK && p && e.code == DECAL_OK && e.message[0] == '\0', "%s: %s: %s",
             label.c_str(), decal_status_name(s), e.message);
      if (s == DECAL_OK) expect_forwarded(p, ref, label);
      decal_close(p);
    }
  }
  check_memory_is_copied(path, bytes, ref);
}

void check_broken_seed(const fs::path& path, const fs::path& scratch) {
  const std::string label = path.filename().string();
  const decal_status s = expect_refused(read_file(path), true, scratch, label);
  const bool version = label.find("major_version") != std::string::npos ||
                       label.find("unknown_required_flag") != std::string::npos;
  EXPECT(s == (version ? DECAL_ERROR_UNSUPPORTED_VERSION : DECAL_ERROR_FORMAT), "%s: %s",
         label.c_str(), decal_status_name(s));
}

// Every prefix, every byte flipped: all refused. From a path every 37th.
void check_mutations(const fs::path& path, const Bytes& bytes, const fs::path& scratch) {
  const std::string name = path.filename().string();
  for (size_t n = 0; n < bytes.size(); ++n) {
    const Bytes prefix(bytes.begin(), bytes.begin() + std::ptrdiff_t(n));
    expect_refused(prefix, n % 37 == 0, scratch, name + " cut to " + std::to_string(n));
  }
  size_t opened = 0, agreed = 0;
  for (size_t at = 0; at < bytes.size(); ++at) {
    Bytes flipped = bytes;
    flipped[at] ^= std::byte(1u << (at % 8));
    const std::string label =
        name + " bit " + std::to_string(at % 8) + " of byte " + std::to_string(at) + " flipped";
    expect_refused(flipped, at % 37 == 0, scratch, label);
    // Resealed: whatever the reader decides, the C API decides too.
    decal_test::reseal(flipped);
    decal::Package ref;
    const bool accepted = cpp_accepts(flipped, ref);
    decal_package* p = nullptr;
    decal_error e{};
    const decal_status s = open_memory(flipped, &p, &e);
    EXPECT((s == DECAL_OK) == accepted, "%s, resealed: C API %s (%s), C++ reader %s", label.c_str(),
           decal_status_name(s), e.message, accepted ? "accepts" : "refuses");
    if (s == DECAL_OK) {
      ++opened;
      if (accepted) expect_forwarded(p, ref, label + ", resealed");
    }
    agreed += (s == DECAL_OK) == accepted;
    decal_close(p);
  }
  std::printf("%s: %zu prefixes and %zu flips refused; resealed flips: %zu open, %zu agree\n",
              name.c_str(), bytes.size(), bytes.size(), opened, agreed);
}

void check_arguments(const fs::path& valid, const fs::path& scratch) {
  auto* p = reinterpret_cast<decal_package*>(1);
  decal_error e{};
  EXPECT(decal_open_file(nullptr, nullptr, &p, &e) == DECAL_ERROR_INVALID_ARGUMENT && !p,
         "NULL path");
  EXPECT(decal_open_file(valid.c_str(), nullptr, nullptr, &e) == DECAL_ERROR_INVALID_ARGUMENT,
         "NULL out");
  EXPECT(decal_open_memory(nullptr, 5, nullptr, &p, &e) == DECAL_ERROR_INVALID_ARGUMENT,
         "NULL data");
  decal_open_options o{};
  o.flags = 0x80u;
  EXPECT(decal_open_file(valid.c_str(), &o, &p, &e) == DECAL_ERROR_INVALID_ARGUMENT && !p,
         "unknown flag");
  o = decal_open_options{};
  o.reserved = 1;
  EXPECT(decal_open_file(valid.c_str(), &o, &p, &e) == DECAL_ERROR_INVALID_ARGUMENT, "reserved");
  EXPECT(decal_open_file((scratch / "missing.decals").c_str(), nullptr, &p, &e) == DECAL_ERROR_IO &&
             std::strstr(e.message, "missing.decals"),
         "missing file: %s", e.message);
  EXPECT(decal_open_file(scratch.c_str(), nullptr, &p, &e) == DECAL_ERROR_IO, "directory: %s",
         e.message);
  const fs::path fifo = scratch / "fifo.decals";
  fs::remove(fifo);
  if (::mkfifo(fifo.c_str(), 0600) == 0)
    EXPECT(decal_open_file(fifo.c_str(), nullptr, &p, &e) == DECAL_ERROR_IO, "FIFO: %s", e.message);
  // A 1-byte inflation limit refuses any package with a nonempty blob.
  o = decal_open_options{};
  o.max_raw_size = 1;
  EXPECT(decal_open_file(valid.c_str(), &o, &p, &e) == DECAL_ERROR_FORMAT, "inflation limit");
  EXPECT(decal_open_file(valid.c_str(), nullptr, &p, nullptr) == DECAL_OK && p, "valid");
  uint32_t index = 7;
  EXPECT(decal_find_blob(p, "no_such_blob", &index, &e) == DECAL_ERROR_NOT_FOUND && index == 7,
         "find missing");
  EXPECT(decal_find_blob_id(p, 9999, &index, &e) == DECAL_ERROR_NOT_FOUND && index == 7,
         "find missing id");
  decal_blob_info info{};
  const uint32_t n = decal_blob_count(p);
  EXPECT(decal_blob_info_at(p, n, &info, &e) == DECAL_ERROR_INVALID_ARGUMENT, "index %u", n);
  EXPECT(decal_blob_info_at(nullptr, 0, &info, &e) == DECAL_ERROR_INVALID_ARGUMENT, "NULL package");
  // A buffer one byte short: nothing written, the needed size returned.
  uint32_t big = 0;
  for (uint32_t i = 0; i < n; ++i) {
    decal_blob_info_at(p, i, &info, nullptr);
    if (info.raw_size > 1) big = i;
  }
  decal_blob_info_at(p, big, &info, nullptr);
  std::vector<unsigned char> canary(info.raw_size, 0xA5);
  size_t needed = 0;
  EXPECT(decal_blob_read(p, big, canary.data(), canary.size() - 1, &needed, &e) ==
                 DECAL_ERROR_BUFFER_TOO_SMALL &&
             needed == info.raw_size && e.code == DECAL_ERROR_BUFFER_TOO_SMALL,
         "short buffer");
  EXPECT(std::all_of(canary.begin(), canary.end(), [](unsigned char c) { return c == 0xA5; }),
         "a short buffer was written");
  EXPECT(decal_blob_read(p, big, nullptr, 4, &needed, &e) == DECAL_ERROR_INVALID_ARGUMENT,
         "NULL buffer");
  decal_close(p);
  decal_close(nullptr);
  EXPECT(std::strcmp(decal_status_name(DECAL_ERROR_FORMAT), "DECAL_ERROR_FORMAT") == 0 &&
             std::strcmp(decal_status_name(-1), "unknown") == 0,
         "status names");
  char version[32];
  std::snprintf(version, sizeof version, "%d.%d.%d", DECAL_C_API_VERSION_MAJOR,
                DECAL_C_API_VERSION_MINOR, DECAL_C_API_VERSION_PATCH);
  EXPECT(std::strcmp(decal_version_string(), version) == 0, "version string '%s', header %s",
         decal_version_string(), version);
  uint32_t major = 0, minor = 0;
  decal_format_version(&major, &minor);
  EXPECT(decal_version() == DECAL_C_API_VERSION && major == DECAL_FORMAT_VERSION_MAJOR &&
             minor == DECAL_FORMAT_VERSION_MINOR,
         "versions");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s <fuzz/corpus/read> <scratch directory>\n", argv[0]);
    return 2;
  }
  const fs::path corpus = argv[1], scratch = argv[2];
  fs::create_directories(scratch);
  std::vector<fs::path> valid, broken;
  for (const auto& entry : fs::directory_iterator(corpus)) {
    const std::string name = entry.path().filename().string();
    if (name.starts_with("valid_")) valid.push_back(entry.path());
    if (name.starts_with("broken_")) broken.push_back(entry.path());
  }
  std::sort(valid.begin(), valid.end());
  std::sort(broken.begin(), broken.end());
  EXPECT(valid.size() >= 2 && broken.size() >= 10, "seed corpus in %s: %zu valid, %zu broken",
         corpus.c_str(), valid.size(), broken.size());
  for (const fs::path& p : broken) check_broken_seed(p, scratch);
  std::printf("%zu broken seeds tried\n", broken.size());
  for (const fs::path& p : valid) {
    const Bytes bytes = read_file(p);
    check_valid_seed(p, bytes);
    check_mutations(p, bytes, scratch);
  }
  // The last in name order (valid_small_zstd): it has blobs of several bytes.
  if (!valid.empty()) check_arguments(valid.back(), scratch);
  std::printf("%s: %d failures\n", g_failures ? "FAILED" : "passed", g_failures);
  return g_failures ? 1 : 0;
}
