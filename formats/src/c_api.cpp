// c_api.cpp — the C API (decal/decal.h) over the C++ reader
// (decal/reader.hpp, decal/inspect.hpp). Each entry point checks its
// arguments, forwards, and turns the reader's Status into a decal_status
// and a message. No exception leaves this file: every entry point that
// calls into C++ that may allocate catches everything (std::bad_alloc as
// DECAL_ERROR_OUT_OF_MEMORY, anything else as DECAL_ERROR_INTERNAL).
#include <fcntl.h>
#include <unistd.h>
#include <xxhash.h>

#include <cstdarg>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <new>
#include <span>
#include <string>

#include "decal/decal.h"
#include "decal/format.hpp"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"

// The header's numbers are the format's (decal/format.hpp).
static_assert(DECAL_FORMAT_VERSION_MAJOR == decal::kVersionMajor);
static_assert(DECAL_FORMAT_VERSION_MINOR == decal::kVersionMinor);
static_assert(DECAL_ELEMENT_U8 == uint32_t(decal::ElementType::u8));
static_assert(DECAL_ELEMENT_RECORD == uint32_t(decal::ElementType::record));
static_assert(DECAL_CODEC_NONE == uint32_t(decal::CodecId::none));
static_assert(DECAL_CODEC_ZSTD == uint32_t(decal::CodecId::zstd));

// The ABI of the structs (decal.h "Versioning"), pinned for 64-bit hosts:
// a change here is a new major version.
static_assert(sizeof(void*) != 8 || sizeof(decal_blob_info) == 72);
static_assert(sizeof(void*) != 8 || offsetof(decal_blob_info, name) == 48);
static_assert(offsetof(decal_blob_info, index) == 24);
static_assert(sizeof(decal_open_options) == 16 && offsetof(decal_open_options, max_raw_size) == 8);
static_assert(sizeof(decal_error) == 4 + DECAL_ERROR_MESSAGE_SIZE);

struct decal_package {
  decal::Package package;
};

namespace {

constexpr uint32_t kKnownOpenFlags = DECAL_OPEN_NO_MMAP | DECAL_OPEN_SKIP_INDEX_CHECK;

// Copies `message` into error->message, cut at a UTF-8 character boundary
// so that the text stays valid UTF-8 (C# and other callers decode it).
void set_message(decal_error* error, const char* message) {
  size_t n = std::strlen(message);
  if (n >= DECAL_ERROR_MESSAGE_SIZE) {
    n = DECAL_ERROR_MESSAGE_SIZE - 1;
    // Back off over continuation bytes (10xxxxxx) to the lead byte, and
    // drop that too: the cut character is incomplete.
    while (n > 0 && (static_cast<unsigned char>(message[n]) & 0xC0) == 0x80) --n;
  }
  std::memcpy(error->message, message, n);
  error->message[n] = '\0';
}

decal_status fail(decal_error* error, decal_status code, const char* message) {
  if (error) {
    error->code = code;
    set_message(error, message);
  }
  return code;
}

// fail() with a printf-style message.
[[gnu::format(printf, 3, 4)]] decal_status failf(decal_error* error, decal_status code,
                                                 const char* f, ...) {
  char buf[DECAL_ERROR_MESSAGE_SIZE];
  va_list args;
  va_start(args, f);
  std::vsnprintf(buf, sizeof buf, f, args);
  va_end(args);
  return fail(error, code, buf);
}

decal_status succeed(decal_error* error) {
  if (error) {
    error->code = DECAL_OK;
    error->message[0] = '\0';
  }
  return DECAL_OK;
}

// Runs `body` (which returns a decal_status) and turns an escaping
// exception into a status: nothing may unwind into C.
template <class Body>
decal_status guarded(decal_error* error, Body&& body) noexcept {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    return fail(error, DECAL_ERROR_OUT_OF_MEMORY, "out of memory");
  } catch (const std::exception& e) {
    return failf(error, DECAL_ERROR_INTERNAL, "internal error: %s", e.what());
  } catch (...) {
    return fail(error, DECAL_ERROR_INTERNAL, "internal error: unknown exception");
  }
}

