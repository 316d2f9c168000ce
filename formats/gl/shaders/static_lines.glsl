// static_lines.glsl — fragment shader of the static line pass (thesis
// Algorithm 3.5, §3.6 corner styles and outline modes, §4.4.1 "Static
// Lines"), with decal_blobs.glsl (DECAL_LINES) and static_common.glsl.
// Mirrors prep::evaluate(): grid cell -> stack-less BVH over the cell's
// segments in drawing order -> point-in-line test per corner style ->
// outline side test (clipped outlines: their ring's quad-tree) -> dash
// test (dash.glsl) ->
// front-to-back compositing, skipping further segments of a line that
// already covered the pixel (or was clipped away); early exit when opaque.
// One pass draws the lines of ranks [u_order_lo, u_order_hi), one run of the
// drawing order (formats/SPEC.md "Drawing order"; prep::draw_runs); leaves
// are in rank order, so the walk stops at the first rank past the run.
// Output: premultiplied colour, blended under what the passes of earlier
// (higher) runs drew.

layout(location = 0) out vec4 o_color;
#ifdef DECAL_UNLIT_LAYERS
layout(location = 1) out vec4 o_unlit;  // the unlit layers' share (static_common.glsl g_unlit)
#endif
uniform uint u_order_lo;
uniform uint u_order_hi;

float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }

// T(A, B, C, d) of the evaluator: all three edge values >= 0 or all <= 0.
bool in_triangle(vec2 a, vec2 b, vec2 c, vec2 d) {
  float c0 = cross2(b - a, d - a), c1 = cross2(c - b, d - b), c2 = cross2(a - c, d - c);
  return (c0 >= 0.0 && c1 >= 0.0 && c2 >= 0.0) || (c0 <= 0.0 && c1 <= 0.0 && c2 <= 0.0);
}
bool is_null(vec2 v) { return v == vec2(0.0); }

// Minimum widths (formats/SPEC.md "Minimum widths"; prep::min_width_scale):
// a line of a layer with min_width_px N is drawn with its half width and
// corner vectors times g_k = max(1, f N min(pixel, limit) / hw), f = 1/2
// (1 for inset and offset), at the pixel's ground size g_px; the package's
// cells hold its segments as far as the limit lets it reach.
float g_k = 1.0;
#ifdef DECAL_MIN_WIDTHS
layout(binding = DECAL_UNIT_MIN_WIDTHS) uniform samplerBuffer u_min_widths;  // N per layer
uniform float u_min_width_pixel_m;
uniform float u_min_width_reach;  // prep::render::min_width_reach: BVH boxes grown by it x min(px, limit)
float g_px = 0.0;
float width_scale(uint line, uvec4 props) {
  int last = textureSize(u_min_widths) - 1;
  float n = texelFetch(u_min_widths, int(min(line_layer(line), uint(last)))).x;
  if (!(n > 0.0)) return 1.0;
  float f = ((props.w >> 2) & 3u) == 0u ? 0.5 : 1.0;
  float want = n * f * min(g_px, u_min_width_pixel_m);
  float hw = uintBitsToFloat(props.x);
  return want > hw && hw > 0.0 ? want / hw : 1.0;
}
#else
float width_scale(uint line, uvec4 props) { return 1.0; }
#endif
vec2 cmiter(uint i) { return g_k * corner_miter(i); }
vec2 cbevel_in(uint i) { return g_k * corner_bevel_in(i); }
vec2 cbevel_out(uint i) { return g_k * corner_bevel_out(i); }

// Outcomes of the segment test (SegmentHit in the evaluator).
const int HIT_NONE = 0, HIT_CLIPPED = 1, HIT_COVERED = 2;

