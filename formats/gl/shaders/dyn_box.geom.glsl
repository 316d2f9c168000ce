// dyn_box.geom.glsl — thesis §4.3.2 "3D Segment Boxes": a box around each
// segment, as wide as the line's pixel width scaled at its farther end
// (Eq. 4.1/4.2, plus a pixel of margin), as high as the terrain range plus
// an offset, joined to the neighbouring boxes of the same line by common
// miter faces (Fig. 4.4b); open ends extend by half the width for the caps.
// Emitted as six quads (a strip per face) for robustness over the 14-index
// strip of Evans et al.
layout(points) in;
layout(triangle_strip, max_vertices = 24) out;
flat in uint v_seg[];
flat out uvec4 g_seg;
uniform float u_zmin, u_zmax;  // terrain range, metres

vec2 face_vector(vec2 n_here, vec2 n_other, float hw) {
  vec2 m = n_here + n_other;
  if (dot(m, m) < 1e-12) return n_here * hw;
  m = normalize(m);
  return m * (hw / max(dot(m, n_here), 0.1));
}

void emit(vec3 p) {
  g_seg = dyn_segment[v_seg[0]];
  gl_Position = u_view_proj * vec4(p, 1.0);
  EmitVertex();
}
void quad(vec3 a, vec3 b, vec3 c, vec3 d) {
  emit(a); emit(b); emit(d); emit(c);
  EndPrimitive();
}

void main() {
  uvec4 s = dyn_segment[v_seg[0]];
  vec3 a = dyn_position(s.x), b = dyn_position(s.y);
  uint line = uint(dyn_vertex(s.x).w);
  uvec4 props = dyn_line_props(line);
  float mpp = max(metres_per_pixel(a), metres_per_pixel(b));
  float hw = max(uintBitsToFloat(props.x) * mpp, dyn_min_half_width(line)) * 1.25 + 1.25 * mpp;
  vec2 d = b.xy - a.xy;
  float len = length(d);
  d = len > 0.0 ? d / len : vec2(1.0, 0.0);
  vec2 n = vec2(-d.y, d.x);
  vec2 pa = a.xy, pb = b.xy, ca, cb;
  if (s.z != NONE) {
    vec2 dp = a.xy - dyn_position(s.z).xy;
    dp = length(dp) > 0.0 ? normalize(dp) : d;
    ca = face_vector(n, vec2(-dp.y, dp.x), hw);
  } else {
    pa -= d * hw;
    ca = n * hw;
  }
  if (s.w != NONE) {
    vec2 dn = dyn_position(s.w).xy - b.xy;
    dn = length(dn) > 0.0 ? normalize(dn) : d;
    cb = face_vector(n, vec2(-dn.y, dn.x), hw);
  } else {
    pb += d * hw;
    cb = n * hw;
  }
  float lo = u_zmin - 1.0, hi = u_zmax + 1.0;
  vec3 a0 = vec3(pa - ca, lo), a1 = vec3(pa + ca, lo), b0 = vec3(pb - cb, lo), b1 = vec3(pb + cb, lo);
  vec3 A0 = vec3(pa - ca, hi), A1 = vec3(pa + ca, hi), B0 = vec3(pb - cb, hi), B1 = vec3(pb + cb, hi);
  quad(a0, a1, b1, b0);  // bottom
  quad(A0, B0, B1, A1);  // top
  quad(a0, b0, B0, A0);  // right side
  quad(a1, A1, B1, b1);  // left side
  quad(a0, A0, A1, a1);  // face at a
  quad(b0, b1, B1, B0);  // face at b
}
