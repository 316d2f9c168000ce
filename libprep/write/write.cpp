// write.cpp — write_package: lays out, compresses and checksums the blobs
// of a .decals package (formats/SPEC.md) and writes the file atomically.
//
// Atomicity: the bytes go to an unnamed O_TMPFILE in the target directory
// (a killed writer leaves nothing behind), are fsync'ed, linked under a
// temporary name and renamed over the target; then the directory is
// fsync'ed. Where O_TMPFILE is unsupported a named temporary file is used,
// removed on any failure and, as far as a signal handler can, on SIGINT and
// SIGTERM.
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <numeric>
#include <string>
#include <type_traits>
#include <vector>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "prep/error.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"
#include "prep/write.hpp"
#include "write_internal.hpp"

static_assert(std::endian::native == std::endian::little,
              "the package format is little-endian and written by memcpy");

namespace prep {
namespace {

uint64_t align_up(uint64_t v) {
  return (v + decal::kBlobAlignment - 1) / decal::kBlobAlignment * decal::kBlobAlignment;
}

[[noreturn]] void fail_io(const std::string& path, const std::string& what, int err = 0) {
  std::string m = path + ": " + what;
  if (err) m += std::string(": ") + std::strerror(err);
  fail<output_error>(kWriteStage, m);
}

// ------------------------------------------------ temp-file signal cleanup --
// Named temporary files currently being written, so that SIGINT/SIGTERM can
// remove them. The handler only reads `state` and `path` and calls unlink(),
// which is async-signal-safe.
struct TempSlot {
  std::atomic<int> state{0};  // 0 free, 1 claimed (path being filled), 2 live
  char path[PATH_MAX] = {};
};
TempSlot g_slots[16];
std::mutex g_signal_mutex;
int g_active_writes = 0;
struct sigaction g_old_int, g_old_term;
bool g_hooked_int = false, g_hooked_term = false;

extern "C" void remove_temps_and_reraise(int sig) {
  for (TempSlot& s : g_slots)
    if (s.state.load() == 2) ::unlink(s.path);
  ::sigaction(sig, sig == SIGINT ? &g_old_int : &g_old_term, nullptr);
  ::raise(sig);
}

// Installs the handler while at least one write is active; a signal the
// process ignores stays ignored (and then the temp file must stay too).
class SignalGuard {
 public:
  SignalGuard() {
    std::lock_guard lock(g_signal_mutex);
    if (g_active_writes++ > 0) return;
    struct sigaction sa {};
    sa.sa_handler = remove_temps_and_reraise;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;
    g_hooked_int = hook(SIGINT, sa, g_old_int);
    g_hooked_term = hook(SIGTERM, sa, g_old_term);
  }
  ~SignalGuard() {
    std::lock_guard lock(g_signal_mutex);
    if (--g_active_writes > 0) return;
    if (g_hooked_int) ::sigaction(SIGINT, &g_old_int, nullptr);
    if (g_hooked_term) ::sigaction(SIGTERM, &g_old_term, nullptr);
    g_hooked_int = g_hooked_term = false;
  }
  SignalGuard(const SignalGuard&) = delete;
  SignalGuard& operator=(const SignalGuard&) = delete;

  // Registers `path` for removal on a signal; returns the slot or nullptr
  // when all are taken (then only the normal failure path cleans up).
  static TempSlot* track(const std::string& path) {
    if (path.size() >= PATH_MAX) return nullptr;
    for (TempSlot& s : g_slots) {
      int expected = 0;
      // Claim the slot, fill the path, then publish it to the handler.
      if (s.state.compare_exchange_strong(expected, 1)) {
        std::memcpy(s.path, path.c_str(), path.size() + 1);
        s.state.store(2);
        return &s;
      }
    }
    return nullptr;
  }
  static void untrack(TempSlot* s) {
    if (s) s->state.store(0);
  }

