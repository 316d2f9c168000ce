// reader.cpp — Package::open / from_memory: validation and decoding of a
// .decals package (formats/SPEC.md). Every file is hostile: each size,
// offset, count and checksum is checked, overflow-safe, before it is used,
// and nothing throws across the API (std::bad_alloc aside).
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>
#include <string>

#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "message.hpp"

static_assert(std::endian::native == std::endian::little,
              "the package format is little-endian and read by memcpy");

namespace decal {
namespace {

using detail::fmt;

using ull = unsigned long long;

// Memory aligned to kBlobAlignment; holds decoded blobs or a file copy.
struct AlignedBuffer {
  std::byte* data = nullptr;
  size_t size = 0;
  AlignedBuffer() = default;
  explicit AlignedBuffer(size_t n) : size(n) {
    if (n) data = static_cast<std::byte*>(::operator new (n, std::align_val_t{kBlobAlignment}));
  }
  AlignedBuffer(AlignedBuffer&& o) noexcept : data(o.data), size(o.size) {
    o.data = nullptr;
    o.size = 0;
  }
  AlignedBuffer& operator=(AlignedBuffer&& o) noexcept {
    std::swap(data, o.data);
    std::swap(size, o.size);
    return *this;
  }
  ~AlignedBuffer() {
    if (data) ::operator delete (data, std::align_val_t{kBlobAlignment});
  }
};

uint64_t align_up(uint64_t v) {
  return (v + kBlobAlignment - 1) / kBlobAlignment * kBlobAlignment;
}

uint64_t xxh64(const std::byte* p, size_t n) {
  return XXH64(p, n, 0);
}

bool all_zero(const std::byte* p, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (p[i] != std::byte{0}) return false;
  return true;
}

// Offset of the first nonzero byte in [p, p+n), or n.
size_t first_nonzero(const std::byte* p, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (p[i] != std::byte{0}) return i;
  return n;
}

std::string entry_label(size_t index, const BlobTableEntry& e) {
  // The name may be garbage before it is validated; print only safe chars.
  std::string name;
  for (char c : e.name) {
    if (c == 0) break;
    name += (c >= 0x20 && c < 0x7f) ? c : '?';
  }
  return fmt("blob #%zu '%s' (id %u)", index, name.c_str(), e.id);
}

// A validated table entry's description (check_layout has run on it).
BlobEntry blob_entry(const BlobTableEntry& e) {
  BlobEntry b;
  b.id = e.id;
  b.name = std::string(e.name, strnlen(e.name, kBlobNameSize));
  b.type = static_cast<ElementType>(e.element_type);
  b.stride = e.stride;
  b.count = e.count;
  return b;
}

bool valid_element_type(uint32_t t) {
  return t >= 1 && t <= 11;
}

// Checks the name field: [a-z0-9_]+, NUL-terminated within the field, zero
// after the terminator.
bool valid_name(const BlobTableEntry& e, std::string_view& name) {
  size_t n = 0;
  while (n < kBlobNameSize && e.name[n] != 0) ++n;
  if (n == 0 || n == kBlobNameSize) return false;
  for (size_t i = 0; i < n; ++i) {
    char c = e.name[i];
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
  }
  for (size_t i = n; i < kBlobNameSize; ++i)
    if (e.name[i] != 0) return false;
  name = std::string_view(e.name, n);
  return true;
}

// Zstd cannot expand more than 128 KiB (one block) per 4 stored bytes (a
// 3-byte block header plus one RLE byte), so a claimed raw size beyond this
// is a lie; refusing it bounds the allocation by the file size.
bool plausible_zstd_raw_size(uint64_t stored, uint64_t raw) {
  if (stored > (uint64_t(1) << 40)) return true;  // no overflow concern below
  return raw <= stored * 32768 + 131072;
}

}  // namespace

namespace {

// The header or the table past the bytes read (a guard: read_package_sizes
// reads as far as the header places the table's end).
Status beyond(uint64_t avail, uint64_t end, const char* what) {
  return Status::failure(fmt("%s ends at byte %llu, past the %llu bytes read of the file", what,
                             ull(end), ull(avail)));
}

// Reserved fields and optional flags may gain a meaning in a later minor
// version; only a file of our minor or older must have them zero.
bool is_newer_minor(const FileHeader& h) {
  return h.version_minor > kVersionMinor;
}

// check_layout's header checks, in order: size, magic, version, header size
// and checksum, file size, flags, reserved fields. Sets `h` from the file.
Status check_header(const std::byte* base, uint64_t avail, uint64_t size, FileHeader& h) {
  if (size == 0) return Status::failure("empty file (0 bytes): not a .decals package");
  if (avail < std::min<uint64_t>(size, sizeof(FileHeader)))
    return beyond(avail, sizeof(FileHeader), "the header");
  const size_t magic_n = std::min<size_t>(size, sizeof kMagic);
  if (std::memcmp(base, kMagic, magic_n) != 0)
    return Status::failure("not a .decals package: magic bytes do not match at byte 0");
  if (size < sizeof(FileHeader))
    return Status::failure(fmt("truncated package: %llu bytes, the header alone needs %zu",
                               ull(size), sizeof(FileHeader)));
  std::memcpy(&h, base, sizeof h);

  // The version comes first: a newer major may lay out everything else
  // differently, so its checksums mean nothing to us.
  if (h.version_major != kVersionMajor)
    return Status::failure(
        fmt("unsupported package major version %u (minor %u); this reader "
            "reads major version %u",
            h.version_major, h.version_minor, kVersionMajor));
  if (h.header_size < sizeof(FileHeader) || h.header_size % 8 != 0 || h.header_size > size)
    return Status::failure(
        fmt("header_size %u at byte 16 is invalid (must be >= %zu, a multiple "
            "of 8 and within the %llu-byte file)",
            h.header_size, sizeof(FileHeader), ull(size)));
  if (h.header_size > avail) return beyond(avail, h.header_size, "the header");
  uint64_t stored_header_sum;
  std::memcpy(&stored_header_sum, base + h.header_size - 8, 8);
  const uint64_t header_sum = xxh64(base, h.header_size - 8);
  if (header_sum != stored_header_sum)
    return Status::failure(
        fmt("header checksum mismatch at byte %u: stored %016llx, computed "
            "%016llx",
            h.header_size - 8, ull(stored_header_sum), ull(header_sum)));
  if (h.file_size != size)
    return Status::failure(fmt("file size mismatch: header says %llu bytes, file has %llu%s",
                               ull(h.file_size), ull(size),
                               size < h.file_size ? " (truncated)" : " (trailing bytes)"));
  const uint32_t unknown_required = h.flags & kRequiredFlagsMask & ~kKnownRequiredFlags;
  if (unknown_required)
    return Status::failure(fmt("unsupported required flag bits 0x%08x in flags 0x%08x at byte 12",
                               unknown_required, h.flags));
  if (!is_newer_minor(h)) {
    if (h.flags & ~kRequiredFlagsMask & ~kKnownOptionalFlags)
      return Status::failure(
          fmt("undefined optional flag bits set in flags 0x%08x at byte 12 "
              "(version %u.%u)",
              h.flags, h.version_major, h.version_minor));
    if (h.reserved0 != 0 || h.reserved1 != 0)
      return Status::failure("reserved header field at byte 28 or 80 is not zero");
    // A longer header (from a later minor) has its extra fields between the
    // v1 fields and its checksum, which always sits in its last 8 bytes.
    const size_t v1_end = offsetof(FileHeader, header_checksum);
    const size_t extra_n = h.header_size - 8 - v1_end;
    const size_t extra = first_nonzero(base + v1_end, extra_n);
    if (extra != extra_n)
      return Status::failure(fmt("header byte %zu (past the v%u.%u fields) is not zero",
                                 v1_end + extra, h.version_major, h.version_minor));
  }
  return Status::success();
}

// check_layout's checks of the blob table's placement and checksum and of
// the metadata (its bytes only when `whole`), after check_header.
Status check_table_and_metadata(const std::byte* base, uint64_t avail, uint64_t size, bool whole,
                                const FileHeader& h) {
  if (h.blob_entry_size < sizeof(BlobTableEntry) || h.blob_entry_size % 8 != 0)
    return Status::failure(
        fmt("blob_entry_size %u at byte 20 is invalid (must be >= %zu and a "
            "multiple of 8)",
            h.blob_entry_size, sizeof(BlobTableEntry)));
  if (h.table_offset != h.header_size)
    return Status::failure(fmt("table_offset %llu at byte 40 must equal header_size %u",
                               ull(h.table_offset), h.header_size));
  // blob_count < 2^32 and blob_entry_size < 2^32: the product fits in 64 bits.
  const uint64_t table_bytes = uint64_t(h.blob_count) * h.blob_entry_size;
  if (table_bytes > size - h.table_offset)
    return Status::failure(
        fmt("blob table (%u entries x %u bytes at byte %llu) runs past the end "
            "of the %llu-byte file",
            h.blob_count, h.blob_entry_size, ull(h.table_offset), ull(size)));
  if (table_bytes > avail - h.table_offset)
    return beyond(avail, h.table_offset + table_bytes, "the blob table");
  const uint64_t table_sum = xxh64(base + h.table_offset, table_bytes);
  if (table_sum != h.table_checksum)
    return Status::failure(fmt("blob table checksum mismatch: stored %016llx, computed %016llx",
                               ull(h.table_checksum), ull(table_sum)));
  const uint64_t table_end = h.table_offset + table_bytes;
  if (h.metadata_offset != table_end)
    return Status::failure(
        fmt("metadata_offset %llu at byte 56 must equal the end of the blob "
            "table, %llu",
            ull(h.metadata_offset), ull(table_end)));
  if (h.metadata_size > size - h.metadata_offset)
    return Status::failure(
        fmt("metadata (%llu bytes at byte %llu) runs past the end of the "
            "%llu-byte file",
            ull(h.metadata_size), ull(h.metadata_offset), ull(size)));
  // Refused before anything parses it (formats/SPEC.md "Metadata"); also in
  // a sizes-only read, which must reject whatever a full read rejects on the
  // bytes it reads.
  if (h.metadata_size > kMaxMetadataBytes)
    return Status::failure(
        fmt("metadata_size %llu at byte 64 is above the reader's limit of "
            "%llu bytes (formats/SPEC.md \"Metadata\")",
            ull(h.metadata_size), ull(kMaxMetadataBytes)));
  const char* m = whole ? reinterpret_cast<const char*>(base + h.metadata_offset) : nullptr;
  if (whole) {
    const uint64_t meta_sum = xxh64(base + h.metadata_offset, h.metadata_size);
    if (meta_sum != h.metadata_checksum)
      return Status::failure(fmt("metadata checksum mismatch: stored %016llx, computed %016llx",
                                 ull(h.metadata_checksum), ull(meta_sum)));
  }
  if (h.metadata_size < 2 || (m && (m[0] != '{' || m[h.metadata_size - 1] != '}')))
    return Status::failure(
        fmt("metadata at byte %llu is not a JSON object (must start with '{' "
            "and end with '}')",
            ull(h.metadata_offset)));
  if (m && std::memchr(m, 0, h.metadata_size) != nullptr)
    return Status::failure("metadata contains a NUL byte");
  return Status::success();
}

// check_layout's checks of table entry `i` (read into entries[i]): name,
// reserved fields, element type and stride against the catalogue, duplicate
// ids, sizes, codec, then its placement after `prev_end` (what ends there is
// `prev_label`), which it advances past the blob.
Status check_entry(const std::byte* base, uint64_t size, bool whole, const FileHeader& h,
                   std::vector<BlobTableEntry>& entries, size_t i, uint64_t& prev_end,
                   std::string& prev_label) {
  BlobTableEntry& e = entries[i];
  const uint64_t at = h.table_offset + i * uint64_t(h.blob_entry_size);
  std::memcpy(&e, base + at, sizeof e);
  const std::string label = entry_label(i, e);
  std::string_view name;
  if (!valid_name(e, name))
    return Status::failure(
        fmt("%s, table entry at byte %llu: name must be 1-31 characters "
            "[a-z0-9_], NUL-padded",
            label.c_str(), ull(at)));
  if (!is_newer_minor(h)) {
    if (e.reserved[0] != 0 || e.reserved[1] != 0)
      return Status::failure(fmt("%s: reserved entry field is not zero", label.c_str()));
    if (!all_zero(base + at + sizeof e, h.blob_entry_size - sizeof e))
      return Status::failure(fmt("%s: entry bytes past the v1 fields are not zero", label.c_str()));
  }
  if (!valid_element_type(e.element_type))
    return Status::failure(fmt("%s: unknown element type %u", label.c_str(), e.element_type));
  const auto type = static_cast<ElementType>(e.element_type);
  if (type == ElementType::record) {
    if (e.stride == 0 || e.stride % 4 != 0)
      return Status::failure(
          fmt("%s: record stride %u is not a positive multiple of 4", label.c_str(), e.stride));
  } else if (e.stride != std430_stride(type)) {
    return Status::failure(fmt("%s: stride %u does not match element type %s (std430 stride %u)",
                               label.c_str(), e.stride, element_type_name(type).data(),
                               std430_stride(type)));
  }
  if (const BlobInfo* info = find_blob_info(static_cast<BlobId>(e.id))) {
    if (name != info->name)
      return Status::failure(
          fmt("%s: id %u is '%s' in the catalogue", label.c_str(), e.id, info->name.data()));
    if (type != info->type || e.stride != info->stride)
      return Status::failure(fmt("%s: element type %s stride %u, catalogue says %s stride %u",
                                 label.c_str(), element_type_name(type).data(), e.stride,
                                 element_type_name(info->type).data(), info->stride));
  }
  for (size_t j = 0; j < i; ++j)
    if (entries[j].id == e.id)
      return Status::failure(fmt("%s: duplicate blob id (also entry #%zu)", label.c_str(), j));
  uint64_t raw = 0;
  if (__builtin_mul_overflow(e.count, uint64_t(e.stride), &raw))
    return Status::failure(
        fmt("%s: count %llu x stride %u overflows uint64", label.c_str(), ull(e.count), e.stride));
  if (raw != e.raw_size)
    return Status::failure(fmt("%s: raw_size %llu != count %llu x stride %u", label.c_str(),
                               ull(e.raw_size), ull(e.count), e.stride));
  if (e.codec == uint32_t(CodecId::none)) {
    if (e.stored_size != e.raw_size)
      return Status::failure(fmt("%s: uncompressed but stored_size %llu != raw_size %llu",
                                 label.c_str(), ull(e.stored_size), ull(e.raw_size)));
  } else if (e.codec == uint32_t(CodecId::zstd)) {
    if (h.flags & kFlagAllUncompressed)
      return Status::failure(
          fmt("%s: zstd codec in a package flagged all-uncompressed", label.c_str()));
    if (!plausible_zstd_raw_size(e.stored_size, e.raw_size))
      return Status::failure(fmt("%s: raw_size %llu cannot come from %llu zstd bytes",
                                 label.c_str(), ull(e.raw_size), ull(e.stored_size)));
  } else {
    return Status::failure(fmt("%s: unknown codec %u", label.c_str(), e.codec));
  }
  if (e.offset % kBlobAlignment != 0)
    return Status::failure(fmt("%s: offset %llu is not a multiple of %llu", label.c_str(),
                               ull(e.offset), ull(kBlobAlignment)));
  if (e.offset > size || e.stored_size > size - e.offset)
    return Status::failure(
        fmt("%s: %llu bytes at offset %llu run past the end of the "
            "%llu-byte file",
            label.c_str(), ull(e.stored_size), ull(e.offset), ull(size)));
  if (e.offset < prev_end)
    return Status::failure(fmt("%s: offset %llu overlaps %s, which ends at byte %llu",
                               label.c_str(), ull(e.offset), prev_label.c_str(), ull(prev_end)));
  if (e.offset != align_up(prev_end))
    return Status::failure(
        fmt("%s: offset %llu leaves a gap; the next aligned offset after "
            "byte %llu is %llu",
            label.c_str(), ull(e.offset), ull(prev_end), ull(align_up(prev_end))));
  // The padding lies past the table: checked when the file is at hand.
  if (whole) {
    const size_t pad = first_nonzero(base + prev_end, e.offset - prev_end);
    if (pad != e.offset - prev_end)
      return Status::failure(
          fmt("padding byte %llu before %s is not zero", ull(prev_end + pad), label.c_str()));
  }
  prev_end = e.offset + e.stored_size;
  prev_label = label;
  return Status::success();
}

// The checks of read_layout. With `whole`, `base` holds the whole file
// (avail == size) and everything is checked. Without, it holds the first
// `avail` bytes of a file of `size` bytes (read_package_sizes): the header
// and the blob table are read and checked as with `whole`, the metadata
// and the blobs are placed by their offsets and sizes only (their bytes,
// the metadata's checksum and the padding between them are not read), and
// it fails, never reading past `avail`, when the header and the table do
// not lie within the first `avail` bytes.
Status check_layout(const std::byte* base, uint64_t avail, uint64_t size, bool whole,
                    PackageLayout& out) {
  out = {};
  if (whole && avail != size) return Status::failure("check_layout: not the whole file");
  FileHeader h{};
  if (Status s = check_header(base, avail, size, h); !s) return s;
  if (Status s = check_table_and_metadata(base, avail, size, whole, h); !s) return s;
  std::vector<BlobTableEntry> entries(h.blob_count);
  uint64_t prev_end = h.metadata_offset + h.metadata_size;
  std::string prev_label = "the metadata";
  for (size_t i = 0; i < entries.size(); ++i)
    if (Status s = check_entry(base, size, whole, h, entries, i, prev_end, prev_label); !s)
      return s;
  if (prev_end != size)
    return Status::failure(fmt("%llu unexplained bytes after %s (byte %llu to %llu)",
                               ull(size - prev_end), prev_label.c_str(), ull(prev_end), ull(size)));
  out.header = h;
  out.entries = std::move(entries);
  return Status::success();
}

}  // namespace

Status read_layout(std::span<const std::byte> file, PackageLayout& out) {
  return check_layout(file.data(), file.size(), file.size(), true, out);
}

struct Package::Impl {
  FileHeader header{};
  std::string metadata;
  std::vector<BlobView> blobs;
  AlignedBuffer file_copy;  // the whole file, when read or copied
  AlignedBuffer decoded;    // decoded blobs, when any was compressed
  void* map = nullptr;
  size_t map_size = 0;
  bool mapped = false;  // blob views point into `map`

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    if (map) ::munmap(map, map_size);
  }
  void unmap() {
    if (map) ::munmap(map, map_size);
    map = nullptr;
    map_size = 0;
  }
};