// The options of decal_open_*, checked; DECAL_OK or INVALID_ARGUMENT.
decal_status read_options(const decal_open_options* in, decal::OpenOptions& out, bool& index_check,
                          decal_error* error) {
  index_check = true;
  if (!in) return DECAL_OK;
  if (in->flags & ~kKnownOpenFlags)
    return failf(error, DECAL_ERROR_INVALID_ARGUMENT, "unknown decal_open_options.flags bits 0x%x",
                 in->flags & ~kKnownOpenFlags);
  if (in->reserved != 0)
    return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "decal_open_options.reserved must be 0");
  out.allow_mmap = (in->flags & DECAL_OPEN_NO_MMAP) == 0;
  if (in->max_raw_size != 0) out.max_raw_bytes = in->max_raw_size;
  index_check = (in->flags & DECAL_OPEN_SKIP_INDEX_CHECK) == 0;
  return DECAL_OK;
}

template <class T>
T load_le(const unsigned char* p) {
  T v = 0;
  for (size_t i = 0; i < sizeof(T); ++i) v = T(v | T(T(p[i]) << (8 * i)));
  return v;
}

// Which status a refused package gets, from its first bytes `head` (at
// most sizeof(FileHeader)): UNSUPPORTED_VERSION for a package of another
// major version (checked before anything else, formats/SPEC.md
// "Validation" step 2) or, with an intact header, a required flag this
// library does not know (step 5); FORMAT otherwise.
decal_status refusal_code(std::span<const unsigned char> head) {
  using H = decal::FileHeader;
  if (head.size() < offsetof(H, flags) + sizeof(uint32_t) ||
      std::memcmp(head.data(), decal::kMagic, sizeof decal::kMagic) != 0)
    return DECAL_ERROR_FORMAT;
  if (load_le<uint16_t>(head.data() + offsetof(H, version_major)) != decal::kVersionMajor)
    return DECAL_ERROR_UNSUPPORTED_VERSION;
  if (head.size() < sizeof(H)) return DECAL_ERROR_FORMAT;
  const auto flags = load_le<uint32_t>(head.data() + offsetof(H, flags));
  if ((flags & decal::kRequiredFlagsMask & ~decal::kKnownRequiredFlags) == 0)
    return DECAL_ERROR_FORMAT;
  // Only a header whose checksum holds says what it requires (v1 headers
  // are sizeof(H) bytes; a longer one cannot be checked from `head`).
  if (load_le<uint32_t>(head.data() + offsetof(H, header_size)) != sizeof(H))
    return DECAL_ERROR_FORMAT;
  const auto stored = load_le<uint64_t>(head.data() + offsetof(H, header_checksum));
  return XXH64(head.data(), offsetof(H, header_checksum), 0) == stored
             ? DECAL_ERROR_UNSUPPORTED_VERSION
             : DECAL_ERROR_FORMAT;
}

// The first bytes of the file at `path`, for refusal_code; empty when it
// cannot be read.
size_t read_head(const char* path, unsigned char (&head)[sizeof(decal::FileHeader)]) {
  int fd = -1;
  uint64_t size = 0;
  if (!decal::open_regular_file(path, fd, size)) return 0;
  size_t done = 0;
  while (done < sizeof head) {
    const ssize_t n = ::read(fd, head + done, sizeof head - done);
    if (n <= 0) break;
    done += static_cast<size_t>(n);
  }
  ::close(fd);
  return done;
}

// After a successful open: the index check (unless skipped), then hands
// the package to the caller.
decal_status finish_open(std::unique_ptr<decal_package> opened, bool index_check,
                         decal_package** out, decal_error* error) {
  if (index_check) {
    if (const decal::Status s = decal::validate_indices(opened->package); !s)
      return fail(error, DECAL_ERROR_FORMAT, s.message.c_str());
  }
  *out = opened.release();
  return succeed(error);
}

// Blob `index` of `package`, or nullptr after setting INVALID_ARGUMENT.
const decal::BlobView* blob_at(const decal_package* package, uint32_t index, decal_error* error) {
  if (!package) {
    fail(error, DECAL_ERROR_INVALID_ARGUMENT, "package is NULL");
    return nullptr;
  }
  const auto blobs = package->package.blobs();
  if (index >= blobs.size()) {
    failf(error, DECAL_ERROR_INVALID_ARGUMENT, "blob index %u out of range (the package has %zu)",
          index, blobs.size());
    return nullptr;
  }
  return &blobs[index];
}

}  // namespace

