// decal/reader.hpp — reading a .decals package. Treats every file as hostile.
//
// Contract: no function here throws (std::bad_alloc aside, which callers may
// treat as fatal); every failure is a Status with a one-line message that
// names what was wrong and where (byte offset, blob name, value). Every size,
// offset, count, stride and checksum is validated before use. Depends only
// on the standard library, zstd and xxHash. Thread-safety: a Package is
// immutable after open() and may be read from several threads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "decal/format.hpp"

namespace decal {

struct Status {
  bool ok = true;
  std::string message;  // empty when ok
  explicit operator bool() const { return ok; }
  static Status success() { return {}; }
  static Status failure(std::string m) { return {false, std::move(m)}; }
};

// One blob as its blob-table entry names it.
struct BlobEntry {
  uint32_t id = 0;  // BlobId value (may be unknown to this build)
  std::string name;
  ElementType type{};
  uint32_t stride = 0;
  uint64_t count = 0;
  bool known() const { return find_blob_info(static_cast<BlobId>(id)) != nullptr; }
};

// One blob, decoded (decompressed) and checksum-verified.
struct BlobView : BlobEntry {
  std::span<const std::byte> bytes;  // count * stride bytes, 4-byte aligned
  CodecId codec = CodecId::none;     // how the file stores it
  uint64_t stored_bytes = 0;         // its size in the file (= bytes.size() for codec none)
};

struct OpenOptions {
  bool allow_mmap = true;  // map uncompressed packages instead of copying
  bool verify_checksums = true;
  uint64_t max_raw_bytes = uint64_t(64) << 30;  // refuse to inflate beyond this
};

class Package {
 public:
  Package();
  ~Package();
  Package(Package&&) noexcept;
  Package& operator=(Package&&) noexcept;

  // Opens and fully validates `path`. On failure `out` is left empty.
  static Status open(const std::string& path, Package& out, const OpenOptions& = {});
  // Same, over bytes in memory (copied when needed).
  static Status from_memory(std::span<const std::byte> bytes, Package& out,
                            const OpenOptions& = {});

  uint16_t major() const;
  uint16_t minor() const;
  uint32_t flags() const;
  std::string_view metadata_json() const;
  std::span<const BlobView> blobs() const;  // in file order, unknown ids included
  bool memory_mapped() const;

  // The blob with this id, or nullptr when absent.
  const BlobView* find(BlobId id) const;

  // Typed view of blob `id`, elements of its catalogue type
  // (BlobTraits<id>::type, decal/format.hpp); empty span when absent. open()
  // checked the stride against the catalogue, so it is sizeof that type.
  template <BlobId id>
  std::span<const typename BlobTraits<id>::type> array() const {
    using T = typename BlobTraits<id>::type;
    const BlobView* b = find(id);
    if (!b || b->stride != sizeof(T)) return {};
    return {reinterpret_cast<const T*>(b->bytes.data()), static_cast<size_t>(b->count)};
  }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Opens `path` read-only for the reader's use: it must be a regular file
// (symlinks followed). A FIFO, a device, a socket or a directory is refused
// without blocking and before a byte is read (the open does not wait for a
// FIFO's writer; formats/SPEC.md "Validation"). On success `fd` is open,
// blocking, close-on-exec (the caller closes it) and `size` is the file's
// size; on failure `fd` is -1 and the message names the path and what it is.
Status open_regular_file(const std::string& path, int& fd, uint64_t& size);

// One blob as the package's blob table describes it.
struct BlobSize : BlobEntry {
  uint64_t raw_bytes = 0;     // count * stride: its size decoded
  uint64_t stored_bytes = 0;  // its size in the file
};

// What a package holds decoded, from its header and blob table alone.
struct PackageSizes {
  uint16_t major = 0, minor = 0;
  uint32_t flags = 0;
  uint64_t file_bytes = 0;
  std::vector<BlobSize> blobs;  // in file order, unknown ids included
  uint64_t raw_bytes = 0;       // the sum of the blobs' raw_bytes: what open() decodes
};

// Reads the header and the blob table of the package at `path` (its first
// header_size + blob_count x blob_entry_size bytes: 2784 for the 28 blobs
// decalprep writes) and neither the metadata nor any blob. What it reads is
// checked as Package::open checks it (formats/SPEC.md "Blob sizes without
// decoding"): magic, version, flags, reserved fields, the header and table
// checksums, every entry's name, type, stride, codec and count x stride
// (overflow-safe) = raw_size, and the placement of the metadata and of
// every blob within the file's size. So a package open() accepts is
// accepted here with the same ids, counts, strides and decoded sizes; one
// accepted here may still fail open() on bytes not read (the metadata's
// checksum and content, the blobs' checksums and zstd frames, the padding).
// On failure `out` is left empty and the message names the path. Never
// throws (std::bad_alloc aside).
Status read_package_sizes(const std::string& path, PackageSizes& out);
// The same over a whole file in memory: the same checks on the same bytes.
Status package_sizes_from_memory(std::span<const std::byte> bytes, PackageSizes& out);

}  // namespace decal
