// slope_widths.glsl — static line widths measured along the terrain
// (formats/SPEC.md "Slope widths"): step 6b of the query block in
// libprep/evaluate/evaluate.cpp, mirrored. In the line pass between
// static_common.glsl and static_lines.glsl; everything is inside
// DECAL_SLOPE_WIDTHS (without it the pass measures in plan).
#ifdef DECAL_SLOPE_WIDTHS
// The terrain pass's G-buffer target: (dh/dx, dh/dy) of the terrain
// triangle at the pixel (Heightfield::triangle_gradient, per primitive).
layout(binding = DECAL_UNIT_TERRAIN_GRADIENT) uniform sampler2D u_terrain_gradient;
// Per layer-table index: nonzero when the layer's lines take slope widths;
// an index past the end takes the last flag (prep::SurfaceSlope).
layout(binding = DECAL_UNIT_SLOPE_LAYERS) uniform usamplerBuffer u_slope_layers;

// Defined in static_lines.glsl.
float cross2(vec2 a, vec2 b);
vec2 cmiter(uint i);
vec2 cbevel_in(uint i);
vec2 cbevel_out(uint i);
bool in_triangle(vec2 a, vec2 b, vec2 c, vec2 d);
bool is_null(vec2 v);

vec2 g_slope = vec2(0.0);  // the pixel's gradient g (slope_begin)
void slope_begin() { g_slope = texelFetch(u_terrain_gradient, ivec2(gl_FragCoord.xy), 0).xy; }
// Step 6b applies: a flagged layer where the ground is not level.
bool slope_applies(uint line) {
  if (g_slope == vec2(0.0)) return false;
  int last = textureSize(u_slope_layers) - 1;
  return texelFetch(u_slope_layers, int(min(line_layer(line), uint(last)))).x != 0u;
}
// <u, v>_G = u.v + (g.u)(g.v)
float gdot(vec2 u, vec2 v) { return dot(u, v) + dot(g_slope, u) * dot(g_slope, v); }
// N(w) = hw (w - g (g.w) / gam) / sqrt(w.w - (g.w)^2 / gam)
vec2 slope_normal(vec2 w, float hw) {
  float gam = 1.0 + dot(g_slope, g_slope), gw = dot(g_slope, w);
  return hw / sqrt(dot(w, w) - gw * gw / gam) * (w - gw / gam * g_slope);
}
// M(a, b) = hw^2 (a + b) / (hw^2 + <a, b>_G)
vec2 slope_miter(vec2 a, vec2 b, float hw) { return hw * hw / (hw * hw + gdot(a, b)) * (a + b); }
// O(x, m, mg, w) of step 6b: x (from a miter vertex) in the neighbouring
// segment's ground piece past the plan miter line m, onto this segment's
// side; w the neighbour's left normal, `ahead` for the next segment.
bool slope_overhang(vec2 x, vec2 m, vec2 mg, vec2 w, float hw, bool ahead) {
  vec2 t = ahead ? vec2(w.y, -w.x) : vec2(-w.y, w.x);  // |t| = |w|
  if (cross2(mg, x) * cross2(mg, t) < 0.0 || cross2(m, x) * cross2(m, t) > 0.0) return false;
  float gt = dot(g_slope, t), c = cross2(t, x);
  return c * c * (1.0 + dot(g_slope, g_slope)) <= hw * hw * (dot(t, t) + gt * gt);
}
// Plan offset of the band's sides over hw: sqrt((1 + (g.t)^2) / gam) (coverage AA).
float slope_side_scale(vec2 e) {
  float gt = dot(g_slope, e) / max(length(e), 1e-20);
  return sqrt((1.0 + gt * gt) / (1.0 + dot(g_slope, g_slope)));
}

// The band of segment (s, eidx) measured in G; d and e as in segment_test.
bool surface_band_covers(vec2 e, vec2 d, float hw, uint corner, uint s, uint eidx) {
  float hw2 = hw * hw;
  float ee = dot(e, e);
  vec2 r = d - (ee > 0.0 ? clamp(dot(d, e) / ee, 0.0, 1.0) : 0.0) * e;
  if (corner == 0u) {  // round
    float eg = gdot(e, e);
    float t = eg > 0.0 ? clamp(gdot(d, e) / eg, 0.0, 1.0) : 0.0;
    vec2 rg = d - t * e;
    return gdot(rg, rg) <= hw2;
  }
  // Within hw (bevel) or the longer plan miter of the segment in plan.
  vec2 pa = cmiter(s), pb = cmiter(eidx);
  float reach2 = corner == 1u ? max(hw2, max(dot(pa, pa), dot(pb, pb))) : hw2;
  if (dot(r, r) > reach2) return false;
  vec2 a_in = cbevel_in(s), a_out = cbevel_out(s);
  vec2 b_in = cbevel_in(eidx), b_out = cbevel_out(eidx);
  if (corner == 1u) {  // miter; sa, sb make the stored (outer) bevels left
    bool na = is_null(pa), nb = is_null(pb);
    float sa = cross2(e, a_out) >= 0.0 ? 1.0 : -1.0;
    float sb = cross2(e, b_in) >= 0.0 ? 1.0 : -1.0;
    vec2 ma = na ? slope_normal(sa * a_out, hw)
                 : slope_miter(slope_normal(sa * a_in, hw), slope_normal(sa * a_out, hw), hw);
    vec2 mb = nb ? slope_normal(sb * b_in, hw)
                 : slope_miter(slope_normal(sb * b_in, hw), slope_normal(sb * b_out, hw), hw);
    return in_triangle(-ma, e - mb, e + mb, d) || in_triangle(-ma, e + mb, ma, d) ||
           (na && gdot(d, d) <= hw2) || (nb && gdot(d - e, d - e) <= hw2) ||
           (!na && slope_overhang(d, pa, ma, sa * a_in, hw, false)) ||
           (!nb && slope_overhang(d - e, pb, mb, sb * b_out, hw, true));
  }
  // bevel
  vec2 n = slope_normal(a_out, hw);
  float c = cross2(e, n);
  if (c != 0.0) {
    float sv = cross2(e, d) / c, tv = cross2(d, n) / c;
    if (tv >= 0.0 && tv <= 1.0 && abs(sv) <= 1.0) return true;
  }
  if (is_null(a_in) ? gdot(d, d) <= hw2 : in_triangle(vec2(0.0), slope_normal(a_in, hw), n, d))
    return true;
  return is_null(b_out) ? gdot(d - e, d - e) <= hw2
                        : in_triangle(e, e + slope_normal(b_in, hw), e + slope_normal(b_out, hw), d);
}
#endif  // DECAL_SLOPE_WIDTHS