extern "C" {

DECAL_API uint32_t decal_version(void) {
  return DECAL_C_API_VERSION;
}

DECAL_API const char* decal_version_string(void) {
#define DECAL_STRINGIFY_(x) #x
#define DECAL_STRINGIFY(x) DECAL_STRINGIFY_(x)
  return DECAL_STRINGIFY(DECAL_C_API_VERSION_MAJOR) "." DECAL_STRINGIFY(
      DECAL_C_API_VERSION_MINOR) "." DECAL_STRINGIFY(DECAL_C_API_VERSION_PATCH);
#undef DECAL_STRINGIFY
#undef DECAL_STRINGIFY_
}

DECAL_API void decal_format_version(uint32_t* major, uint32_t* minor) {
  if (major) *major = decal::kVersionMajor;
  if (minor) *minor = decal::kVersionMinor;
}

DECAL_API const char* decal_status_name(int32_t status) {
  switch (status) {
    case DECAL_OK: return "DECAL_OK";
    case DECAL_ERROR_INVALID_ARGUMENT: return "DECAL_ERROR_INVALID_ARGUMENT";
    case DECAL_ERROR_IO: return "DECAL_ERROR_IO";
    case DECAL_ERROR_FORMAT: return "DECAL_ERROR_FORMAT";
    case DECAL_ERROR_UNSUPPORTED_VERSION: return "DECAL_ERROR_UNSUPPORTED_VERSION";
    case DECAL_ERROR_NOT_FOUND: return "DECAL_ERROR_NOT_FOUND";
    case DECAL_ERROR_BUFFER_TOO_SMALL: return "DECAL_ERROR_BUFFER_TOO_SMALL";
    case DECAL_ERROR_OUT_OF_MEMORY: return "DECAL_ERROR_OUT_OF_MEMORY";
    case DECAL_ERROR_INTERNAL: return "DECAL_ERROR_INTERNAL";
    default: return "unknown";
  }
}

DECAL_API decal_status decal_open_file(const char* path, const decal_open_options* options,
                                       decal_package** out, decal_error* error) {
  if (out) *out = nullptr;
  if (!path || !out) return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "path or out is NULL");
  return guarded(error, [&]() -> decal_status {
    decal::OpenOptions opt;
    bool index_check = true;
    if (const decal_status s = read_options(options, opt, index_check, error); s != DECAL_OK)
      return s;
    // Whether the file can be opened at all decides IO against FORMAT; the
    // reader opens it again (the same checks, formats/SPEC.md "Validation").
    {
      int fd = -1;
      uint64_t size = 0;
      if (const decal::Status s = decal::open_regular_file(path, fd, size); !s)
        return fail(error, DECAL_ERROR_IO, s.message.c_str());
      ::close(fd);
    }
    auto opened = std::make_unique<decal_package>();
    if (const decal::Status s = decal::Package::open(path, opened->package, opt); !s) {
      unsigned char head[sizeof(decal::FileHeader)];
      const size_t n = read_head(path, head);
      return fail(error, refusal_code({head, n}), s.message.c_str());
    }
    return finish_open(std::move(opened), index_check, out, error);
  });
}

DECAL_API decal_status decal_open_memory(const void* data, size_t size,
                                         const decal_open_options* options, decal_package** out,
                                         decal_error* error) {
  if (out) *out = nullptr;
  if (!out) return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "out is NULL");
  if (!data && size != 0)
    return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "data is NULL with a nonzero size");
  return guarded(error, [&]() -> decal_status {
    decal::OpenOptions opt;
    bool index_check = true;
    if (const decal_status s = read_options(options, opt, index_check, error); s != DECAL_OK)
      return s;
    const std::span<const std::byte> bytes(static_cast<const std::byte*>(data), size);
    auto opened = std::make_unique<decal_package>();
    if (const decal::Status s = decal::Package::from_memory(bytes, opened->package, opt); !s) {
      const size_t head = size < sizeof(decal::FileHeader) ? size : sizeof(decal::FileHeader);
      return fail(error, refusal_code({static_cast<const unsigned char*>(data), head}),
                  s.message.c_str());
    }
    return finish_open(std::move(opened), index_check, out, error);
  });
}

DECAL_API void decal_close(decal_package* package) {
  delete package;  // ~Package is noexcept (munmap and frees)
}

DECAL_API decal_status decal_package_version(const decal_package* package, uint32_t* major,
                                             uint32_t* minor, decal_error* error) {
  if (!package) return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "package is NULL");
  if (major) *major = package->package.major();
  if (minor) *minor = package->package.minor();
  return succeed(error);
}

DECAL_API uint32_t decal_package_flags(const decal_package* package) {
  return package ? package->package.flags() : 0;
}