// props = (half_width bits, rgba, order, style) of `line`. Step 6 of the
// query block in libprep/evaluate/evaluate.cpp, in metres relative to vertex
// a: the segment vector e is an exact integer difference.
int segment_test(uint s, uint eidx, vec2 p, uint line, uvec4 props) {
  float hw = uintBitsToFloat(props.x) * g_k, hw2 = hw * hw;
  uint corner = props.w & 3u;
  uint outline = (props.w >> 2) & 3u;
  ivec2 ai = line_vertex(s);
  vec2 e = vec2(line_vertex(eidx) - ai) * QUANTUM;
  vec2 d = p - rel(ai);
  bool covered = false;
#ifdef DECAL_SLOPE_WIDTHS
  // Step 6b (slope_widths.glsl): the band measured along the terrain
  // replaces the plan band below.
  if (slope_applies(line)) covered = surface_band_covers(e, d, hw, corner, s, eidx); else
#endif
  if (corner == 0u) {  // round
    float ee = dot(e, e);
    float t = ee > 0.0 ? clamp(dot(d, e) / ee, 0.0, 1.0) : 0.0;
    vec2 r = d - t * e;
    covered = dot(r, r) <= hw2;
  } else if (corner == 1u) {  // miter; a null miter falls back to the left normal + a disc
    vec2 ma = cmiter(s), mb = cmiter(eidx);
    bool na = is_null(ma), nb = is_null(mb);
    if (na) { ma = cbevel_out(s); if (cross2(e, ma) < 0.0) ma = -ma; }
    if (nb) { mb = cbevel_in(eidx); if (cross2(e, mb) < 0.0) mb = -mb; }
    covered = in_triangle(-ma, e - mb, e + mb, d) || in_triangle(-ma, e + mb, ma, d) ||
              (na && dot(d, d) <= hw2) || (nb && dot(d - e, d - e) <= hw2);
  } else {  // bevel: rectangle, then the corner triangles (null: round end)
    vec2 n = cbevel_out(s);
    float c = cross2(e, n);
    if (c != 0.0) {
      float sv = cross2(e, d) / c, tv = cross2(d, n) / c;
      covered = tv >= 0.0 && tv <= 1.0 && abs(sv) <= 1.0;
    }
    vec2 ai_in = cbevel_in(s), b_out = cbevel_out(eidx);
    if (!covered)
      covered = is_null(ai_in) ? dot(d, d) <= hw2 : in_triangle(vec2(0.0), ai_in, n, d);
    if (!covered)
      covered = is_null(b_out) ? dot(d - e, d - e) <= hw2 : in_triangle(e, e + cbevel_in(eidx), e + b_out, d);
  }
  if (!covered) return HIT_NONE;
  if (outline == 0u) return HIT_COVERED;
  // Clipped outline (style bit 5): the two-sided band cut by the line's own
  // ring, whose quad-tree root is clip_node; bit 6 says which side is kept.
  if ((props.w & 32u) != 0u) {
    bool inside = qt_contains(line_clip_node(line), p);
    return inside == ((props.w & 64u) != 0u) ? HIT_COVERED : HIT_CLIPPED;
  }
  // Other outlines (thesis §3.6, width doubled at build time): inset keeps the
  // left half (K = +1), offset the right half (K = -1); at a corner turning
  // towards the kept side the kept part is the intersection of both halves.
  float K = outline == 1u ? 1.0 : -1.0;
  if (K * cross2(e, d) < 0.0) return HIT_NONE;
  vec2 cb_out = cbevel_out(eidx);
  if (!is_null(cb_out)) {
    float o = cross2(e, cbevel_in(eidx)) >= 0.0 ? 1.0 : -1.0;
    if (K * o < 0.0 && K * dot(d - e, o * cb_out) < 0.0) return HIT_NONE;
  }
  vec2 ca_in = cbevel_in(s);
  if (!is_null(ca_in)) {
    float o = cross2(e, cbevel_out(s)) >= 0.0 ? 1.0 : -1.0;
    if (K * o < 0.0 && K * dot(d, o * ca_in) < 0.0) return HIT_NONE;
  }
  return HIT_COVERED;
}

// Step 6c of the query block (dashes, dash.glsl): the along-line distance
// of p on segment (s, eidx): the start vertex's distance plus the clamped
// projection, so a corner's join region takes the vertex's own distance.
float dash_s(uint s, uint eidx, vec2 p) {
  ivec2 ai = line_vertex(s);
  vec2 e = vec2(line_vertex(eidx) - ai) * QUANTUM;
  vec2 d = p - rel(ai);
  float ee = dot(e, e);
  float t = ee > 0.0 ? clamp(dot(d, e) / ee, 0.0, 1.0) : 0.0;
  return d_dash_vertex[s] + t * sqrt(ee);
}
bool dash_covers(uint s, uint eidx, vec2 p, uint line) {
  uint layer = line_layer(line);
  if (dash_solid(layer)) return true;
  bool on;
  dash_signed(layer, dash_s(s, eidx, p), on);
  return on;
}

