// The packed R-tree over the parts' boxes (part_index.hpp): built once when
// the prepare step closes its parts file, queried by every tile.
#include "part_index.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep::tiling {

namespace {

constexpr char kIndexMagic[8] = {'D', 'P', 'P', 'I', 'D', 'X', '0', '1'};
constexpr uint32_t kMaxIndexLevels = 24;  // 16^24 leaves: far beyond any file
constexpr uint64_t kIndexHeadBytes = 8 + 8 + 4 + 4;

// The index along the Hilbert curve of order 16 of the cell (x, y), both
// below 2^16: consecutive leaves lie close together, so a node's box is
// small.
uint64_t hilbert_index(uint32_t x, uint32_t y) {
  constexpr uint32_t n = 1u << 16;
  uint64_t d = 0;
  for (uint32_t s = n / 2; s > 0; s /= 2) {
    const uint32_t rx = (x & s) ? 1 : 0, ry = (y & s) ? 1 : 0;
    d += uint64_t(s) * s * ((3 * rx) ^ ry);
    if (ry == 0) {
      if (rx == 1) {
        x = n - 1 - x;
        y = n - 1 - y;
      }
      std::swap(x, y);
    }
  }
  return d;
}

// A box that holds nothing yet, and `into` grown to hold `r`'s box.
BoxRecord nothing() {
  BoxRecord b;
  b.xmin = b.ymin = INFINITY;
  b.xmax = b.ymax = -INFINITY;
  return b;
}
void take_in(BoxRecord& into, const BoxRecord& r) {
  into.xmin = std::min(into.xmin, r.xmin);
  into.ymin = std::min(into.ymin, r.ymin);
  into.xmax = std::max(into.xmax, r.xmax);
  into.ymax = std::max(into.ymax, r.ymax);
}

bool box_meets(const BoxRecord& r, const Extent& w) {
  return r.xmin <= w.xmax && r.xmax >= w.xmin && r.ymin <= w.ymax && r.ymax >= w.ymin;
}

std::vector<BoxRecord> read_boxes(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  struct stat st {};
  if (!f || ::fstat(::fileno(f), &st) != 0) {
    if (f) std::fclose(f);
    fail<output_error>(kTilesetStage, "cannot read " + path + ": " + std::strerror(errno));
  }
  std::vector<BoxRecord> out(uint64_t(st.st_size) / sizeof(BoxRecord));
  const bool ok = uint64_t(st.st_size) % sizeof(BoxRecord) == 0 &&
                  std::fread(out.data(), sizeof(BoxRecord), out.size(), f) == out.size();
  std::fclose(f);
  if (!ok) fail<output_error>(kTilesetStage, "cannot read " + path + ": not whole box records");
  return out;
}

}  // namespace

