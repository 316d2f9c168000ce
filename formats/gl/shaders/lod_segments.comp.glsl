// lod_segments.comp.glsl — per selected LOD segment: the segment between
// its points' dynamic vertices, with the dynamic vertices of the visible
// neighbours for the common miter faces (a closed ring wraps at its ends,
// an open line's ends have none), unless both ends lie outside the same
// frustum plane. Appends to dyn_segment beside dyn_segments.comp.glsl's and
// counts the indirect draw.
layout(local_size_x = 256) in;

uint vertex_of(uint p) { return p == NONE ? NONE : lod_map[p].x; }

void main() {
  uint k = gl_GlobalInvocationID.x;
  if (k >= lod_selected) return;
  uvec4 g = lod_segment[lod_visible[k]];
  uvec2 ma = lod_map[g.x], mb = lod_map[g.y];
  uint va = ma.x, vb = mb.x;
  if (va == NONE || vb == NONE) return;
  if (((dyn_flags[va] & dyn_flags[vb]) & 31u) != 0u) return;  // both outside one plane
  uint pa = ma.y == NONE ? lod_link[g.x].x : (ma.y == g.x ? NONE : lod_link[ma.y].x);
  uint nb = mb.y == NONE ? lod_link[g.y].y : (mb.y == g.y ? NONE : lod_link[mb.y].y);
  uint pv = va == vb ? NONE : vertex_of(pa);
  uint nv = va == vb ? NONE : vertex_of(nb);
  uint slot = atomicAdd(draw_count, 1u);
  dyn_segment[slot] = uvec4(va, vb, pv, nv);
  atomicAdd(lod_drawn, 1u);
}