#ifdef DECAL_AA_COVERAGE
// Coverage AA (Thöny et al. §3.5): the band formula over the distance to
// the segment's centre line, with the width raised to at least one pixel.
// Inset/offset lines cover the band [0, hw] on the kept side (their stored
// half width is the doubled one). Pixels the exact style test puts inside
// keep at least half coverage (miter tips, bevel corners). A clipped outline
// gives no coverage to a pixel on the kept side of this segment that its
// ring test drops (the band reaching past another edge of a narrow ring);
// that edge's own segment shades the pixels beside it.
float segment_coverage(uint s, uint eidx, vec2 p, uint line, uvec4 props, float wpix) {
  int hit = segment_test(s, eidx, p, line, props);
  bool inside = hit == HIT_COVERED;
  float hw = uintBitsToFloat(props.x) * g_k;
  uint outline = (props.w >> 2) & 3u;
  ivec2 ai = line_vertex(s);
  vec2 e = vec2(line_vertex(eidx) - ai) * QUANTUM;
  vec2 d = p - rel(ai);
#ifdef DECAL_SLOPE_WIDTHS
  if (slope_applies(line)) hw *= slope_side_scale(e);  // the band's sides on the ground
#endif
  float ee = max(dot(e, e), 1e-20);
  float t = dot(d, e) / ee;
  float c;
  if (outline == 0u) {
    float dist = length(d - clamp(t, 0.0, 1.0) * e);
    c = band_coverage(dist, max(2.0 * hw, wpix), wpix);
  } else {
    if (!inside && (t < 0.0 || t > 1.0)) return 0.0;
    float K = outline == 1u ? 1.0 : -1.0;
    float sd = K * cross2(e, d) / sqrt(ee);  // > 0 on the kept side
    if ((props.w & 32u) != 0u && !inside && sd >= 0.0 &&
        (hit == HIT_CLIPPED || qt_contains(line_clip_node(line), p) != ((props.w & 64u) != 0u)))
      return 0.0;
    float w = max(hw, wpix);
    c = band_coverage(abs(sd - 0.5 * hw), w, wpix);
  }
  c = inside ? max(c, 0.5) : c;
  // Dashes: the pixel's share of the dash along the line (a box of one
  // pixel across the nearest on/off boundary).
  uint layer = line_layer(line);
  if (!dash_solid(layer)) {
    bool on;
    float sd = dash_signed(layer, dash_s(s, eidx, p), on);
    c *= clamp(0.5 + sd / wpix, 0.0, 1.0);
  }
  return c;
}
#endif

// The last line decided (aliased).
uint g_last_line = 0xffffffffu;
#ifdef DECAL_AA_COVERAGE
// One coverage per line: the largest over its (consecutive) segments.
uint g_cur_line = 0xffffffffu, g_cur_rgba = 0u;
float g_cur_cov = 0.0;
bool g_done = false;  // composited to opaque: g_cur_cov is not added
#endif

ivec4 bvh_box(uint node, ivec3 base) { return line_bvh_box(node, base); }

// Leaf of the walk (static_common.glsl bvh_walk): segment entry `entry` of
// the cell; false ends the walk (past the run, or opaque).
bool bvh_leaf(uint entry, vec2 p) {
  uvec2 seg = cell_segment(entry);
  uint line = line_of_vertex(seg.x);
  uvec4 props = line_props(line);
  if (props.z >= u_order_hi) return false;
  if (props.z < u_order_lo) return true;
  g_k = width_scale(line, props);
#ifdef DECAL_AA_COVERAGE
  float cov = segment_coverage(seg.x, seg.y, p, line, props, g_wpix);
  if (line == g_cur_line) {
    g_cur_cov = max(g_cur_cov, cov);
  } else {
    if (g_cur_cov > 0.0) {
      if (under_opaque_cov(g_cur_rgba, g_cur_cov, line_layer(g_cur_line))) { g_done = true; return false; }
    }
    g_cur_line = line;
    g_cur_rgba = props.y;
    g_cur_cov = cov;
  }
#else
  // Segments of one line are consecutive: a line adds its colour once
  // (thesis Fig. 4.7); a clipped-away line is decided as well.
  if (line != g_last_line) {
    int hit = segment_test(seg.x, seg.y, p, line, props);
    if (hit == HIT_COVERED && !dash_covers(seg.x, seg.y, p, line)) hit = HIT_NONE;
    if (hit != HIT_NONE) g_last_line = line;
    if (hit == HIT_COVERED && under_opaque(props.y, line_layer(line))) return false;
  }
#endif
  return true;
}

void main() {
#ifdef DECAL_SLOPE_WIDTHS
  slope_begin();
#endif
  vec3 p;
  int cell;
  if (!pixel_cell(p, cell)) discard;
#ifdef DECAL_MIN_WIDTHS
  g_px = pixel_metres(p);
#endif
#ifdef DECAL_AA_COVERAGE
  float margin = g_wpix;
#else
  float margin = 0.0;
#endif
#ifdef DECAL_MIN_WIDTHS
  margin += u_min_width_reach * min(g_px, u_min_width_pixel_m);
#endif
  bvh_walk(cell_segment_range(uint(cell)), line_bvh_range(uint(cell)), cell_box_base(cell), p.xy,
           margin);
#ifdef DECAL_AA_COVERAGE
  if (!g_done && g_cur_cov > 0.0)
    composite_under_cov(g_acc, g_cur_rgba, g_cur_cov, line_layer(g_cur_line));
#endif
  if (g_acc.a <= 0.0) discard;
  o_color = g_acc;
#ifdef DECAL_UNLIT_LAYERS
  o_unlit = vec4(g_unlit, g_acc.a);
#endif
}