 private:
  static bool hook(int sig, const struct sigaction& sa, struct sigaction& old) {
    if (::sigaction(sig, nullptr, &old) != 0) return false;
    if (old.sa_handler == SIG_IGN && !(old.sa_flags & SA_SIGINFO)) return false;
    return ::sigaction(sig, &sa, nullptr) == 0;
  }
};

// -------------------------------------------------------- the atomic file --
class AtomicFile {
 public:
  explicit AtomicFile(const std::string& path) : path_(path) {
    if (path.empty() || path.back() == '/') fail_io(path, "not a file path");
    const size_t slash = path.rfind('/');
    dir_ = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
    base_ = slash == std::string::npos ? path : path.substr(slash + 1);
    if (base_ == "." || base_ == "..") fail_io(path, "not a file path");
    dirfd_ = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dirfd_ < 0) fail_io(path, "cannot open directory '" + dir_ + "'", errno);
    static std::atomic<unsigned> counter{0};
    tmp_name_ = "." + base_ + ".tmp-" + std::to_string(::getpid()) + "-" +
                std::to_string(counter.fetch_add(1));
    fd_ = ::openat(dirfd_, ".", O_TMPFILE | O_WRONLY | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      // No O_TMPFILE on this file system: fall back to a named temp file.
      slot_ = SignalGuard::track(dir_ + "/" + tmp_name_);
      fd_ = ::openat(dirfd_, tmp_name_.c_str(), O_CREAT | O_EXCL | O_WRONLY | O_CLOEXEC, 0644);
      if (fd_ < 0) {
        const int err = errno;
        cleanup();
        fail_io(path, "cannot create a temporary file in '" + dir_ + "'", err);
      }
      named_ = true;
    }
  }
  ~AtomicFile() { cleanup(); }
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void write(const void* data, size_t n) {
    const char* p = static_cast<const char*>(data);
    while (n > 0) {
      const ssize_t w = ::write(fd_, p, n);
      if (w < 0 && errno == EINTR) continue;
      if (w < 0) fail_io(path_, "write failed", errno);
      p += w;
      n -= static_cast<size_t>(w);
    }
  }
  // Starts the write-back of bytes already written (Linux
  // sync_file_range, asynchronous), so that commit()'s fsync finds less to
  // do. Advisory: an error here is left to fsync to report.
  void start_writeback(uint64_t offset, uint64_t n) {
    (void)::sync_file_range(fd_, static_cast<off_t>(offset), static_cast<off_t>(n),
                            SYNC_FILE_RANGE_WRITE);
  }
  // Writes at `offset` without moving the file position.
  void pwrite(const void* data, size_t n, uint64_t offset) {
    const char* p = static_cast<const char*>(data);
    while (n > 0) {
      const ssize_t w = ::pwrite(fd_, p, n, static_cast<off_t>(offset));
      if (w < 0 && errno == EINTR) continue;
      if (w < 0) fail_io(path_, "write failed", errno);
      p += w;
      n -= static_cast<size_t>(w);
      offset += static_cast<uint64_t>(w);
    }
  }
  void zeros(size_t n) {
    static const std::array<char, 4096> kZero{};
    while (n > 0) {
      const size_t k = std::min(n, kZero.size());
      write(kZero.data(), k);
      n -= k;
    }
  }

  // fsync, give the file its temporary name (if it has none), rename it
  // over the target and fsync the directory.
  void commit() {
    if (::fsync(fd_) != 0) fail_io(path_, "fsync failed", errno);
    if (!named_) {
      slot_ = SignalGuard::track(dir_ + "/" + tmp_name_);
      const std::string proc = "/proc/self/fd/" + std::to_string(fd_);
      if (::linkat(AT_FDCWD, proc.c_str(), dirfd_, tmp_name_.c_str(), AT_SYMLINK_FOLLOW) != 0 &&
          ::linkat(fd_, "", dirfd_, tmp_name_.c_str(), AT_EMPTY_PATH) != 0)
        fail_io(path_, "cannot link the temporary file into '" + dir_ + "'", errno);
      named_ = true;
    }
    if (::close(fd_) != 0) {
      fd_ = -1;
      fail_io(path_, "close failed", errno);
    }
    fd_ = -1;
    if (::renameat(dirfd_, tmp_name_.c_str(), dirfd_, base_.c_str()) != 0)
      fail_io(path_, "cannot rename the temporary file over the target", errno);
    named_ = false;  // the name now belongs to the target
    SignalGuard::untrack(slot_);
    slot_ = nullptr;
    if (::fsync(dirfd_) != 0) fail_io(path_, "fsync of directory '" + dir_ + "' failed", errno);
  }

