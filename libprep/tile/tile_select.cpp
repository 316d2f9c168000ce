// Which tiles of a tileset a view draws (prep/tile.hpp).
#include "prep/tile.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <queue>
#include <set>
#include <string>

#include "prep/error.hpp"
#include "prep/render.hpp"
#include "prep/stage_error.hpp"

namespace prep::render {
namespace {

// A tile of the quadtree, with or without data.
struct Node {
  int level = 0;
  TileKey key;
  Extent square;                     // absolute
  const TileEntry* entry = nullptr;  // none: no data at this level here
  double pixel = 0;                  // ground metres per pixel at its nearest visible point
  double sse = 0;                    // r_L / pixel: its error in pixels if drawn
  std::optional<uint64_t> blob;      // its blobs decoded, once asked (TileBlobBytes)
  int parent = -1;
  std::vector<int> children;
  bool drawn = false;
};

int64_t floor_half(int64_t v) {
  return v >= 0 ? v / 2 : -((-v + 1) / 2);
}

bool meets(const Extent& square, const std::optional<Extent>& view) {
  if (!view) return true;
  // As prep::tiles_in: the half-open square against the view.
  return square.xmin < view->xmax && view->xmin < square.xmax && square.ymin < view->ymax &&
         view->ymin < square.ymax;
}

std::string bytes_text(uint64_t b) {
  char s[64];
  std::snprintf(s, sizeof s, "%llu bytes (%.1f MiB)", static_cast<unsigned long long>(b),
                double(b) / 1048576.0);
  return s;
}

}  // namespace

namespace {

// One selection: the index and the view, the quadtree walked, the result.
class Selector {
 public:
  Selector(const TilesetIndex& index, const Camera& camera, uint32_t width, uint32_t height,
           double zmin, double zmax, const TileSelectOptions& options)
      : index_(index),
        camera_(camera),
        width_(width),
        height_(height),
        zmin_(zmin),
        zmax_(zmax),
        options_(options),
        top_(int(index.levels.size())) {}

  TileSelection run() {
    check();
    const double ox = index_.frame.origin_x, oy = index_.frame.origin_y;
    out_.per_level.assign(size_t(top_) + 1, 0);
    if (const std::optional<Extent> f = ground_footprint(camera_, width_, height_, zmin_, zmax_))
      out_.footprint = Extent{f->xmin + ox, f->ymin + oy, f->xmax + ox, f->ymax + oy};
    for (const TileEntry& t : index_.tiles)
      if (meets(t.square, out_.footprint)) {
        ++out_.full_detail_tiles;
        out_.full_detail_bytes += t.bytes;
      }
    if (options_.level) return one_level(*options_.level);
    walk();
    for (Node& n : nodes_) {
      out_.blob_bytes += drawn_blob(n);
      out_.package_bytes += drawn_package(n);
    }
    if (options_.gpu_budget && out_.blob_bytes > options_.gpu_budget) coarsen();
    for (const Node& n : nodes_)
      if (n.drawn && n.entry) {
        out_.tiles.push_back({n.level, n.entry, n.pixel, n.blob.value_or(0)});
        ++out_.per_level[size_t(n.level)];
      }
    std::sort(out_.tiles.begin(), out_.tiles.end(),
              [](const SelectedTile& a, const SelectedTile& b) {
                return a.level != b.level ? a.level < b.level : a.entry->key < b.entry->key;
              });
    return std::move(out_);
  }

 private:
  const TilesetIndex& index_;
  const Camera& camera_;
  const uint32_t width_, height_;
  const double zmin_, zmax_;
  const TileSelectOptions& options_;
  const int top_;  // the coarsest level
  TileSelection out_;
  std::vector<Node> nodes_;
  size_t roots_ = 0;
  // The tiles of each level, and the keys with data at that level or below
  // it (only those are walked: a tile absent at every level has no data).
  std::vector<std::map<TileKey, const TileEntry*>> entries_;
  std::vector<std::set<TileKey>> occupied_;

