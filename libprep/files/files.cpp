// What decalprep may open and what it may write (prep/files.hpp).
#include "prep/files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <xxhash.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <string_view>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

const char* kind_of(mode_t m) {
  if (S_ISFIFO(m)) return "a FIFO (named pipe)";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISDIR(m)) return "a directory";
  if (S_ISREG(m)) return "";
  return "not a regular file";
}

// The local file a /vsizip/, /vsitar/, /vsigzip/, /vsi7z/ or /vsirar/ path
// reads: what follows the prefix up to the archive's extension (GDAL's own
// rule is richer; this catches a FIFO or a device named as the archive).
std::string archive_of(const std::string& path) {
  for (std::string_view p : {"/vsizip/", "/vsitar/", "/vsigzip/", "/vsi7z/", "/vsirar/"}) {
    if (path.rfind(p, 0) != 0) continue;
    std::string rest = path.substr(p.size());
    if (rest.rfind("{", 0) == 0) {
      const size_t close = rest.find('}');
      return close == std::string::npos ? std::string{} : rest.substr(1, close - 1);
    }
    for (std::string_view ext : {".zip", ".tar", ".tgz", ".tar.gz", ".gz", ".7z", ".rar", ".kmz"}) {
      const size_t at = rest.find(ext);
      if (at != std::string::npos) {
        const size_t end = at + ext.size();
        if (end == rest.size() || rest[end] == '/') return rest.substr(0, end);
      }
    }
    return rest;
  }
  return {};
}

}  // namespace

std::optional<FileId> file_id(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return std::nullopt;
  return FileId{static_cast<unsigned long long>(st.st_dev),
                static_cast<unsigned long long>(st.st_ino)};
}

bool is_gdal_virtual_path(const std::string& path) {
  return path.rfind("/vsi", 0) == 0;
}

bool is_network_path(const std::string& path) {
  static constexpr std::array<std::string_view, 11> kNetwork = {
      "/vsicurl",        "/vsis3",    "/vsigs",      "/vsiaz",   "/vsiadls",
      "/vsioss",         "/vsiswift", "/vsiwebhdfs", "/vsihdfs", "/vsicurl_streaming",
      "/vsis3_streaming"};
  for (std::string_view n : kNetwork)
    if (path.find(n) != std::string::npos) return true;
  // A URL GDAL would fetch through /vsicurl/ by itself.
  for (std::string_view scheme : {"http://", "https://", "ftp://"})
    if (path.find(scheme) != std::string::npos) return true;
  return false;
}

std::string special_file_kind(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {};
  if (S_ISDIR(st.st_mode)) return {};
  return kind_of(st.st_mode);
}

void check_input_file(const std::string& path, const std::string& what, InputKind kind) {
  std::string local = path;
  if (is_gdal_virtual_path(path)) {
    local = archive_of(path);
    if (local.empty() || is_gdal_virtual_path(local)) return;
  }
  struct stat st {};
  if (::stat(local.c_str(), &st) != 0) return;  // the opener says it is missing
  if (S_ISREG(st.st_mode)) return;
  if (S_ISDIR(st.st_mode) && kind == InputKind::file_or_directory) return;
  fail<input_error>(kNoStage,
                    what + " '" + local + "' is " + kind_of(st.st_mode) +
                        ", not a regular file; decalprep reads only regular files (a FIFO or a "
                        "device could block or never end)");
}

void check_output_file(const std::string& path, const std::string& what,
                       const std::vector<std::string>& inputs) {
  struct stat st {};
  // A link is not replaced either: the rename would put a file where the
  // user's link was, and an open() would write wherever it points.
  if (::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode))
    fail<output_error>(kNoStage,
                       what + " '" + path +
                           "' is a symbolic link; decalprep replaces only a regular file (nothing "
                           "was written)");
  if (::stat(path.c_str(), &st) == 0) {
    if (!S_ISREG(st.st_mode))
      fail<output_error>(kNoStage,
                         what + " '" + path + "' exists and is " + kind_of(st.st_mode) +
                             "; decalprep replaces only a regular file (nothing was written)");
    const FileId target{static_cast<unsigned long long>(st.st_dev),
                        static_cast<unsigned long long>(st.st_ino)};
    for (const std::string& in : inputs) {
      if (in.empty()) continue;
      if (file_id(in) == target)
        fail<output_error>(
            kNoStage, what + " '" + path + "' is the input '" + in +
                          "' itself; writing it would destroy the input (nothing was written)");
    }
  }
}

void write_file_atomically(const std::string& path, std::string_view bytes,
                           const std::string& what) {
  check_output_file(path, what, {});
  static std::atomic<unsigned> counter{0};
  const size_t slash = path.rfind('/');
  const std::string folder = slash == std::string::npos ? "" : path.substr(0, slash + 1);
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const std::string tmp = folder + "." + name + ".tmp-" + std::to_string(::getpid()) + "-" +
                          std::to_string(counter.fetch_add(1));
  auto fail_with = [&](const std::string& doing, int err) {
    fail<output_error>(kNoStage, what + " '" + path + "': " + doing + ": " + std::strerror(err));
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) fail_with("cannot create a temporary file beside it", errno);
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : ENOSPC;
      ::close(fd);
      ::unlink(tmp.c_str());
      fail_with("cannot write", err);
    }
    done += static_cast<size_t>(n);
  }
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    fail_with("cannot write", err);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    fail_with("cannot rename " + tmp + " over it", err);
  }
}

std::optional<FileDigest> file_digest(const std::string& path, std::string* why) {
  // The reader's open: a FIFO or a device (a tile symlinked to /dev/zero)
  // is refused before a byte is read, never read forever.
  int fd = -1;
  uint64_t size = 0;
  if (const decal::Status s = decal::open_regular_file(path, fd, size); !s) {
    if (why) *why = s.message;
    return std::nullopt;
  }
  XXH64_state_t* st = XXH64_createState();
  XXH64_reset(st, 0);
  std::vector<char> buf(1 << 16);
  FileDigest d;
  for (;;) {
    const ssize_t n = ::read(fd, buf.data(), buf.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      if (why) *why = "cannot read '" + path + "': " + std::strerror(errno);
      ::close(fd);
      XXH64_freeState(st);
      return std::nullopt;
    }
    if (n == 0) break;
    XXH64_update(st, buf.data(), static_cast<size_t>(n));
    d.bytes += static_cast<uint64_t>(n);
  }
  ::close(fd);
  d.xxh64 = XXH64_digest(st);
  XXH64_freeState(st);
  return d;
}

std::string hex64(uint64_t v) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016" PRIx64, v);
  return hex;
}

void write_text_file(const std::string& path, const std::string& text) {
  write_file_atomically(path, text, "output file");
}

}  // namespace prep