 private:
  void cleanup() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    if (named_) ::unlinkat(dirfd_, tmp_name_.c_str(), 0);
    named_ = false;
    SignalGuard::untrack(slot_);
    slot_ = nullptr;
    if (dirfd_ >= 0) ::close(dirfd_);
    dirfd_ = -1;
  }

  SignalGuard signals_;
  std::string path_, dir_, base_, tmp_name_;
  int dirfd_ = -1;
  int fd_ = -1;
  bool named_ = false;  // tmp_name_ exists in the directory
  TempSlot* slot_ = nullptr;
};

// A compressed blob's zstd frame: allocated at ZSTD_compressBound (pages
// never written are never resident), then shrunk to the frame's size.
struct FreeBytes {
  void operator()(std::byte* p) const noexcept { std::free(p); }
};
using Frame = std::unique_ptr<std::byte, FreeBytes>;

struct EncodedBlob {
  decal::BlobTableEntry entry{};
  Frame compressed;                   // null when stored as is
  std::span<const std::byte> stored;  // the bytes to write
};

void check_blob(const std::string& path, const BlobInput& b, std::span<const BlobInput> all,
                size_t index) {
  const auto id = static_cast<uint32_t>(b.id);
  const std::string label = "blob id " + std::to_string(id);
  const auto t = static_cast<uint32_t>(b.type);
  if (t < 1 || t > 11) fail_io(path, label + ": unknown element type " + std::to_string(t));
  if (b.type == decal::ElementType::record ? (b.stride == 0 || b.stride % 4 != 0)
                                           : b.stride != decal::std430_stride(b.type))
    fail_io(path, label + ": stride " + std::to_string(b.stride) + " does not fit element type " +
                      std::string(decal::element_type_name(b.type)));
  if (const decal::BlobInfo* info = decal::find_blob_info(b.id))
    if (info->type != b.type || info->stride != b.stride)
      fail_io(path, label + " (" + std::string(info->name) +
                        "): type/stride differ from the "
                        "catalogue");
  uint64_t raw = 0;
  if (__builtin_mul_overflow(b.count, uint64_t(b.stride), &raw) || raw != b.bytes.size())
    fail_io(path, label + ": " + std::to_string(b.bytes.size()) + " bytes given for " +
                      std::to_string(b.count) + " elements of " + std::to_string(b.stride));
  for (size_t j = 0; j < index; ++j)
    if (all[j].id == b.id) fail_io(path, label + ": given twice");
}

}  // namespace