  void check() const {
    for (int l = 1; l <= top_; ++l)
      if (index_.levels[size_t(l - 1)].level != l)
        fail<format_error>(kRenderStage, "tileset.json: overview level " + std::to_string(l) +
                                             " is numbered " +
                                             std::to_string(index_.levels[size_t(l - 1)].level));
    if (options_.level && (*options_.level < 0 || *options_.level > top_))
      fail<usage_error>(kRenderStage, "--level " + std::to_string(*options_.level) +
                                          ": the tileset has levels 0.." + std::to_string(top_));
    if (options_.gpu_budget && !options_.blob_bytes)
      fail<usage_error>(kRenderStage,
                        "--gpu-budget needs the tiles' decoded blob bytes (blob_bytes)");
  }

  uint64_t blob_bytes_of(int l, const TileEntry& t) const {
    return options_.blob_bytes ? options_.blob_bytes(l, t) : 0;
  }
  // "N bytes (x MiB) of decoded blobs (P package bytes)"
  static std::string need_text(uint64_t blob, uint64_t package) {
    return bytes_text(blob) + " of decoded blobs (" + std::to_string(package) + " package bytes)";
  }
  const std::vector<TileEntry>& tiles_of(int l) const {
    return l == 0 ? index_.tiles : index_.levels[size_t(l - 1)].tiles;
  }
  double size_of(int l) const {
    return l == 0 ? index_.tile_size : index_.levels[size_t(l - 1)].tile_size;
  }
  double resolution_of(int l) const {
    return l == 0 ? index_.resolution : index_.levels[size_t(l - 1)].resolution;
  }

  // The nearest visible point of a square: the square cut to the footprint
  // and the data's extent, between zmin and zmax, nearest the eye.
  double pixel_of(const Extent& sq) const {
    const double ox = index_.frame.origin_x, oy = index_.frame.origin_y;
    Extent b = sq;
    const Extent& e = index_.extent;
    b = {std::max(b.xmin, e.xmin), std::max(b.ymin, e.ymin), std::min(b.xmax, e.xmax),
         std::min(b.ymax, e.ymax)};
    if (out_.footprint) {
      const Extent& f = *out_.footprint;
      b = {std::max(b.xmin, f.xmin), std::max(b.ymin, f.ymin), std::min(b.xmax, f.xmax),
           std::min(b.ymax, f.ymax)};
    }
    if (b.xmin > b.xmax || b.ymin > b.ymax) b = sq;  // meets only on an edge
    const Vec3 p{std::clamp(camera_.eye[0], b.xmin - ox, b.xmax - ox),
                 std::clamp(camera_.eye[1], b.ymin - oy, b.ymax - oy),
                 std::clamp(camera_.eye[2], std::min(zmin_, zmax_), std::max(zmin_, zmax_))};
    return pixel_ground_size(camera_, width_, height_, p);
  }

  // One level everywhere.
  TileSelection one_level(int l) {
    for (const TileEntry& t : tiles_of(l))
      if (meets(t.square, out_.footprint)) {
        out_.tiles.push_back({l, &t, pixel_of(t.square), blob_bytes_of(l, t)});
        out_.blob_bytes += out_.tiles.back().blob_bytes;
        out_.package_bytes += t.bytes;
        ++out_.per_level[size_t(l)];
      }
    if (options_.gpu_budget && out_.blob_bytes > options_.gpu_budget)
      fail<resource_error>(kRenderStage, "--gpu-budget " + bytes_text(options_.gpu_budget) +
                                             " is exceeded: level " + std::to_string(l) +
                                             " of this view needs " +
                                             need_text(out_.blob_bytes, out_.package_bytes) +
                                             " in " + std::to_string(out_.tiles.size()) + " tiles");
    return std::move(out_);
  }

  // The square key k has on level l's grid (formats/SPEC.md "Tiling scheme").
  Extent square_of(int l, const TileKey& k) const {
    const double s = size_of(l);
    return Extent{double(k.x) * s, double(k.y) * s, double(k.x + 1) * s, double(k.y + 1) * s};
  }

  int make(int l, const TileKey& k, int parent) {
    Node n;
    n.level = l;
    n.key = k;
    n.square = square_of(l, k);
    const auto it = entries_[size_t(l)].find(k);
    if (it != entries_[size_t(l)].end()) {
      n.entry = it->second;
      n.square = n.entry->square;
    }
    n.pixel = pixel_of(n.square);
    n.sse = n.pixel > 0 ? resolution_of(l) / n.pixel : INFINITY;
    n.parent = parent;
    nodes_.push_back(n);
    return int(nodes_.size() - 1);
  }

