// dyn_lists.frag.glsl — thesis §4.3.2 "Linked Lists": for each fragment of a
// segment box, back-project the pixel with the terrain depth, test the pixel
// against the line segment at the pixel's own scale (Eq. 4.1/4.2) per corner
// style, and push (order, line) onto the pixel's list with an atomic counter
// and an atomic head exchange, with the pixel's coverage of the line (1
// when aliased; a dashed line's pixels in an "off" interval are left out).
// Nodes beyond the capacity are only counted;
// the host grows the buffer and repeats the pass.
flat in uvec4 g_seg;
layout(binding = DECAL_UNIT_DEPTH) uniform sampler2D u_depth;
uniform mat4 u_inv_view_proj;
uniform vec4 u_clip;  // decals only in [x, z) x [y, w), anchor-relative metres (a tileset's tile)
uniform float u_miter_limit_cos;  // cos of the package's miter limit (build_options.miter_limit_deg)

float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }
bool in_triangle(vec2 p, vec2 a, vec2 b, vec2 c) {
  float d1 = cross2(b - a, p - a), d2 = cross2(c - b, p - b), d3 = cross2(a - c, p - c);
  return !((d1 < 0.0 || d2 < 0.0 || d3 < 0.0) && (d1 > 0.0 || d2 > 0.0 || d3 > 0.0));
}
vec2 left_normal(vec2 from, vec2 to) {
  vec2 d = to - from;
  float l = length(d);
  return l > 0.0 ? vec2(-d.y, d.x) / l : vec2(0.0);
}
// Corner at vertex v between segment (u -> v) and (v -> w): the miter vector
// (to the left), or zero for a round fallback below the package's miter
// limit (thesis §4.2.1; formats/SPEC.md, blob line_corners).
vec2 miter_at(vec2 u, vec2 v, vec2 w, float hw) {
  vec2 e1 = normalize(u - v), e2 = normalize(w - v);
  if (dot(e1, e2) > u_miter_limit_cos) return vec2(0.0);
  vec2 n1 = left_normal(u, v), n2 = left_normal(v, w);
  vec2 m = n1 + n2;
  if (dot(m, m) < 1e-12) return n2 * hw;
  m = normalize(m);
  return m * (hw / dot(m, n2));
}

bool covers(vec2 p, float hw, uint corner) {
  vec2 a = dyn_position(g_seg.x).xy, b = dyn_position(g_seg.y).xy;
  vec2 d = b - a;
  float len2 = dot(d, d);
  if (corner == 0u || len2 == 0.0) {
    float t = len2 > 0.0 ? clamp(dot(p - a, d) / len2, 0.0, 1.0) : 0.0;
    vec2 q = a + t * d - p;
    return dot(q, q) <= hw * hw;
  }
  vec2 n = vec2(-d.y, d.x) * (hw / sqrt(len2));
  bool has_prev = g_seg.z != NONE, has_next = g_seg.w != NONE;
  vec2 pp = has_prev ? dyn_position(g_seg.z).xy : a, nn = has_next ? dyn_position(g_seg.w).xy : b;
  if (corner == 1u) {
    vec2 ma = has_prev ? miter_at(pp, a, b, hw) : vec2(0.0);
    vec2 mb = has_next ? miter_at(a, b, nn, hw) : vec2(0.0);
    bool ra = ma == vec2(0.0), rb = mb == vec2(0.0);
    vec2 qa = ra ? n : ma, qb = rb ? n : mb;
    if (in_triangle(p, a + qa, a - qa, b - qb) || in_triangle(p, a + qa, b - qb, b + qb)) return true;
    if (ra && dot(p - a, p - a) <= hw * hw) return true;
    if (rb && dot(p - b, p - b) <= hw * hw) return true;
    return false;
  }
  // bevel: rectangle, then the corner triangles on the outer side of each turn
  float t = dot(p - a, d) / len2;
  float side = cross2(d, p - a);
  if (t >= 0.0 && t <= 1.0 && side * side <= hw * hw * len2) return true;
  if (has_prev) {
    vec2 n1 = left_normal(pp, a) * hw, n2 = n;
    float turn = cross2(a - pp, d);
    vec2 s = turn > 0.0 ? -vec2(1.0) : vec2(1.0);
    if (in_triangle(p, a, a + s * n1, a + s * n2)) return true;
  } else if (dot(p - a, p - a) <= hw * hw) return true;
  if (has_next) {
    vec2 n1 = n, n2 = left_normal(b, nn) * hw;
    float turn = cross2(d, nn - b);
    vec2 s = turn > 0.0 ? -vec2(1.0) : vec2(1.0);
    if (in_triangle(p, b, b + s * n1, b + s * n2)) return true;
  } else if (dot(p - b, p - b) <= hw * hw) return true;
  return false;
}