void write_box_index(const std::string& boxes_path, const std::string& index_path) {
  std::vector<BoxRecord> leaves = read_boxes(boxes_path);
  // Sorted by the Hilbert index of each box's centre on a 2^16 grid over
  // all the boxes (ties in write order, so the file is the same every run).
  BoxRecord all = nothing();
  for (const BoxRecord& r : leaves) take_in(all, r);
  const double sx = all.xmax > all.xmin ? 65535.0 / (all.xmax - all.xmin) : 0;
  const double sy = all.ymax > all.ymin ? 65535.0 / (all.ymax - all.ymin) : 0;
  // Each leaf's Hilbert index above its position (8 bytes a part), sorted,
  // then the leaves permuted in place cycle by cycle: the build holds 56
  // bytes a part at its peak.
  if (leaves.size() >= (uint64_t(1) << 32))
    fail<resource_error>(kTilesetStage, "more than 2^32 parts in " + boxes_path);
  std::vector<uint64_t> order(leaves.size());
  for (size_t i = 0; i < leaves.size(); ++i) {
    const BoxRecord& r = leaves[i];
    const double cx = std::clamp((0.5 * (r.xmin + r.xmax) - all.xmin) * sx, 0.0, 65535.0);
    const double cy = std::clamp((0.5 * (r.ymin + r.ymax) - all.ymin) * sy, 0.0, 65535.0);
    order[i] = hilbert_index(uint32_t(cx), uint32_t(cy)) << 32 | i;
  }
  std::sort(order.begin(), order.end());
  constexpr uint64_t kDone = ~uint64_t(0);
  for (size_t k = 0; k < order.size(); ++k) {
    if (order[k] == kDone) continue;
    const BoxRecord first = leaves[k];
    for (size_t j = k;;) {
      const size_t from = size_t(order[j] & 0xffffffffu);
      order[j] = kDone;
      if (from == k) {
        leaves[j] = first;
        break;
      }
      leaves[j] = leaves[from];
      j = from;
    }
  }
  order = {};
  std::vector<std::vector<BoxRecord>> levels(1);
  levels[0] = std::move(leaves);
  while (levels.back().size() > kIndexFanout) {
    const std::vector<BoxRecord>& below = levels.back();
    std::vector<BoxRecord> up((below.size() + kIndexFanout - 1) / kIndexFanout);
    for (size_t j = 0; j < up.size(); ++j) {
      const size_t first = j * kIndexFanout;
      const size_t last = std::min(below.size(), first + kIndexFanout);
      BoxRecord& node = up[j];
      node = nothing();
      for (size_t k = first; k < last; ++k) take_in(node, below[k]);
      node.offset = first;
      node.bytes = uint32_t(last - first);
    }
    levels.push_back(std::move(up));
  }
  std::reverse(levels.begin(), levels.end());

  std::FILE* f = std::fopen(index_path.c_str(), "wb");
  if (!f)
    fail<output_error>(kTilesetStage, "cannot create " + index_path + ": " + std::strerror(errno));
  bool ok = std::fwrite(kIndexMagic, 1, 8, f) == 8;
  const uint64_t entries = levels.back().size();
  const uint32_t head[2] = {uint32_t(levels.size()), kIndexFanout};
  ok = ok && std::fwrite(&entries, 8, 1, f) == 1 && std::fwrite(head, 4, 2, f) == 2;
  for (const auto& l : levels) {
    const uint64_t n = l.size();
    ok = ok && std::fwrite(&n, 8, 1, f) == 1;
  }
  for (const auto& l : levels)
    ok = ok && std::fwrite(l.data(), sizeof(BoxRecord), l.size(), f) == l.size();
  ok = std::fclose(f) == 0 && ok;
  if (!ok) fail<output_error>(kTilesetStage, "cannot write " + index_path);
}

// ---------------------------------------------------------------- reader --

bool pread_exact(int fd, void* dst, size_t n, uint64_t at) {
  auto* p = static_cast<char*>(dst);
  while (n > 0) {
    const ssize_t got = ::pread(fd, p, n, static_cast<off_t>(at));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    p += got;
    n -= size_t(got);
    at += uint64_t(got);
  }
  return true;
}