  // The quadtree from the coarsest level down: a tile whose resolution is
  // within its pixel is drawn, else its children with data in view are
  // visited.
  void walk() {
    entries_.resize(size_t(top_) + 1);
    occupied_.resize(size_t(top_) + 1);
    for (int l = 0; l <= top_; ++l) {
      for (const TileEntry& t : tiles_of(l)) {
        entries_[size_t(l)][t.key] = &t;
        occupied_[size_t(l)].insert(t.key);
      }
      if (l > 0)
        for (const TileKey& k : occupied_[size_t(l - 1)])
          occupied_[size_t(l)].insert({floor_half(k.x), floor_half(k.y)});
    }
    std::vector<int> stack;
    for (const TileKey& k : occupied_[size_t(top_)])
      if (meets(square_of(top_, k), out_.footprint)) stack.push_back(make(top_, k, -1));
    roots_ = stack.size();
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      const int l = nodes_[size_t(i)].level;
      if (l == 0 || resolution_of(l) <= nodes_[size_t(i)].pixel) {
        nodes_[size_t(i)].drawn = true;
        continue;
      }
      const TileKey k = nodes_[size_t(i)].key;
      for (int64_t cy = 2 * k.y; cy <= 2 * k.y + 1; ++cy)
        for (int64_t cx = 2 * k.x; cx <= 2 * k.x + 1; ++cx) {
          const TileKey c{cx, cy};
          if (!occupied_[size_t(l - 1)].count(c) || !meets(square_of(l - 1, c), out_.footprint))
            continue;
          const int j = make(l - 1, c, i);
          nodes_[size_t(i)].children.push_back(j);
          stack.push_back(j);
        }
    }
  }

  // A node's decoded blob bytes, asked once and only for tiles with data.
  uint64_t blob_of(Node& n) const {
    if (!n.entry) return 0;
    if (!n.blob) n.blob = blob_bytes_of(n.level, *n.entry);
    return *n.blob;
  }
  uint64_t drawn_blob(Node& n) const { return n.drawn ? blob_of(n) : 0; }
  static uint64_t drawn_package(const Node& n) { return n.drawn && n.entry ? n.entry->bytes : 0; }
  bool all_children_drawn(const Node& n) const {
    return !n.drawn && !n.children.empty() &&
           std::all_of(n.children.begin(), n.children.end(),
                       [&](int c) { return nodes_[size_t(c)].drawn; });
  }

  // Coarsen until the budget holds: a tile all of whose visited children
  // are drawn may replace them; the one with the smallest error in pixels
  // first.
  void coarsen() {
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    for (size_t i = 0; i < nodes_.size(); ++i)
      if (all_children_drawn(nodes_[i])) queue.push({nodes_[i].sse, int(i)});
    while (out_.blob_bytes > options_.gpu_budget && !queue.empty()) {
      const int i = queue.top().second;
      queue.pop();
      Node& n = nodes_[size_t(i)];
      for (int c : n.children) {
        out_.blob_bytes -= drawn_blob(nodes_[size_t(c)]);
        out_.package_bytes -= drawn_package(nodes_[size_t(c)]);
        nodes_[size_t(c)].drawn = false;
      }
      n.drawn = true;
      out_.blob_bytes += drawn_blob(n);
      out_.package_bytes += drawn_package(n);
      ++out_.coarsened;
      if (n.parent >= 0 && all_children_drawn(nodes_[size_t(n.parent)]))
        queue.push({nodes_[size_t(n.parent)].sse, n.parent});
    }
    if (out_.blob_bytes > options_.gpu_budget)
      fail<resource_error>(
          kRenderStage, "--gpu-budget " + bytes_text(options_.gpu_budget) +
                            " is exceeded: the coarsest tiles of this view (level " +
                            std::to_string(top_) + ", " + std::to_string(roots_) + " tiles) need " +
                            need_text(out_.blob_bytes, out_.package_bytes));
  }
};

}  // namespace

TileSelection select_tiles(const TilesetIndex& index, const Camera& camera, uint32_t width,
                           uint32_t height, double zmin, double zmax,
                           const TileSelectOptions& options) {
  return Selector(index, camera, width, height, zmin, zmax, options).run();
}

}  // namespace prep::render