// Dashes (formats/SPEC.md "Dashed lines"): the pixel's along-line screen
// distance on this segment, the start vertex's (dyn_dash.comp.glsl) plus
// the screen length from it to the point of the segment nearest p in plan
// (clamped: a corner's join region takes the vertex's own distance).
float dash_s(vec2 p) {
  vec3 a = dyn_position(g_seg.x), b = dyn_position(g_seg.y);
  vec2 ab = b.xy - a.xy;
  float len2 = dot(ab, ab);
  float t = len2 > 0.0 ? clamp(dot(p - a.xy, ab) / len2, 0.0, 1.0) : 0.0;
  vec4 ca = u_view_proj * vec4(a, 1.0), cq = u_view_proj * vec4(mix(a, b, t), 1.0);
  return dyn_dash[dash_vertex_at(g_seg.x)] + screen_length(ca, cq);
}

// A dashed line's pixel takes its distance from the segment on whose side
// of each corner's bisector it lies (where the segment boxes meet), so the
// neighbouring segments' dashes do not overlap inside a corner.
bool dash_own_side(vec2 p) {
  vec2 a = dyn_position(g_seg.x).xy, b = dyn_position(g_seg.y).xy;
  vec2 d = b - a;
  d = dot(d, d) > 0.0 ? normalize(d) : vec2(1.0, 0.0);
  if (g_seg.z != NONE) {
    vec2 dp = a - dyn_position(g_seg.z).xy;
    vec2 t = dot(dp, dp) > 0.0 ? normalize(dp) + d : d;
    if (dot(t, t) < 1e-12) t = d;
    if (dot(p - a, t) < 0.0) return false;
  }
  if (g_seg.w != NONE) {
    vec2 dn = dyn_position(g_seg.w).xy - b;
    vec2 t = dot(dn, dn) > 0.0 ? normalize(dn) + d : d;
    if (dot(t, t) < 1e-12) t = d;
    if (dot(p - b, t) > 0.0) return false;
  }
  return true;
}

void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  float depth = texelFetch(u_depth, px, 0).r;
  if (depth <= 0.0) discard;
  vec4 w = u_inv_view_proj * vec4(gl_FragCoord.xy / u_viewport * 2.0 - 1.0, depth, 1.0);
  vec3 p = w.xyz / w.w;
  if (p.x < u_clip.x || p.y < u_clip.y || p.x >= u_clip.z || p.y >= u_clip.w) discard;
  uint line = uint(dyn_vertex(g_seg.x).w);
  uvec4 props = dyn_line_props(line);
  float wpix = metres_per_pixel(p);
  float hw = max(uintBitsToFloat(props.x) * wpix, dyn_min_half_width(line));
#ifdef DECAL_AA_COVERAGE
  // Coverage AA (Thöny et al. §3.5): band coverage over the distance to the
  // segment, width at least one pixel; the exact style test keeps corners.
  bool inside = covers(p.xy, hw, props.w & 3u);
  vec2 a = dyn_position(g_seg.x).xy, b = dyn_position(g_seg.y).xy, ab = b - a;
  float t = clamp(dot(p.xy - a, ab) / max(dot(ab, ab), 1e-20), 0.0, 1.0);
  float dist = length(a + t * ab - p.xy);
  float wl = max(2.0 * hw, wpix);
  float cov = clamp((min(0.5 * wpix - dist, 0.5 * wl) + min(0.5 * wpix + dist, 0.5 * wl)) / wpix, 0.0, 1.0);
  if (inside) cov = max(cov, 0.5);
  uint layer = dyn_line_layer(line);
  if (!dash_solid(layer)) {  // the pixel's share of the dash along the line
    if (!dash_own_side(p.xy)) discard;
    bool on;
    cov *= clamp(0.5 + dash_signed(layer, dash_s(p.xy), on), 0.0, 1.0);
  }
  if (cov <= 0.0) discard;
#else
  if (!covers(p.xy, hw, props.w & 3u)) discard;
  uint layer = dyn_line_layer(line);
  if (!dash_solid(layer)) {
    if (!dash_own_side(p.xy)) discard;
    bool on;
    dash_signed(layer, dash_s(p.xy), on);
    if (!on) discard;
  }
  float cov = 1.0;
#endif
  uint node = atomicAdd(list_nodes, 1u);
  if (node < list_capacity) {
    uint pixel = uint(px.y) * uint(u_viewport.x) + uint(px.x);
    uint next = atomicExchange(dyn_head[pixel], node);
    dyn_node[node] = uvec4(props.z, line, next, floatBitsToUint(cov));
  }
}
