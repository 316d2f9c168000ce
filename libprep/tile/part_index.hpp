// The box index of a tileset build's parts file (not a public header): a
// static packed R-tree on disk. The leaves are the parts' box records,
// sorted by the Hilbert index of their centres; each node above holds the
// box of up to kIndexFanout consecutive entries of the level below
// (ARCHITECTURE.md "3b. tile", parts.bin and parts.idx).
//
// parts.idx, little-endian:
//   "DPPIDX01"                    8 bytes
//   uint64 entries                the leaf count (the parts)
//   uint32 levels, uint32 fanout  levels >= 1, root first
//   uint64 count[levels]          entries per level; the last is `entries`
//   BoxRecord items               every level's, root first, back to back
// An inner item's `offset` is the index of its first child in the next
// level and its `bytes` the number of children; a leaf is the part's
// record as boxes.bin has it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "prep/spec.hpp"

namespace prep::tiling {

// One part's box record (boxes.bin, and the leaves of parts.idx): its kind
// (PartKind), where its record lies in parts.bin, and its exact box.
struct BoxRecord {
  int32_t kind = 0;
  uint32_t bytes = 0;
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
  uint64_t offset = 0;
};
static_assert(sizeof(BoxRecord) == 48, "BoxRecord is stored as its bytes");

inline constexpr uint32_t kIndexFanout = 16;

// Reads exactly `n` bytes of `fd` at `at` (pread, retried on EINTR and short
// reads); false on an error or the end of the file.
bool pread_exact(int fd, void* dst, size_t n, uint64_t at);

// Builds `index_path` from the records of `boxes_path` (written in order).
// Holds the records and their sort keys in memory while it sorts them
// (56 bytes a part).
// Throws output_error naming the file.
void write_box_index(const std::string& boxes_path, const std::string& index_path);

// Reads parts.idx: the inner levels in memory (about 3 bytes a part), the
// leaves from the file when a query reaches them. Treats the file as
// hostile: every count, child range and record is checked against the
// file's size before it is used. One reader per thread.
class BoxIndex {
 public:
  // `data_bytes`: the size of parts.bin, which every leaf must lie within.
  BoxIndex(const std::string& path, uint64_t data_bytes);
  ~BoxIndex();
  BoxIndex(const BoxIndex&) = delete;
  BoxIndex& operator=(const BoxIndex&) = delete;

  // Appends every leaf whose box meets `window` (closed boxes), in no
  // particular order.
  void query(const Extent& window, std::vector<BoxRecord>& out) const;
  uint64_t entries() const { return entries_; }

 private:
  void read_leaves(uint64_t first, uint32_t count, std::vector<BoxRecord>& buf) const;
  std::string path_;
  int fd_ = -1;
  uint64_t entries_ = 0;
  uint64_t data_bytes_ = 0;
  uint64_t leaf_at_ = 0;                       // file offset of the leaf level
  std::vector<std::vector<BoxRecord>> inner_;  // the levels above the leaves, root first
};

}  // namespace prep::tiling