DECAL_API decal_status decal_metadata(const decal_package* package, const char** text, size_t* size,
                                      decal_error* error) {
  if (!package || !text)
    return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "package or text is NULL");
  // The view is of a std::string the package owns, so a NUL follows it.
  const std::string_view json = package->package.metadata_json();
  *text = json.data();
  if (size) *size = json.size();
  return succeed(error);
}

DECAL_API uint32_t decal_blob_count(const decal_package* package) {
  // open() refused tables of more than UINT32_MAX entries (blob_count is a
  // uint32 field), so the count fits.
  return package ? static_cast<uint32_t>(package->package.blobs().size()) : 0;
}

DECAL_API decal_status decal_blob_info_at(const decal_package* package, uint32_t index,
                                          decal_blob_info* info, decal_error* error) {
  if (!info) return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "info is NULL");
  const decal::BlobView* b = blob_at(package, index, error);
  if (!b) return DECAL_ERROR_INVALID_ARGUMENT;
  decal_blob_info r{};
  r.index = index;
  r.id = b->id;
  r.name = b->name.c_str();
  r.element_type = static_cast<uint32_t>(b->type);
  // Both names are views of string literals, so NUL-terminated and static.
  r.element_type_name = decal::element_type_name(b->type).data();
  r.stride = b->stride;
  r.codec = static_cast<uint32_t>(b->codec);
  r.codec_name = decal::codec_name(static_cast<uint32_t>(b->codec)).data();
  r.known = b->known() ? 1 : 0;
  r.count = b->count;
  r.raw_size = b->bytes.size();
  r.stored_size = b->stored_bytes;
  *info = r;
  return succeed(error);
}

DECAL_API decal_status decal_find_blob(const decal_package* package, const char* name,
                                       uint32_t* index, decal_error* error) {
  if (!package || !name || !index)
    return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "package, name or index is NULL");
  const auto blobs = package->package.blobs();
  for (size_t i = 0; i < blobs.size(); ++i) {
    if (std::strcmp(blobs[i].name.c_str(), name) == 0) {
      *index = static_cast<uint32_t>(i);
      return succeed(error);
    }
  }
  // Names are at most 31 bytes (formats/SPEC.md "Blob table"); print a
  // bounded part of the caller's string.
  return failf(error, DECAL_ERROR_NOT_FOUND, "no blob named '%.64s'", name);
}

DECAL_API decal_status decal_find_blob_id(const decal_package* package, uint32_t id,
                                          uint32_t* index, decal_error* error) {
  if (!package || !index)
    return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "package or index is NULL");
  const auto blobs = package->package.blobs();
  for (size_t i = 0; i < blobs.size(); ++i) {
    if (blobs[i].id == id) {
      *index = static_cast<uint32_t>(i);
      return succeed(error);
    }
  }
  return failf(error, DECAL_ERROR_NOT_FOUND, "no blob with id %u", id);
}

DECAL_API decal_status decal_blob_read(const decal_package* package, uint32_t index, void* buffer,
                                       size_t capacity, size_t* needed, decal_error* error) {
  const decal::BlobView* b = blob_at(package, index, error);
  if (!b) return DECAL_ERROR_INVALID_ARGUMENT;
  const std::span<const std::byte> bytes = b->bytes;
  if (needed) *needed = bytes.size();
  if (!buffer && capacity != 0)
    return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "buffer is NULL with a nonzero capacity");
  if (capacity < bytes.size())
    return failf(error, DECAL_ERROR_BUFFER_TOO_SMALL,
                 "blob #%u '%s' needs %zu bytes; the buffer holds %zu", index, b->name.c_str(),
                 bytes.size(), capacity);
  // buffer is not NULL here unless capacity, and so the blob, is empty.
  if (buffer && !bytes.empty()) std::memcpy(buffer, bytes.data(), bytes.size());
  return succeed(error);
}

DECAL_API decal_status decal_blob_data(const decal_package* package, uint32_t index,
                                       const void** data, size_t* size, decal_error* error) {
  if (!data || !size) return fail(error, DECAL_ERROR_INVALID_ARGUMENT, "data or size is NULL");
  const decal::BlobView* b = blob_at(package, index, error);
  if (!b) return DECAL_ERROR_INVALID_ARGUMENT;
  *data = b->bytes.empty() ? nullptr : b->bytes.data();
  *size = b->bytes.size();
  return succeed(error);
}

}  // extern "C"