namespace {

void check_metadata(const std::string& path, const std::string& metadata_json) {
  if (metadata_json.size() < 2 || metadata_json.front() != '{' || metadata_json.back() != '}' ||
      metadata_json.find('\0') != std::string::npos)
    fail_io(path, "metadata must be a JSON object text ('{' ... '}', no NUL bytes)");
  if (metadata_json.size() > decal::kMaxMetadataBytes)
    fail_io(path, "metadata of " + std::to_string(metadata_json.size()) + " bytes is above the " +
                      std::to_string(decal::kMaxMetadataBytes) +
                      "-byte limit readers hold it to (formats/SPEC.md \"Metadata\"); not written");
}

// The codec options and the blob count a package can hold.
void check_write_options(const std::string& path, const WriteOptions& options, size_t blobs) {
  if (options.codec == Codec::zstd &&
      (options.zstd_level < ZSTD_minCLevel() || options.zstd_level > ZSTD_maxCLevel()))
    fail_io(path, "zstd level " + std::to_string(options.zstd_level) + " is outside [" +
                      std::to_string(ZSTD_minCLevel()) + ", " + std::to_string(ZSTD_maxCLevel()) +
                      "]");
  if (blobs > UINT32_MAX) fail_io(path, "too many blobs");
}

// The table entry of blob `i` of `blobs` (checked: check_blob) but for its
// place in the file, stored size and checksum; `name` receives its name
// (the catalogue's, else blob_<id>).
void describe_blob(const std::string& path, std::span<const BlobInput> blobs, size_t i,
                   const WriteOptions& options, decal::BlobTableEntry& e, std::string& name) {
  const BlobInput& b = blobs[i];
  check_blob(path, b, blobs, i);
  e.id = static_cast<uint32_t>(b.id);
  e.element_type = static_cast<uint32_t>(b.type);
  e.stride = b.stride;
  e.count = b.count;
  e.raw_size = b.bytes.size();
  const decal::BlobInfo* info = decal::find_blob_info(b.id);
  name = info ? std::string(info->name) : "blob_" + std::to_string(e.id);
  std::memcpy(e.name, name.data(), name.size());
  // Empty blobs are stored as no bytes at all, whatever the codec.
  const bool zstd = options.codec == Codec::zstd && !b.bytes.empty();
  e.codec = static_cast<uint32_t>(zstd ? decal::CodecId::zstd : decal::CodecId::none);
}

// The header of a package of `blob_count` blobs: its layout (the blob
// table after the header, the metadata after the table); the sizes,
// flags and checksums known only at the end are left zero.
decal::FileHeader package_header(uint32_t blob_count) {
  decal::FileHeader h{};
  std::memcpy(h.magic, decal::kMagic, sizeof h.magic);
  h.version_major = decal::kVersionMajor;
  h.version_minor = decal::kVersionMinor;
  h.header_size = sizeof(decal::FileHeader);
  h.blob_entry_size = sizeof(decal::BlobTableEntry);
  h.blob_count = blob_count;
  h.table_offset = h.header_size;
  h.metadata_offset = h.table_offset + uint64_t(h.blob_count) * h.blob_entry_size;
  return h;
}

// The package written front to back as the blobs are compressed: first
// zeros where the header and the blob table go (their offsets, stored
// sizes and checksums are known only at the end, and then written over
// the zeros), the metadata once source.complete() has made it, then each
// blob as soon as it and every blob before it in table order are done. A
// compressed frame is freed once written, and a blob's own bytes (`owner`)
// once compressed or written, so the writer holds the frames of the blobs
// done out of order, not the whole package; and it starts the write-back
// of each blob, so that the final fsync has little left to do. The fields
// under `mutex` are shared by the compressing threads.
struct PackageStream {
  const std::string& path;
  const WriteOptions& options;
  std::vector<BlobInput>& blobs;
  std::vector<EncodedBlob>& enc;
  const std::vector<std::string>& names;
  decal::FileHeader& h;
  AtomicFile& out;
  ProgressStage& stage;
  uint64_t end = 0;           // file position
  std::string metadata_json;  // from source.complete()

  std::mutex mutex;
  std::vector<char> ready = std::vector<char>(blobs.size(), 0);
  bool metadata_ready = false, metadata_written = false;
  size_t next_to_write = 0;
  bool writing = false;

  // With the lock held by `lock`: writes the metadata and every done blob
  // from `next_to_write` on, unless another thread is writing (the writer
  // re-checks under the lock after each write, so a blob marked done
  // meanwhile is not left behind).
  void write_ready(std::unique_lock<std::mutex>& lock) {
    if (writing) return;
    writing = true;
    for (;;) {
      if (!metadata_written) {
        if (!metadata_ready) break;
        lock.unlock();
        out.zeros(h.metadata_offset);
        out.write(metadata_json.data(), metadata_json.size());
        end = h.metadata_offset + metadata_json.size();
        lock.lock();
        metadata_written = true;
        continue;
      }
      if (next_to_write == blobs.size() || !ready[next_to_write]) break;
      const size_t j = next_to_write;
      lock.unlock();
      EncodedBlob& b = enc[j];
      b.entry.offset = align_up(end);
      out.zeros(b.entry.offset - end);
      out.write(b.stored.data(), b.stored.size());
      out.start_writeback(b.entry.offset, b.stored.size());
      end = b.entry.offset + b.stored.size();
      b.compressed.reset();
      b.stored = {};
      blobs[j].owner.reset();
      lock.lock();
      ++next_to_write;
    }
    writing = false;
  }