namespace {

// Validates `file` and fills `impl`. When every blob is uncompressed the
// views point into `file` (which the caller keeps alive in `impl`);
// otherwise every blob is decoded into impl.decoded.
// (A template so that it may take the private Package::Impl.)
template <class PackageImpl>
Status load(std::span<const std::byte> file, const OpenOptions& opt, PackageImpl& impl,
            bool& views_into_file) {
  PackageLayout layout;
  if (Status s = read_layout(file, layout); !s) return s;
  const std::byte* base = file.data();
  bool any_compressed = false;
  uint64_t decoded_total = 0;
  for (size_t i = 0; i < layout.entries.size(); ++i) {
    const BlobTableEntry& e = layout.entries[i];
    if (opt.verify_checksums) {
      const uint64_t sum = xxh64(base + e.offset, e.stored_size);
      if (sum != e.checksum)
        return Status::failure(fmt("%s: checksum mismatch: stored %016llx, computed %016llx",
                                   entry_label(i, e).c_str(), ull(e.checksum), ull(sum)));
    }
    if (e.codec != uint32_t(CodecId::none)) any_compressed = true;
  }
  for (const BlobTableEntry& e : layout.entries) {
    // Each decoded blob starts on an aligned boundary of the arena.
    if (e.raw_size > opt.max_raw_bytes || decoded_total > opt.max_raw_bytes - e.raw_size)
      return Status::failure(fmt("package inflates beyond the %llu-byte limit (max_raw_bytes)",
                                 ull(opt.max_raw_bytes)));
    decoded_total = align_up(decoded_total + e.raw_size);
  }
  views_into_file = !any_compressed;
  impl.header = layout.header;
  impl.metadata.assign(reinterpret_cast<const char*>(base + layout.header.metadata_offset),
                       layout.header.metadata_size);
  impl.blobs.clear();
  impl.blobs.reserve(layout.entries.size());
  if (any_compressed) impl.decoded = AlignedBuffer(decoded_total);
  ZSTD_DCtx* dctx = nullptr;
  uint64_t cursor = 0;
  Status status;
  for (size_t i = 0; i < layout.entries.size() && status; ++i) {
    const BlobTableEntry& e = layout.entries[i];
    BlobView v;
    static_cast<BlobEntry&>(v) = blob_entry(e);
    v.codec = static_cast<CodecId>(e.codec);
    v.stored_bytes = e.stored_size;
    if (!any_compressed) {
      if (e.raw_size) v.bytes = {base + e.offset, static_cast<size_t>(e.raw_size)};
    } else {
      // No pointer arithmetic on the null arena of an all-empty package.
      std::byte* dst = impl.decoded.data ? impl.decoded.data + cursor : nullptr;
      const std::byte* src = base + e.offset;
      if (e.codec == uint32_t(CodecId::none)) {
        if (e.raw_size) std::memcpy(dst, src, e.raw_size);
      } else {
        const unsigned long long content = ZSTD_getFrameContentSize(src, e.stored_size);
        const size_t frame = ZSTD_findFrameCompressedSize(src, e.stored_size);
        if (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN ||
            content != e.raw_size) {
          status = Status::failure(fmt("%s: zstd frame content size does not match raw_size %llu",
                                       entry_label(i, e).c_str(), ull(e.raw_size)));
          break;
        }
        if (ZSTD_isError(frame) || frame != e.stored_size) {
          status = Status::failure(
              fmt("%s: stored bytes are not exactly one zstd frame", entry_label(i, e).c_str()));
          break;
        }
        if (!dctx) dctx = ZSTD_createDCtx();
        if (!dctx) {
          status = Status::failure("cannot create a zstd decompression context");
          break;
        }
        const size_t got = ZSTD_decompressDCtx(dctx, dst, e.raw_size, src, e.stored_size);
        if (ZSTD_isError(got) || got != e.raw_size) {
          status =
              Status::failure(fmt("%s: zstd decoding failed: %s", entry_label(i, e).c_str(),
                                  ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short output"));
          break;
        }
      }
      if (e.raw_size) v.bytes = {dst, static_cast<size_t>(e.raw_size)};
      cursor = align_up(cursor + e.raw_size);
    }
    impl.blobs.push_back(std::move(v));
  }
  ZSTD_freeDCtx(dctx);
  return status;
}

}  // namespace

Package::Package() = default;
Package::~Package() = default;
Package::Package(Package&&) noexcept = default;
Package& Package::operator=(Package&&) noexcept = default;

Status Package::from_memory(std::span<const std::byte> bytes, Package& out,
                            const OpenOptions& opt) {
  out = Package();
  // The caller's span has no lifetime we could rely on, and may be
  // misaligned: always work on an aligned copy.
  auto impl = std::make_unique<Impl>();
  impl->file_copy = AlignedBuffer(bytes.size());
  if (!bytes.empty()) std::memcpy(impl->file_copy.data, bytes.data(), bytes.size());
  bool into_file = false;
  Status s = load({impl->file_copy.data, impl->file_copy.size}, opt, *impl, into_file);
  if (!s) return s;
  if (!into_file) impl->file_copy = AlignedBuffer();
  out.impl_ = std::move(impl);
  return s;
}

namespace {

// What a file of mode `mode` is, for a refusal: "a FIFO (named pipe)".
const char* file_kind(mode_t mode) {
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISDIR(mode)) return "a directory";
  return "not a regular file";
}

}  // namespace

Status open_regular_file(const std::string& path, int& fd, uint64_t& size) {
  fd = -1;
  size = 0;
  // O_NONBLOCK: open() of a FIFO without a writer (or of some devices)
  // would block before fstat() could refuse it. A FIFO, a device, a socket
  // or a directory is refused before a byte is read; a regular file then
  // reads as usual (O_NONBLOCK has no effect on it, but is cleared anyway).
  const int got = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (got < 0)
    return Status::failure(fmt("cannot open '%s': %s", path.c_str(), std::strerror(errno)));
  struct stat st;
  if (::fstat(got, &st) != 0) {
    const int err = errno;
    ::close(got);
    return Status::failure(fmt("cannot stat '%s': %s", path.c_str(), std::strerror(err)));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(got);
    return Status::failure(fmt("'%s' is %s, not a regular file: refused before reading",
                               path.c_str(), file_kind(st.st_mode)));
  }
  const int flags = ::fcntl(got, F_GETFL);
  if (flags < 0 || ::fcntl(got, F_SETFL, flags & ~O_NONBLOCK) != 0) {
    const int err = errno;
    ::close(got);
    return Status::failure(fmt("cannot read '%s': %s", path.c_str(), std::strerror(err)));
  }
  fd = got;
  size = static_cast<uint64_t>(st.st_size);
  return Status::success();
}

Status Package::open(const std::string& path, Package& out, const OpenOptions& opt) {
  out = Package();
  int fd = -1;
  uint64_t size = 0;
  if (Status s = open_regular_file(path, fd, size); !s) return s;
  auto impl = std::make_unique<Impl>();
  std::span<const std::byte> file;
  if (opt.allow_mmap && size > 0) {
    void* m = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
    if (m != MAP_FAILED) {
      impl->map = m;
      impl->map_size = size;
      file = {static_cast<const std::byte*>(m), static_cast<size_t>(size)};
    }
  }
  if (!impl->map) {
    impl->file_copy = AlignedBuffer(size);
    uint64_t done = 0;
    while (done < size) {
      // done < size, and size came from a non-negative off_t (st_size), so
      // the offset fits off_t.
      const ssize_t n =
          ::pread(fd, impl->file_copy.data + done, size - done, static_cast<off_t>(done));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        const int err = errno;
        ::close(fd);
        return Status::failure(fmt("cannot read '%s' at byte %llu: %s", path.c_str(), ull(done),
                                   n == 0 ? "unexpected end of file" : std::strerror(err)));
      }
      done += static_cast<uint64_t>(n);
    }
    file = {impl->file_copy.data, impl->file_copy.size};
  }
  ::close(fd);
  bool into_file = false;
  Status s = load(file, opt, *impl, into_file);
  if (!s) return Status::failure(path + ": " + s.message);
  if (!into_file) {
    impl->unmap();
    impl->file_copy = AlignedBuffer();
  } else {
    impl->mapped = impl->map != nullptr;
  }
  out.impl_ = std::move(impl);
  return s;
}