BoxIndex::BoxIndex(const std::string& path, uint64_t data_bytes)
    : path_(path), data_bytes_(data_bytes) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0)
    fail<output_error>(kTilesetStage, "cannot open " + path + ": " + std::strerror(errno));
  auto corrupt = [&](const std::string& what) {
    fail<output_error>(kTilesetStage, path + " is not a parts index this build wrote: " + what);
  };
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) corrupt("not a regular file");
  const auto size = uint64_t(st.st_size);
  char magic[8];
  uint32_t head[2];
  if (size < kIndexHeadBytes || !pread_exact(fd_, magic, 8, 0) ||
      !pread_exact(fd_, &entries_, 8, 8) || !pread_exact(fd_, head, 8, 16))
    corrupt("shorter than its header");
  if (std::memcmp(magic, kIndexMagic, 8) != 0) corrupt("wrong magic");
  const uint32_t levels = head[0];
  if (levels < 1 || levels > kMaxIndexLevels) corrupt("levels " + std::to_string(levels));
  if (head[1] != kIndexFanout) corrupt("fanout " + std::to_string(head[1]));
  std::vector<uint64_t> count(levels);
  if (size < kIndexHeadBytes + 8ull * levels ||
      !pread_exact(fd_, count.data(), 8ull * levels, kIndexHeadBytes))
    corrupt("shorter than its level counts");
  // Each level is the one below in groups of kIndexFanout; the root holds at
  // most kIndexFanout; the items fill the file exactly.
  if (count.back() != entries_ || entries_ > size / sizeof(BoxRecord)) corrupt("entry count");
  if (count.front() > kIndexFanout) corrupt("root of " + std::to_string(count.front()) + " items");
  uint64_t items = 0;
  for (uint32_t i = 0; i < levels; ++i) {
    if (i + 1 < levels && count[i] != (count[i + 1] + kIndexFanout - 1) / kIndexFanout)
      corrupt("level " + std::to_string(i) + " count");
    items += count[i];
  }
  const uint64_t items_at = kIndexHeadBytes + 8ull * levels;
  if (items > (size - items_at) / sizeof(BoxRecord) || items_at + items * sizeof(BoxRecord) != size)
    corrupt("size " + std::to_string(size) + " bytes does not match its counts");
  uint64_t at = items_at;
  inner_.resize(levels - 1);
  for (uint32_t i = 0; i + 1 < levels; ++i) {
    inner_[i].resize(count[i]);
    if (!pread_exact(fd_, inner_[i].data(), count[i] * sizeof(BoxRecord), at))
      corrupt("short read at level " + std::to_string(i));
    for (const BoxRecord& r : inner_[i])
      if (r.bytes < 1 || r.bytes > kIndexFanout || r.bytes > count[i + 1] ||
          r.offset > count[i + 1] - r.bytes)
        corrupt("a node's children out of range at level " + std::to_string(i));
    at += count[i] * sizeof(BoxRecord);
  }
  leaf_at_ = at;
}

BoxIndex::~BoxIndex() {
  if (fd_ >= 0) ::close(fd_);
}

void BoxIndex::read_leaves(uint64_t first, uint32_t count, std::vector<BoxRecord>& buf) const {
  buf.resize(count);
  if (first > entries_ || count > entries_ - first ||
      !pread_exact(fd_, buf.data(), size_t(count) * sizeof(BoxRecord),
                   leaf_at_ + first * sizeof(BoxRecord)))
    fail<output_error>(kTilesetStage, "cannot read the leaves of " + path_);
  for (const BoxRecord& r : buf)
    if (r.kind < 0 || r.kind > 2 || r.offset > data_bytes_ || r.bytes > data_bytes_ - r.offset)
      fail<output_error>(kTilesetStage, path_ + ": a part record out of range (offset " +
                                            std::to_string(r.offset) + ", " +
                                            std::to_string(r.bytes) + " bytes)");
}

void BoxIndex::query(const Extent& window, std::vector<BoxRecord>& out) const {
  if (entries_ == 0) return;
  std::vector<BoxRecord> leaves;
  struct Visit {
    size_t level;
    uint64_t first;
    uint32_t count;
  };
  std::vector<Visit> stack;
  const size_t leaf_level = inner_.size();
  stack.push_back({0, 0, uint32_t(leaf_level == 0 ? entries_ : inner_[0].size())});
  while (!stack.empty()) {
    const Visit v = stack.back();
    stack.pop_back();
    if (v.level == leaf_level) {
      read_leaves(v.first, v.count, leaves);
      for (const BoxRecord& r : leaves)
        if (box_meets(r, window)) out.push_back(r);
      continue;
    }
    const std::vector<BoxRecord>& level = inner_[v.level];
    for (uint64_t k = v.first; k < v.first + v.count; ++k)
      if (box_meets(level[k], window))
        stack.push_back({v.level + 1, level[k].offset, level[k].bytes});
  }
}

}  // namespace prep::tiling
