// dyn_segments.comp.glsl — thesis §4.3.1 step 3, per kept vertex: the
// segment to the next kept vertex of its line (closed lines wrap to their
// start), with the kept neighbours for the common miter faces, unless both
// ends lie outside the same frustum plane. Appends to dyn_segment and counts
// the indirect draw.
layout(local_size_x = 256) in;

uint kept_pos(uint v) { return dyn_block[v / 256u] + dyn_scan[v]; }

void main() {
  uint k = gl_GlobalInvocationID.x;
  if (k >= kept) return;
  uint v = dyn_compact[k];
  uint line = uint(dyn_vertex(v).w);
  uint first = kept_pos(dyn_line_start(line));
  uint last = (line + 1u < u_line_count ? kept_pos(dyn_line_start(line + 1u)) : kept) - 1u;
  bool closed = dyn_prev_next(dyn_line_start(line)).x >= 0;
  uint next = k < last ? k + 1u : (closed ? first : NONE);
  if (next == NONE || next == k) return;
  uint prev = k > first ? k - 1u : (closed ? last : NONE);
  uint next2 = next < last ? next + 1u : (closed ? first : NONE);
  uint b = dyn_compact[next];
  if (((dyn_flags[v] & dyn_flags[b]) & 31u) != 0u) return;  // both outside one plane
  uint slot = atomicAdd(draw_count, 1u);
  dyn_segment[slot] = uvec4(v, b, prev == NONE ? NONE : dyn_compact[prev], next2 == NONE ? NONE : dyn_compact[next2]);
}
