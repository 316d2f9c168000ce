// lod_mask.comp.glsl — after dyn_cull, per dynamic vertex: the vertices of
// lines drawn from their LOD segments leave the vertex chains (kept bit and
// scan flag cleared; the frustum outcode stays for lod_segments).
layout(local_size_x = 256) in;

void main() {
  uint v = gl_GlobalInvocationID.x;
  if (v >= u_vertex_count) return;
  if (lod_line_drawn[uint(dyn_vertex(v).w)] == 0u) return;
  dyn_flags[v] &= 0x7fffffffu;
  dyn_scan[v] = 0u;
}