  // source.complete(): the metadata, checked, into the header; then written
  // with whatever is ready.
  void complete(PackageSource& source) {
    std::string json = source.complete ? source.complete() : std::string();
    check_metadata(path, json);
    std::unique_lock lock(mutex);
    metadata_json = std::move(json);
    h.metadata_size = metadata_json.size();
    h.metadata_checksum = XXH64(metadata_json.data(), metadata_json.size(), 0);
    metadata_ready = true;
    write_ready(lock);
  }

  // Blob `i` compressed (one single-threaded zstd frame, in `cctx`, made on
  // first use) or stored as is, checksummed, marked done and written with
  // whatever is ready.
  void encode(size_t i, ZSTD_CCtx*& cctx) {
    BlobInput& b = blobs[i];
    decal::BlobTableEntry& e = enc[i].entry;
    if (e.codec == static_cast<uint32_t>(decal::CodecId::zstd)) {
      if (!cctx) {
        cctx = ZSTD_createCCtx();
        if (!cctx) fail_io(path, "cannot create a zstd context");
      }
      ZSTD_CCtx_reset(cctx, ZSTD_reset_session_and_parameters);
      ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, options.zstd_level);
      // The frame's own checksum guards the decoded bytes end to end.
      ZSTD_CCtx_setParameter(cctx, ZSTD_c_checksumFlag, 1);
      ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 1);
      const size_t bound = ZSTD_compressBound(b.bytes.size());
      Frame frame(static_cast<std::byte*>(std::malloc(bound)));
      if (!frame) fail_io(path, "out of memory compressing '" + names[i] + "'");
      const size_t n = ZSTD_compress2(cctx, frame.get(), bound, b.bytes.data(), b.bytes.size());
      if (ZSTD_isError(n))
        fail_io(path, "zstd compression of '" + names[i] + "' failed: " + ZSTD_getErrorName(n));
      // Shrinking keeps the address (glibc: in place, or mremap for large
      // blocks), so no copy is made.
      if (auto* shrunk = static_cast<std::byte*>(std::realloc(frame.get(), std::max<size_t>(n, 1))))
        (void)frame.release(), frame.reset(shrunk);
      enc[i].compressed = std::move(frame);
      enc[i].stored = {enc[i].compressed.get(), n};
      b.owner.reset();
    } else {
      enc[i].stored = b.bytes;
    }
    e.stored_size = enc[i].stored.size();
    e.checksum = XXH64(enc[i].stored.data(), enc[i].stored.size(), 0);
    stage.add(e.raw_size);
    std::unique_lock lock(mutex);
    ready[i] = 1;
    write_ready(lock);
  }

  // Compression and checksums, one blob per task. Each blob is one
  // single-threaded zstd frame, so the bytes do not depend on the thread
  // count, which the caller caps with tbb::global_control (`--threads`,
  // libprep/pipeline/pipeline.cpp). Not ZSTD_c_nbWorkers: its frames are the
  // same for any worker count >= 1 but differ from single-threaded ones (so
  // every package would change), and on the 10^7-vertex synthetic blobs at
  // level 3 they cost about 20% more CPU (job overlap, input copies) and
  // 45-90 MiB of job buffers at two threads, which undoes on two cores what
  // splitting the largest blob (about 60% of the compression time) gains.
  // The blobs are compressed largest first (the longest task starts first,
  // so the last one to finish is short), ties in table order. The first
  // slot to start completes the source; then each slot takes the next blob
  // of that order until none is left. Whoever finishes last (a blob or the
  // metadata) writes what is left. A slot no worker thread picks up finds
  // the work done.
  void run(PackageSource& source) {
    std::vector<size_t> order(blobs.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
      return blobs[a].bytes.size() > blobs[b].bytes.size();
    });
    std::atomic<bool> completing{false};
    std::atomic<size_t> next{0};
    const size_t slots = std::max<size_t>(
        1, std::min(blobs.size(), size_t(std::max(1, tbb::this_task_arena::max_concurrency()))));
    tbb::parallel_for(size_t(0), slots, [&](size_t) {
      ZSTD_CCtx* cctx = nullptr;
      struct CctxFree {
        ZSTD_CCtx*& c;
        ~CctxFree() { ZSTD_freeCCtx(c); }
      } cctx_free{cctx};
      try {
        if (!completing.exchange(true)) complete(source);
        for (size_t k; (k = next.fetch_add(1, std::memory_order_relaxed)) < order.size();)
          encode(order[k], cctx);
      } catch (...) {
        next.store(order.size());  // the other slots stop after their blob
        throw;
      }
    });
  }
};