uint16_t Package::major() const {
  return impl_ ? impl_->header.version_major : 0;
}
uint16_t Package::minor() const {
  return impl_ ? impl_->header.version_minor : 0;
}
uint32_t Package::flags() const {
  return impl_ ? impl_->header.flags : 0;
}
std::string_view Package::metadata_json() const {
  return impl_ ? std::string_view(impl_->metadata) : std::string_view();
}
std::span<const BlobView> Package::blobs() const {
  return impl_ ? std::span<const BlobView>(impl_->blobs) : std::span<const BlobView>();
}
bool Package::memory_mapped() const {
  return impl_ && impl_->mapped;
}

const BlobView* Package::find(BlobId id) const {
  if (!impl_) return nullptr;
  for (const BlobView& b : impl_->blobs)
    if (b.id == static_cast<uint32_t>(id)) return &b;
  return nullptr;
}

namespace {

// The bytes at the start of a file of `size` bytes that hold its header and
// blob table where the header `head` (the file's first `head_n` bytes)
// places them; at most `size`. check_layout then checks that placement:
// read_package_sizes reads no more than this.
uint64_t directory_bytes(const std::byte* head, uint64_t head_n, uint64_t size) {
  if (head_n < sizeof(FileHeader)) return std::min(head_n, size);
  FileHeader h;
  std::memcpy(&h, head, sizeof h);
  uint64_t need = std::max<uint64_t>(h.header_size, sizeof(FileHeader));
  auto reach = [&](uint64_t offset, uint64_t n) {
    uint64_t end = 0;
    if (__builtin_add_overflow(offset, n, &end)) end = UINT64_MAX;
    need = std::max(need, end);
  };
  reach(h.table_offset, uint64_t(h.blob_count) * h.blob_entry_size);
  return std::min(need, size);
}

// PackageSizes from the first `avail` bytes of a file of `size` bytes.
Status sizes_of(const std::byte* base, uint64_t avail, uint64_t size, PackageSizes& out) {
  out = {};
  PackageLayout layout;
  if (Status s = check_layout(base, avail, size, false, layout); !s) return s;
  PackageSizes r;
  r.major = layout.header.version_major;
  r.minor = layout.header.version_minor;
  r.flags = layout.header.flags;
  r.file_bytes = size;
  r.blobs.reserve(layout.entries.size());
  for (size_t i = 0; i < layout.entries.size(); ++i) {
    const BlobTableEntry& e = layout.entries[i];
    BlobSize b;
    static_cast<BlobEntry&>(b) = blob_entry(e);
    b.raw_bytes = e.raw_size;
    b.stored_bytes = e.stored_size;
    if (__builtin_add_overflow(r.raw_bytes, e.raw_size, &r.raw_bytes))
      return Status::failure(fmt("%s: the decoded sizes of the blobs add up past 2^64 bytes",
                                 entry_label(i, e).c_str()));
    r.blobs.push_back(std::move(b));
  }
  out = std::move(r);
  return Status::success();
}

}  // namespace

