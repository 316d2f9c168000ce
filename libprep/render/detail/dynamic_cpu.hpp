// The dynamic lines of one source as the GL pass draws them for one view
// (thesis §4.3, §4.4.2), computed on the CPU in double precision from the
// same rules as its shaders: the vertices kept (dyn_cull.comp.glsl: a vertex
// that lands on its predecessor's pixel is dropped, line starts and ends
// never), the segments between kept vertices with their kept neighbours and
// frustum culling (dyn_segments.comp.glsl), the per-pixel test at the
// pixel's ground point and scale per corner style (dyn_lists.frag.glsl,
// dyn_scale.glsl), and every covering line composited front to back in
// drawing order (dyn_composite.frag.glsl). Internal to prep_render.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "detail/math.hpp"
#include "prep/render.hpp"

namespace prep::render::detail {

// LOD of the dynamic lines (RenderOptions::lod, lod_view): on, the
// tolerance, and the terrain's height range.
struct DynamicLod {
  bool on = false;
  double tolerance_px = 0.5, zmin = 0, zmax = 0;
};

class DynamicLinesCpu {
 public:
  // `camera` in the source's frame (metres relative to its origin). With
  // `lod.on`, the lines that have LOD segments are drawn from those
  // decal::visible_segments selects for lod_view (the GL pass's lod_*.comp.glsl),
  // with the same neighbours and frustum test as the other segments.
  DynamicLinesCpu(const DecalSource& source, const Camera& camera, uint32_t width, uint32_t height,
                  const DynamicLod& lod = {});

  bool empty() const { return segments_.empty(); }
  // LOD counts as in Image (lod_lines, lod_selected, lod_drawn, lod_full).
  std::array<uint64_t, 4> lod_counts() const { return lod_counts_; }
  // Straight-alpha colour of the dynamic layer where a pixel's ray meets the
  // terrain at `p` (metres relative to the source's origin).
  std::array<float, 4> at(const Vec3& p) const;

 private:
  struct Segment {
    std::array<double, 2> a, b, prev, next;  // plan positions, metres
    bool has_prev = false, has_next = false;
    uint32_t line = 0;
    // Dashes: the ends in 3D (metres) and the line's screen length from its
    // start to a, pixels (dyn_dash.comp.glsl).
    std::array<double, 3> a3{}, b3{};
    double s0 = 0;
  };
  // Along-line screen distance of plan point p on segment s, pixels
  // (dyn_lists.frag.glsl dash_s).
  double dash_s(const Segment& s, const std::array<double, 2>& p) const;
  bool dash_own_side(const Segment& s, const std::array<double, 2>& p) const;
  std::array<double, 4> clip_of(const std::array<double, 3>& x) const;
  double screen_length(std::array<double, 4> ca, std::array<double, 4> cb) const;
  bool covers(const Segment& s, const std::array<double, 2>& p, double hw, uint32_t corner) const;
  double metres_per_pixel(const Vec3& p) const;

  // LOD lines' segments (DynamicLod::on): appended to segments_.
  void add_lod_segments(const DecalSource& source, const DynamicLod& lod, const Camera& camera,
                        uint32_t height, const std::vector<std::array<int32_t, 4>>& verts,
                        const std::vector<uint32_t>& codes, std::vector<char>& keep);

  std::vector<Segment> segments_;
  std::array<uint64_t, 4> lod_counts_{};
  std::vector<decal::LineProps> props_;
  // Half of each layer's min_width_m (DecalSource::min_width_m), metres;
  // empty: none; and the largest.
  std::vector<double> min_hw_m_;
  double max_min_hw_m_ = 0;
  std::shared_ptr<const LineDashes> dashes_;  // null: every line solid
  Mat4 vp_{};
  double near_w_ = 0, width_ = 0, height_ = 0;
  Vec3 eye_{};
  double mpp_ortho_ = 0, mpp_per_metre_ = 0, cos_limit_ = 0, reach_ = 1, max_hw_px_ = 0;
  // A uniform grid over the segments' plan boxes.
  double gx0_ = 0, gy0_ = 0, cell_ = 1;
  int64_t gnx_ = 0, gny_ = 0;
  std::vector<uint32_t> cell_start_, cell_items_;
};

}  // namespace prep::render::detail