// Fills in what the header and the blob table lack once every blob is
// written (`end`: the file size) and writes both over their zeros.
void write_header_and_table(AtomicFile& out, decal::FileHeader& h,
                            const std::vector<EncodedBlob>& enc, uint64_t end) {
  bool all_uncompressed = true;
  for (const EncodedBlob& b : enc)
    if (b.entry.codec == static_cast<uint32_t>(decal::CodecId::zstd)) all_uncompressed = false;
  h.flags = all_uncompressed ? decal::kFlagAllUncompressed : 0;
  h.file_size = end;
  std::vector<decal::BlobTableEntry> table;
  table.reserve(enc.size());
  for (const EncodedBlob& b : enc) table.push_back(b.entry);
  h.table_checksum = XXH64(table.data(), table.size() * sizeof(decal::BlobTableEntry), 0);
  h.header_checksum = XXH64(&h, offsetof(decal::FileHeader, header_checksum), 0);
  out.pwrite(&h, sizeof h, 0);
  out.pwrite(table.data(), table.size() * sizeof(decal::BlobTableEntry), h.table_offset);
}

}  // namespace

void write_package_consuming(const std::string& path, PackageSource& source,
                             const WriteOptions& options) {
  std::vector<BlobInput>& blobs = source.blobs;
  check_write_options(path, options, blobs.size());
  uint64_t raw_bytes = 0;
  for (const BlobInput& b : blobs) raw_bytes += b.bytes.size();
  ProgressStage stage(options.progress, "write", raw_bytes, "bytes");
  std::vector<EncodedBlob> enc(blobs.size());
  std::vector<std::string> names(blobs.size());
  for (size_t i = 0; i < blobs.size(); ++i)
    describe_blob(path, blobs, i, options, enc[i].entry, names[i]);
  decal::FileHeader h = package_header(static_cast<uint32_t>(blobs.size()));

  AtomicFile out(path);
  PackageStream stream{path, options, blobs, enc, names, h, out, stage};
  stream.run(source);
  if (!stream.metadata_written || stream.next_to_write != blobs.size())
    fail_io(path, "internal error: a blob was not written");
  write_header_and_table(out, h, enc, stream.end);
  out.commit();
  stage.finish();
}

void write_package(const std::string& path, const std::string& metadata_json,
                   std::span<const BlobInput> blobs, const WriteOptions& options) {
  check_metadata(path, metadata_json);
  PackageSource source;
  source.blobs.assign(blobs.begin(), blobs.end());
  source.complete = [&] { return metadata_json; };
  write_package_consuming(path, source, options);
}

namespace {

template <class T>
BlobInput blob_of(decal::BlobId id, const std::vector<T>& v) {
  const decal::BlobInfo* info = decal::find_blob_info(id);
  static_assert(std::is_trivially_copyable_v<T>);
  return {id, info->type, info->stride, v.size(), std::as_bytes(std::span<const T>(v))};
}

}  // namespace

std::vector<BlobInput> model_blobs(const DecalModel& m, bool include_empty) {
  std::vector<BlobInput> out;
  for_each_model_array(m, [&](decal::BlobId id, const auto& v) {
    if (include_empty || !v.empty()) out.push_back(blob_of(id, v));
  });
  return out;
}

std::vector<BlobInput> take_model_blobs(DecalModel& m) {
  std::vector<BlobInput> out;
  for_each_model_array(m, [&](decal::BlobId id, auto& v) {
    // The moved vector keeps its buffer, so the blob's span stays valid, and
    // leaves `v` empty.
    auto owned = std::make_shared<std::remove_reference_t<decltype(v)>>(std::move(v));
    BlobInput b = blob_of(id, *owned);
    b.owner = std::move(owned);
    out.push_back(std::move(b));
  });
  return out;
}

}  // namespace prep