Status package_sizes_from_memory(std::span<const std::byte> bytes, PackageSizes& out) {
  return sizes_of(bytes.data(), directory_bytes(bytes.data(), bytes.size(), bytes.size()),
                  bytes.size(), out);
}

Status read_package_sizes(const std::string& path, PackageSizes& out) {
  out = {};
  int fd = -1;
  uint64_t size = 0;
  if (Status s = open_regular_file(path, fd, size); !s) return s;
  std::vector<std::byte> buf;
  // Reads the file's first n bytes into buf (n <= size: it fits off_t).
  auto read_to = [&](uint64_t n) -> Status {
    uint64_t done = buf.size();
    buf.resize(static_cast<size_t>(n));
    while (done < n) {
      const ssize_t got = ::pread(fd, buf.data() + done, n - done, static_cast<off_t>(done));
      if (got < 0 && errno == EINTR) continue;
      if (got <= 0)
        return Status::failure(fmt("cannot read '%s' at byte %llu: %s", path.c_str(), ull(done),
                                   got == 0 ? "unexpected end of file" : std::strerror(errno)));
      done += static_cast<uint64_t>(got);
    }
    return Status::success();
  };
  // The header first, then as far as it says the blob table reaches; the
  // checks see those bytes only, as package_sizes_from_memory's do.
  Status s = read_to(std::min<uint64_t>(size, 4096));
  uint64_t need = 0;
  if (s) {
    need = directory_bytes(buf.data(), buf.size(), size);
    if (need > buf.size()) s = read_to(need);
  }
  ::close(fd);
  if (!s) return s;
  s = sizes_of(buf.data(), need, size, out);
  if (!s) return Status::failure(path + ": " + s.message);
  return s;
}

}  // namespace decal
