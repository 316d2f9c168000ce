// dyn_cull.comp.glsl — thesis §4.3.1 "Update Indices", step 1, per vertex:
// project to the pixel grid, keep a vertex unless it lands on the same pixel
// as its predecessor (line starts and open-line ends are always kept), and
// record its frustum outcode for segment culling.
layout(local_size_x = 256) in;

uint outcode(vec4 c) {
  uint o = 0u;
  if (c.x < -c.w) o |= 1u;
  if (c.x > c.w) o |= 2u;
  if (c.y < -c.w) o |= 4u;
  if (c.y > c.w) o |= 8u;
  if (c.w <= 0.0) o |= 16u;  // behind the eye
  return o;
}

ivec2 pixel_of(vec4 c) { return ivec2(floor((c.xy / c.w * 0.5 + 0.5) * u_viewport)); }

void main() {
  uint v = gl_GlobalInvocationID.x;
  if (v >= u_vertex_count) return;
  vec4 c = u_view_proj * vec4(dyn_position(v), 1.0);
  ivec2 pn = dyn_prev_next(v);
  uint line = uint(dyn_vertex(v).w);
  bool keep = v == dyn_line_start(line) || pn.x < 0 || pn.y < 0 || c.w <= 0.0;
  if (!keep) {
    vec4 cp = u_view_proj * vec4(dyn_position(uint(pn.x)), 1.0);
    keep = cp.w <= 0.0 || pixel_of(cp) != pixel_of(c);
  }
  dyn_flags[v] = (keep ? 0x80000000u : 0u) | outcode(c);
  dyn_scan[v] = keep ? 1u : 0u;
}
