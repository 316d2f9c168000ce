// Structural validation of package blobs before any GL call (gl.hpp
// validate_blobs). Every index a shader follows is checked here, because an
// out-of-range read on a GPU is undefined behaviour, not an exception.
#include <algorithm>
#include <array>
#include <cstring>
#include <string>

#include "decal/gl/gl.hpp"

namespace decal::gl {

namespace {

template <class T>
struct Arr {
  const std::byte* p = nullptr;
  uint64_t n = 0;
  T operator[](uint64_t i) const {
    T v;
    std::memcpy(&v, p + i * sizeof(T), sizeof(T));
    return v;
  }
};

using I2 = std::array<int32_t, 2>;
using U2 = std::array<uint32_t, 2>;
using I4 = std::array<int32_t, 4>;
using U4 = std::array<uint32_t, 4>;

std::string where(std::string_view blob, uint64_t i) {
  return "render: invalid package: " + std::string(blob) + "[" + std::to_string(i) + "] ";
}

}  // namespace

Status validate_blobs(std::span<const BlobBytes> blobs, const Grid& grid) {
  const BlobBytes* by_id[64] = {};
  for (const auto& b : blobs) {
    const BlobInfo* info = find_blob_info(b.id);
    if (!info) continue;
    if (info->stride == 0 || b.bytes.size() / info->stride != b.count || b.bytes.size() % info->stride != 0)
      return Status::failure("render: invalid package: blob " + std::string(info->name) + " holds " +
                             std::to_string(b.bytes.size()) + " bytes for " + std::to_string(b.count) +
                             " elements of " + std::to_string(info->stride));
    auto idx = static_cast<uint32_t>(b.id);
    if (idx >= 64) continue;
    if (by_id[idx]) return Status::failure("render: invalid package: blob " + std::string(info->name) + " appears twice");
    by_id[idx] = &b;
  }
  auto get = [&]<class T>(BlobId id, Arr<T>& a) {
    const BlobBytes* b = by_id[static_cast<uint32_t>(id)];
    a = b ? Arr<T>{b->bytes.data(), b->count} : Arr<T>{};
  };

  if (grid.nx == 0 || grid.ny == 0 || grid.cell_w <= 0 || grid.cell_h <= 0)
    return Status::failure("render: invalid package: grid " + std::to_string(grid.nx) + "x" + std::to_string(grid.ny) +
                           " with cell " + std::to_string(grid.cell_w) + "x" + std::to_string(grid.cell_h));
  const uint64_t cells = uint64_t(grid.nx) * grid.ny;
  // The shaders compute cell coordinates in int32 quanta.
  const int64_t lim = int64_t(1) << 31;
  if (grid.origin_x <= -lim || grid.origin_x >= lim || grid.origin_y <= -lim || grid.origin_y >= lim ||
      grid.origin_x + grid.cell_w * int64_t(grid.nx) >= lim || grid.origin_y + grid.cell_h * int64_t(grid.ny) >= lim)
    return Status::failure("render: invalid package: grid exceeds the int32 quantum range");

  Arr<I2> lv; Arr<uint32_t> lvl; Arr<LineProps> lp; Arr<LineCorner> lc; Arr<U2> csr, cs;
  get(BlobId::line_vertices, lv); get(BlobId::line_vertex_line, lvl); get(BlobId::line_props, lp);
  get(BlobId::line_corners, lc); get(BlobId::cell_segment_range, csr); get(BlobId::cell_segments, cs);
  Arr<PolyProps> pp; Arr<uint32_t> prn; Arr<I4> qb; Arr<I2> qn; Arr<U2> qlr, qls; Arr<I2> qlv;
  Arr<U2> cpr; Arr<U4> cp; Arr<U2> ch;
  get(BlobId::poly_props, pp); get(BlobId::poly_root_node, prn); get(BlobId::qt_node_box, qb);
  get(BlobId::qt_node, qn); get(BlobId::qt_leaf_range, qlr); get(BlobId::qt_leaf_segments, qls);
  get(BlobId::qt_leaf_vertices, qlv); get(BlobId::cell_poly_range, cpr); get(BlobId::cell_polys, cp);
  get(BlobId::cell_holes, ch);
  Arr<U4> lbr, pbr; Arr<I4> lbb, pbb;
  get(BlobId::line_bvh_range, lbr); get(BlobId::line_bvh_box, lbb);
  get(BlobId::poly_bvh_range, pbr); get(BlobId::poly_bvh_box, pbb);
  Arr<I4> dv; Arr<I2> dpn; Arr<uint32_t> dls; Arr<LineProps> dlp;
  get(BlobId::dyn_vertices, dv); get(BlobId::dyn_prev_next, dpn); get(BlobId::dyn_line_start, dls);
  get(BlobId::dyn_line_props, dlp);

  // --- static lines ---
  if (lvl.n != lv.n) return Status::failure(where("line_vertex_line", lvl.n) + "count differs from line_vertices " + std::to_string(lv.n));
  if (lc.n != lv.n) return Status::failure(where("line_corners", lc.n) + "count differs from line_vertices " + std::to_string(lv.n));
  for (uint64_t i = 0; i < lvl.n; ++i)
    if (lvl[i] >= lp.n) return Status::failure(where("line_vertex_line", i) + "line " + std::to_string(lvl[i]) + " >= " + std::to_string(lp.n));
  for (uint64_t i = 0; i < lp.n; ++i) {
    LineProps p = lp[i];
    if (!(p.half_width >= 0.0f && p.half_width < 1e7f)) return Status::failure(where("line_props", i) + "half_width " + std::to_string(p.half_width));
    // A clipped outline's ring query starts at clip_node (static_lines.glsl).
    if ((p.style & kStyleClipBit) && p.clip_node >= qn.n)
      return Status::failure(where("line_props", i) + "clip_node " + std::to_string(p.clip_node) + " >= " + std::to_string(qn.n));
  }
  for (uint64_t i = 0; i < cs.n; ++i) {
    U2 s = cs[i];
    if (s[0] >= lv.n || s[1] >= lv.n) return Status::failure(where("cell_segments", i) + "vertex " + std::to_string(std::max(s[0], s[1])) + " >= " + std::to_string(lv.n));
  }
  // --- static polygons ---
  if (qb.n != qn.n) return Status::failure(where("qt_node_box", qb.n) + "count differs from qt_node " + std::to_string(qn.n));
  for (uint64_t i = 0; i < pp.n; ++i) {
    int32_t e = pp[i].exterior;
    if (e < -1 || (e >= 0 && uint64_t(e) >= pp.n)) return Status::failure(where("poly_props", i) + "exterior " + std::to_string(e));
  }
  for (uint64_t i = 0; i < prn.n; ++i)
    if (prn[i] >= qn.n) return Status::failure(where("poly_root_node", i) + "node " + std::to_string(prn[i]) + " >= " + std::to_string(qn.n));
  for (uint64_t i = 0; i < qn.n; ++i) {
    I2 n = qn[i];
    if (n[0] < 0 || n[0] > 3) return Status::failure(where("qt_node", i) + "type " + std::to_string(n[0]));
    // Children after their parent keeps every descent finite.
    if (n[0] == 0 && (n[1] <= int64_t(i) || uint64_t(n[1]) + 4 > qn.n))
      return Status::failure(where("qt_node", i) + "children at " + std::to_string(n[1]) + " of " + std::to_string(qn.n));
    if (n[0] == 3 && (n[1] < 0 || uint64_t(n[1]) >= qlr.n))
      return Status::failure(where("qt_node", i) + "leaf range " + std::to_string(n[1]) + " >= " + std::to_string(qlr.n));
  }
  for (uint64_t i = 0; i < qlr.n; ++i) {
    U2 r = qlr[i];
    if (uint64_t(r[0]) + r[1] > qls.n) return Status::failure(where("qt_leaf_range", i) + "(" + std::to_string(r[0]) + ", " + std::to_string(r[1]) + ") beyond " + std::to_string(qls.n));
  }
  for (uint64_t i = 0; i < qls.n; ++i) {
    U2 s = qls[i];
    if (s[0] >= qlv.n || s[1] >= qlv.n) return Status::failure(where("qt_leaf_segments", i) + "vertex " + std::to_string(std::max(s[0], s[1])) + " >= " + std::to_string(qlv.n));
  }
  for (uint64_t i = 0; i < cp.n; ++i) {
    U4 e = cp[i];
    if (e[0] >= pp.n) return Status::failure(where("cell_polys", i) + "polygon " + std::to_string(e[0]) + " >= " + std::to_string(pp.n));
    if (e[1] >= qn.n) return Status::failure(where("cell_polys", i) + "node " + std::to_string(e[1]) + " >= " + std::to_string(qn.n));
    if (uint64_t(e[2]) + e[3] > ch.n) return Status::failure(where("cell_polys", i) + "holes (" + std::to_string(e[2]) + ", " + std::to_string(e[3]) + ") beyond " + std::to_string(ch.n));
  }
  for (uint64_t i = 0; i < ch.n; ++i) {
    U2 h = ch[i];
    if (h[0] >= pp.n) return Status::failure(where("cell_holes", i) + "polygon " + std::to_string(h[0]) + " >= " + std::to_string(pp.n));
    if (h[1] >= qn.n) return Status::failure(where("cell_holes", i) + "node " + std::to_string(h[1]) + " >= " + std::to_string(qn.n));
  }
  // --- per-cell ranges and BVHs ---
  auto check_cells = [&](std::string_view name, const Arr<U2>& range, uint64_t list_n, const Arr<U4>& bvh,
                         std::string_view bvh_name, uint64_t box_n) -> Status {
    if (range.n == 0 && list_n == 0 && bvh.n == 0) return Status::success();
    if (range.n != cells) return Status::failure(where(name, range.n) + "count differs from the " + std::to_string(cells) + " grid cells");
    if (bvh.n != cells) return Status::failure(where(bvh_name, bvh.n) + "count differs from the " + std::to_string(cells) + " grid cells");
    for (uint64_t c = 0; c < cells; ++c) {
      U2 r = range[c];
      if (uint64_t(r[0]) + r[1] > list_n) return Status::failure(where(name, c) + "(" + std::to_string(r[0]) + ", " + std::to_string(r[1]) + ") beyond " + std::to_string(list_n));
      U4 b = bvh[c];
      // (first node, leaf slots, internal nodes): a full binary tree whose
      // leaf k is the cell's k-th list entry (thesis §4.2.1, Eq. 4.5–4.7).
      uint64_t leaves = b[1], internal = b[2];
      if (leaves < r[1] || (leaves > 0 && internal + 1 != leaves) || (leaves & (leaves - 1)) != 0 ||
          uint64_t(b[0]) + leaves + internal > box_n)
        return Status::failure(where(bvh_name, c) + "(" + std::to_string(b[0]) + ", " + std::to_string(b[1]) + ", " +
                               std::to_string(b[2]) + ") does not fit " + std::to_string(r[1]) + " entries / " +
                               std::to_string(box_n) + " boxes");
    }
    return Status::success();
  };
  if (Status s = check_cells("cell_segment_range", csr, cs.n, lbr, "line_bvh_range", lbb.n); !s) return s;
  if (Status s = check_cells("cell_poly_range", cpr, cp.n, pbr, "poly_bvh_range", pbb.n); !s) return s;
  // --- dynamic lines ---
  if (dpn.n != dv.n) return Status::failure(where("dyn_prev_next", dpn.n) + "count differs from dyn_vertices " + std::to_string(dv.n));
  for (uint64_t i = 0; i < dv.n; ++i) {
    I4 v = dv[i];
    if (v[3] < 0 || uint64_t(v[3]) >= dlp.n) return Status::failure(where("dyn_vertices", i) + "line " + std::to_string(v[3]) + " >= " + std::to_string(dlp.n));
    I2 pn = dpn[i];
    if (pn[0] < -1 || pn[1] < -1 || (pn[0] >= 0 && uint64_t(pn[0]) >= dv.n) || (pn[1] >= 0 && uint64_t(pn[1]) >= dv.n))
      return Status::failure(where("dyn_prev_next", i) + "(" + std::to_string(pn[0]) + ", " + std::to_string(pn[1]) + ") outside " + std::to_string(dv.n));
  }
  for (uint64_t i = 0; i < dls.n; ++i)
    if (dls[i] >= dv.n) return Status::failure(where("dyn_line_start", i) + "vertex " + std::to_string(dls[i]) + " >= " + std::to_string(dv.n));
  // The dynamic update walks lines as consecutive vertex runs: line l owns
  // [start[l], start[l+1]), starts increase from 0, and every vertex names
  // the run it lies in.
  if (dv.n > 0 && (dls.n == 0 || dls[0] != 0))
    return Status::failure(where("dyn_line_start", 0) + "must be 0 when dynamic vertices exist");
  for (uint64_t l = 0; l < dls.n; ++l) {
    const uint64_t end = l + 1 < dls.n ? dls[l + 1] : dv.n;
    if (end <= dls[l]) return Status::failure(where("dyn_line_start", l + 1) + "does not increase");
    for (uint64_t v = dls[l]; v < end; ++v)
      if (uint64_t(dv[v][3]) != l)
        return Status::failure(where("dyn_vertices", v) + "line " + std::to_string(dv[v][3]) + " lies in the run of line " + std::to_string(l));
  }
  if (dls.n != dlp.n && dv.n > 0)
    return Status::failure(where("dyn_line_start", dls.n) + "count differs from dyn_line_props " + std::to_string(dlp.n));
  return Status::success();
}

}  // namespace decal::gl
