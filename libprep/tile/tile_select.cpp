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

TileSelection select_tiles(const TilesetIndex& index, const Camera& camera, uint32_t width,
                           uint32_t height, double zmin, double zmax,
                           const TileSelectOptions& options) {
  const int top = int(index.levels.size());
  for (int l = 1; l <= top; ++l)
    if (index.levels[size_t(l - 1)].level != l)
      fail<format_error>(kRenderStage, "tileset.json: overview level " + std::to_string(l) +
                                           " is numbered " +
                                           std::to_string(index.levels[size_t(l - 1)].level));
  if (options.level && (*options.level < 0 || *options.level > top))
    fail<usage_error>(kRenderStage, "--level " + std::to_string(*options.level) +
                                        ": the tileset has levels 0.." + std::to_string(top));
  if (options.gpu_budget && !options.blob_bytes)
    fail<usage_error>(kRenderStage,
                      "--gpu-budget needs the tiles' decoded blob bytes (blob_bytes)");
  auto blob_bytes_of = [&](int l, const TileEntry& t) -> uint64_t {
    return options.blob_bytes ? options.blob_bytes(l, t) : 0;
  };
  // "N bytes (x MiB) of decoded blobs (P package bytes)"
  auto need_text = [](uint64_t blob, uint64_t package) {
    return bytes_text(blob) + " of decoded blobs (" + std::to_string(package) + " package bytes)";
  };

  const double ox = index.frame.origin_x, oy = index.frame.origin_y;
  TileSelection out;
  out.per_level.assign(size_t(top) + 1, 0);
  if (const std::optional<Extent> f = ground_footprint(camera, width, height, zmin, zmax))
    out.footprint = Extent{f->xmin + ox, f->ymin + oy, f->xmax + ox, f->ymax + oy};

  auto tiles_of = [&](int l) -> const std::vector<TileEntry>& {
    return l == 0 ? index.tiles : index.levels[size_t(l - 1)].tiles;
  };
  auto size_of = [&](int l) {
    return l == 0 ? index.tile_size : index.levels[size_t(l - 1)].tile_size;
  };
  auto resolution_of = [&](int l) {
    return l == 0 ? index.resolution : index.levels[size_t(l - 1)].resolution;
  };

  for (const TileEntry& t : index.tiles)
    if (meets(t.square, out.footprint)) {
      ++out.full_detail_tiles;
      out.full_detail_bytes += t.bytes;
    }

  // The nearest visible point of a square: the square cut to the footprint
  // and the data's extent, between zmin and zmax, nearest the eye.
  auto pixel_of = [&](const Extent& sq) {
    Extent b = sq;
    const Extent& e = index.extent;
    b = {std::max(b.xmin, e.xmin), std::max(b.ymin, e.ymin), std::min(b.xmax, e.xmax),
         std::min(b.ymax, e.ymax)};
    if (out.footprint) {
      const Extent& f = *out.footprint;
      b = {std::max(b.xmin, f.xmin), std::max(b.ymin, f.ymin), std::min(b.xmax, f.xmax),
           std::min(b.ymax, f.ymax)};
    }
    if (b.xmin > b.xmax || b.ymin > b.ymax) b = sq;  // meets only on an edge
    const Vec3 p{std::clamp(camera.eye[0], b.xmin - ox, b.xmax - ox),
                 std::clamp(camera.eye[1], b.ymin - oy, b.ymax - oy),
                 std::clamp(camera.eye[2], std::min(zmin, zmax), std::max(zmin, zmax))};
    return pixel_ground_size(camera, width, height, p);
  };

  // One level everywhere.
  if (options.level) {
    const int l = *options.level;
    for (const TileEntry& t : tiles_of(l))
      if (meets(t.square, out.footprint)) {
        out.tiles.push_back({l, &t, pixel_of(t.square), blob_bytes_of(l, t)});
        out.blob_bytes += out.tiles.back().blob_bytes;
        out.package_bytes += t.bytes;
        ++out.per_level[size_t(l)];
      }
    if (options.gpu_budget && out.blob_bytes > options.gpu_budget)
      fail<resource_error>(kRenderStage, "--gpu-budget " + bytes_text(options.gpu_budget) +
                                             " is exceeded: level " + std::to_string(l) +
                                             " of this view needs " +
                                             need_text(out.blob_bytes, out.package_bytes) + " in " +
                                             std::to_string(out.tiles.size()) + " tiles");
    return out;
  }

  // The tiles of each level, and the keys with data at that level or below
  // it (only those are walked: a tile absent at every level has no data).
  std::vector<std::map<TileKey, const TileEntry*>> entries(size_t(top) + 1);
  std::vector<std::set<TileKey>> occupied(size_t(top) + 1);
  for (int l = 0; l <= top; ++l) {
    for (const TileEntry& t : tiles_of(l)) {
      entries[size_t(l)][t.key] = &t;
      occupied[size_t(l)].insert(t.key);
    }
    if (l > 0)
      for (const TileKey& k : occupied[size_t(l - 1)])
        occupied[size_t(l)].insert({floor_half(k.x), floor_half(k.y)});
  }
  // The square key k has on level l's grid (formats/SPEC.md "Tiling scheme").
  auto square_of = [&](int l, const TileKey& k) {
    const double s = size_of(l);
    return Extent{double(k.x) * s, double(k.y) * s, double(k.x + 1) * s, double(k.y + 1) * s};
  };
  std::vector<Node> nodes;
  auto make = [&](int l, const TileKey& k, int parent) {
    Node n;
    n.level = l;
    n.key = k;
    n.square = square_of(l, k);
    const auto it = entries[size_t(l)].find(k);
    if (it != entries[size_t(l)].end()) {
      n.entry = it->second;
      n.square = n.entry->square;
    }
    n.pixel = pixel_of(n.square);
    n.sse = n.pixel > 0 ? resolution_of(l) / n.pixel : INFINITY;
    n.parent = parent;
    nodes.push_back(n);
    return int(nodes.size() - 1);
  };
  std::vector<int> stack;
  for (const TileKey& k : occupied[size_t(top)])
    if (meets(square_of(top, k), out.footprint)) stack.push_back(make(top, k, -1));
  std::vector<int> roots = stack;
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    const int l = nodes[size_t(i)].level;
    if (l == 0 || resolution_of(l) <= nodes[size_t(i)].pixel) {
      nodes[size_t(i)].drawn = true;
      continue;
    }
    const TileKey k = nodes[size_t(i)].key;
    for (int64_t cy = 2 * k.y; cy <= 2 * k.y + 1; ++cy)
      for (int64_t cx = 2 * k.x; cx <= 2 * k.x + 1; ++cx) {
        const TileKey c{cx, cy};
        if (!occupied[size_t(l - 1)].count(c) || !meets(square_of(l - 1, c), out.footprint))
          continue;
        const int j = make(l - 1, c, i);
        nodes[size_t(i)].children.push_back(j);
        stack.push_back(j);
      }
  }

  // A node's decoded blob bytes, asked once and only for tiles with data.
  auto blob_of = [&](Node& n) -> uint64_t {
    if (!n.entry) return 0;
    if (!n.blob) n.blob = blob_bytes_of(n.level, *n.entry);
    return *n.blob;
  };
  auto drawn_blob = [&](Node& n) { return n.drawn ? blob_of(n) : 0; };
  auto drawn_package = [&](const Node& n) { return n.drawn && n.entry ? n.entry->bytes : 0; };
  for (Node& n : nodes) {
    out.blob_bytes += drawn_blob(n);
    out.package_bytes += drawn_package(n);
  }

  if (options.gpu_budget && out.blob_bytes > options.gpu_budget) {
    // Coarsen: a tile all of whose visited children are drawn may replace
    // them; the one with the smallest error in pixels first.
    auto all_children_drawn = [&](const Node& n) {
      return !n.drawn && !n.children.empty() &&
             std::all_of(n.children.begin(), n.children.end(),
                         [&](int c) { return nodes[size_t(c)].drawn; });
    };
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    for (size_t i = 0; i < nodes.size(); ++i)
      if (all_children_drawn(nodes[i])) queue.push({nodes[i].sse, int(i)});
    while (out.blob_bytes > options.gpu_budget && !queue.empty()) {
      const int i = queue.top().second;
      queue.pop();
      Node& n = nodes[size_t(i)];
      for (int c : n.children) {
        out.blob_bytes -= drawn_blob(nodes[size_t(c)]);
        out.package_bytes -= drawn_package(nodes[size_t(c)]);
        nodes[size_t(c)].drawn = false;
      }
      n.drawn = true;
      out.blob_bytes += drawn_blob(n);
      out.package_bytes += drawn_package(n);
      ++out.coarsened;
      if (n.parent >= 0 && all_children_drawn(nodes[size_t(n.parent)]))
        queue.push({nodes[size_t(n.parent)].sse, n.parent});
    }
    if (out.blob_bytes > options.gpu_budget)
      fail<resource_error>(kRenderStage,
                           "--gpu-budget " + bytes_text(options.gpu_budget) +
                               " is exceeded: the coarsest tiles of this view (level " +
                               std::to_string(top) + ", " + std::to_string(roots.size()) +
                               " tiles) need " + need_text(out.blob_bytes, out.package_bytes));
  }

  for (const Node& n : nodes)
    if (n.drawn && n.entry) {
      out.tiles.push_back({n.level, n.entry, n.pixel, n.blob.value_or(0)});
      ++out.per_level[size_t(n.level)];
    }
  std::sort(out.tiles.begin(), out.tiles.end(), [](const SelectedTile& a, const SelectedTile& b) {
    return a.level != b.level ? a.level < b.level : a.entry->key < b.entry->key;
  });
  return out;
}

}  // namespace prep::render
