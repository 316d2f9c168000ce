// prep/files.hpp — the one rule for what decalprep opens and what it writes.
//
// Inputs: every file decalprep reads (a source, a scene file, a DEM, a
// package, a tile, an index) is checked with stat() before a byte is read:
// a FIFO, a socket, a device or (unless allowed) a directory is refused, so
// nothing can block in open() or read forever. GDAL's virtual paths
// (/vsizip/..., /vsicurl/...) are not local files: the caller decides
// whether it accepts one (remote_path_kind).
//
// Outputs: a writer touches only the named output, and only when it is a
// regular file or absent (check_output_file) and is not one of the build's
// inputs (compared by device and inode, not by spelling, so "a/../v.geojson",
// a hard link or a symlink are caught too).
//
// Thread-safe: these functions only stat().
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace prep {

// A file's identity: device and inode.
struct FileId {
  unsigned long long dev = 0, ino = 0;
  bool operator==(const FileId&) const = default;
};

// The identity of the file `path` names (symlinks followed), or nullopt
// when it does not exist or cannot be stat()ed.
std::optional<FileId> file_id(const std::string& path);

// True for a GDAL virtual file system path (/vsi...): not a local file.
bool is_gdal_virtual_path(const std::string& path);
// True for a GDAL virtual path that reaches the network (/vsicurl/,
// /vsis3/, /vsigs/, /vsiaz/, /vsiadls/, /vsioss/, /vsiswift/, /vsiwebhdfs/,
// /vsihdfs/, and any of these inside another, e.g. /vsizip//vsicurl/...).
bool is_network_path(const std::string& path);

// What an input may be besides a regular file.
enum class InputKind { file, file_or_directory };

// Refuses, with input_error "<what> '<path>' is a FIFO (named pipe): ..."
// and the like, a local path that exists and is not a regular file (or a
// directory, where `kind` allows one). A path that does not exist is left
// to the opener, whose message says so. GDAL virtual paths pass unchecked,
// except that the local file a /vsizip/, /vsitar/ or /vsigzip/ path opens
// is checked too. Throws nothing else.
void check_input_file(const std::string& path, const std::string& what,
                      InputKind kind = InputKind::file);

// A sentence saying what kind of non-regular file `path` is ("a FIFO
// (named pipe)", "a character device", ...), or empty for a regular file,
// a directory or a path that does not exist.
std::string special_file_kind(const std::string& path);

// Refuses, with output_error (exit 7), an output target that exists and is
// not a regular file (a FIFO, a device node, a directory, a socket, a
// symbolic link, dangling or not), and a
// target that is the same file as any of `inputs` (existing inputs only;
// compared by device and inode). `what` names the output in the message
// ("package", "report", "PNG"). Leaves everything as it was.
void check_output_file(const std::string& path, const std::string& what,
                       const std::vector<std::string>& inputs);

// Writes `bytes` to `path` whole, or leaves `path` as it was: the target is
// checked as check_output_file does (no inputs), the bytes go to a temp file
// of this process's own beside it (".<name>.tmp-<pid>-<n>", created
// exclusively, never through a link) and are renamed over the target, so a
// reader never sees half of it. Throws output_error naming `what` and the
// path on failure, after removing the temp file. Thread-safe.
void write_file_atomically(const std::string& path, std::string_view bytes,
                           const std::string& what);

// Bytes and XXH64 (seed 0) of a file, read in 64 KiB pieces; nullopt when it
// cannot be opened.
struct FileDigest {
  uint64_t bytes = 0, xxh64 = 0;
};
// The file is opened as the package reader opens one (decal::open_regular_file):
// a FIFO, a device or a socket is refused before a byte is read; `why`,
// when given, then says why (the path and what it is).
std::optional<FileDigest> file_digest(const std::string& path, std::string* why = nullptr);

// "%016llx"
std::string hex64(uint64_t v);

// Writes a small text file whole, through an exclusive temp file and a
// rename (write_file_atomically), so that a reader never sees half of it.
// Throws output_error naming the path.
void write_text_file(const std::string& path, const std::string& text);

// ------------------------------------------------------------ interrupts --

// what a build undoes when SIGINT or SIGTERM stops it.
//
// A command that makes things on disk over a long run (a tileset build)
// calls watch_interrupts() before it starts any thread: SIGINT and SIGTERM
// are then blocked in every thread and one watcher thread waits for them
// (sigwait). When one comes, the watcher runs every registered cleanup,
// newest first, runs the handler a library installed for that signal, if
// any (prep/write.hpp's temp-file removal), prints what it did and ends the
// process with exit code 128 + the signal's number (130 for SIGINT, 143 for
// SIGTERM: prep::ExitCode::interrupted / terminated), the code a shell
// reports for a process that a signal stopped.
//
// Cleanups run on the watcher thread while the build's other threads may
// still be working: a cleanup must not wait for them and must tolerate
// files that come and go (rename a folder away before removing it).
// Without watch_interrupts() (the library used in-process, as by the
// tests) an OnInterrupt does nothing.
// Blocks SIGINT and SIGTERM in the calling thread (every thread it starts
// inherits the mask) and starts the watcher. Call once, from main's thread,
// before any other thread exists. Idempotent.
void watch_interrupts();

// Registers `cleanup` (with a line that says what it undoes, printed when it
// runs) for as long as the object lives. Thread-safe.
class OnInterrupt {
 public:
  OnInterrupt(std::string what, std::function<void()> cleanup);
  ~OnInterrupt();
  OnInterrupt(const OnInterrupt&) = delete;
  OnInterrupt& operator=(const OnInterrupt&) = delete;

 private:
  unsigned long id_ = 0;
};

}  // namespace prep
