// static_lines.glsl — fragment shader of the static line pass (thesis
// Algorithm 3.5, §3.6 corner styles and outline modes, §4.4.1 "Static
// Lines"), with decal_blobs.glsl (DECAL_LINES) and static_common.glsl.
// Mirrors prep::evaluate(): grid cell -> stack-less BVH over the cell's
// segments in drawing order -> point-in-line test per corner style ->
// outline side test -> front-to-back compositing, skipping further segments
// of a line that already covered the pixel; early exit when opaque.
// Output: premultiplied colour, blended over the polygon layer.

layout(location = 0) out vec4 o_color;

float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }

bool in_triangle(vec2 p, vec2 a, vec2 b, vec2 c) {
  float d1 = cross2(b - a, p - a), d2 = cross2(c - b, p - b), d3 = cross2(a - c, p - c);
  bool neg = d1 < 0.0 || d2 < 0.0 || d3 < 0.0;
  bool pos = d1 > 0.0 || d2 > 0.0 || d3 > 0.0;
  return !(neg && pos);
}

float dist2_to_segment(vec2 p, vec2 a, vec2 b) {
  vec2 d = b - a;
  float len2 = dot(d, d);
  float t = len2 > 0.0 ? clamp(dot(p - a, d) / len2, 0.0, 1.0) : 0.0;
  vec2 q = a + t * d - p;
  return dot(q, q);
}

// Corner triangle of the bevel style at vertex v (position pv); a null pair
// of bevel vectors marks a round end.
bool bevel_corner(uint v, vec2 pv, vec2 p, float hw) {
  vec2 bi = corner_bevel_in(v), bo = corner_bevel_out(v);
  if (bi == vec2(0.0) && bo == vec2(0.0)) return dot(p - pv, p - pv) <= hw * hw;
  return in_triangle(p, pv, pv + bi, pv + bo);
}

// props = (half_width bits, rgba, order, style)
bool segment_covers(uint s, uint e, vec2 p, uvec4 props) {
  float hw = uintBitsToFloat(props.x);
  uint corner = props.w & 3u;
  uint outline = (props.w >> 2) & 3u;
  vec2 a = rel(line_vertex(s)), b = rel(line_vertex(e));
  vec2 d = b - a;
  float len2 = dot(d, d);
  float side = cross2(d, p - a);  // > 0: left of the directed segment
  // Outline modes (width doubled at build time): inset keeps the left half,
  // offset the right half (thesis §3.6).
  if (outline == 1u && side < 0.0) return false;
  if (outline == 2u && side > 0.0) return false;
  if (corner == 0u || len2 == 0.0) return dist2_to_segment(p, a, b) <= hw * hw;
  if (corner == 1u) {
    // Miter: the quad spanned by the two miter vectors (two triangles); a
    // null miter is a round end or round fallback: square cut plus a disc.
    vec2 n = vec2(-d.y, d.x) * (hw / sqrt(len2));
    vec2 ma = corner_miter(s), mb = corner_miter(e);
    bool round_a = ma == vec2(0.0), round_b = mb == vec2(0.0);
    vec2 qa = round_a ? n : ma, qb = round_b ? n : mb;
    if (in_triangle(p, a + qa, a - qa, b - qb) || in_triangle(p, a + qa, b - qb, b + qb)) return true;
    if (round_a && dot(p - a, p - a) <= hw * hw) return true;
    if (round_b && dot(p - b, p - b) <= hw * hw) return true;
    return false;
  }
  // Bevel: the segment rectangle, then the two corner triangles.
  float t = dot(p - a, d) / len2;
  if (t >= 0.0 && t <= 1.0 && side * side <= hw * hw * len2) return true;
  return bevel_corner(s, a, p, hw) || bevel_corner(e, b, p, hw);
}

void main() {
  vec3 p;
  if (!pixel_world(p)) discard;
  int cell = cell_of(p.xy);
  if (cell < 0) discard;
  uvec2 range = cell_segment_range(uint(cell));
  uvec4 bvh = line_bvh_range(uint(cell));
  vec4 acc = vec4(0.0);
  uint last_line = 0xffffffffu;
  if (bvh.y > 0u) {
    uint internal = bvh.z;
    uint i = 0u;
    do {
      if (box_contains(line_bvh_box(bvh.x + i), p.xy)) {
        if (i < internal) { i = 2u * i + 1u; continue; }
        uint k = i - internal;  // leaf k = the cell's k-th segment in drawing order
        if (k < range.y) {
          uvec2 seg = cell_segment(range.x + k);
          uint line = line_of_vertex(seg.x);
          // Segments of one line are consecutive: a line adds its colour once (thesis Fig. 4.7).
          if (line != last_line) {
            uvec4 props = line_props(line);
            if (segment_covers(seg.x, seg.y, p.xy, props)) {
              last_line = line;
              composite_under(acc, props.y);
              if (opaque(acc)) break;
            }
          }
        }
      }
      i = bvh_next(i);
    } while (i != 0u);
  }
  if (acc.a <= 0.0) discard;
  o_color = acc;
}
