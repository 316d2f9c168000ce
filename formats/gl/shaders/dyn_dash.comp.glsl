// dyn_dash.comp.glsl — the along-line screen distance of dynamic lines
// (formats/SPEC.md "Dashed lines"): per frame, each kept vertex's line
// length in pixels from the line's start, the prefix sum over its line of
// the kept segments' projected lengths (the segments of
// dyn_segments.comp.glsl, frustum-culled ones included, each cut at the
// near plane). A segmented scan over the kept positions k (a line's kept
// vertices are consecutive in dyn_compact), in the three dispatches of
// dyn_scan.comp.glsl, selected by a define:
//   DASH_LOCAL   per block of 256: lengths, segmented inclusive prefix in
//                place, block (sum, line start seen) out
//   DASH_BLOCKS  one invocation: the carry into each block
//   DASH_APPLY   kept vertex -> dyn_dash[dash_vertex_at(v)], the exclusive prefix
// dynamic_cpu.cpp sums the same lengths in double.
layout(local_size_x = 256) in;
shared float s_val[256];
shared uint s_flag[256];

uint kept_pos(uint v) { return dyn_block[v / 256u] + dyn_scan[v]; }
vec4 clip_of(uint v) { return u_view_proj * vec4(dyn_position(v), 1.0); }

void main() {
  uint n = u_vertex_count, blocks = (n + 255u) / 256u;
  uint k = gl_GlobalInvocationID.x, i = gl_LocalInvocationID.x;
#if defined(DASH_LOCAL)
  float len = 0.0;
  uint head = 0u;
  if (k < kept) {
    uint v = dyn_compact[k];
    uint line = uint(dyn_vertex(v).w);
    uint first = kept_pos(dyn_line_start(line));
    uint last = (line + 1u < u_line_count ? kept_pos(dyn_line_start(line + 1u)) : kept) - 1u;
    head = k == first ? 1u : 0u;
    if (k < last) len = screen_length(clip_of(v), clip_of(dyn_compact[k + 1u]));
    dyn_dash[k] = len;
  }
  // Segmented inclusive scan (Hillis–Steele): (F, V) after (F', V') is
  // (F' | F, F ? V : V' + V).
  s_val[i] = len;
  s_flag[i] = head;
  barrier();
  for (uint off = 1u; off < 256u; off <<= 1) {
    float add = i >= off ? s_val[i - off] : 0.0;
    uint f = i >= off ? s_flag[i - off] : 0u;
    barrier();
    if (s_flag[i] == 0u) s_val[i] += add;
    s_flag[i] |= f;
    barrier();
  }
  if (k < kept) {
    dyn_dash[n + k] = s_val[i];
    dyn_dash[2u * n + k] = float(s_flag[i]);
  }
  if (i == 255u) {
    dyn_dash[4u * n + 2u * gl_WorkGroupID.x] = s_val[255];
    dyn_dash[4u * n + 2u * gl_WorkGroupID.x + 1u] = float(s_flag[255]);
  }
#elif defined(DASH_BLOCKS)
  if (k != 0u) return;
  float carry = 0.0;
  for (uint b = 0u; b < blocks; ++b) {
    dyn_dash[4u * n + 2u * blocks + b] = carry;
    float sum = dyn_dash[4u * n + 2u * b];
    carry = dyn_dash[4u * n + 2u * b + 1u] != 0.0 ? sum : carry + sum;
  }
#elif defined(DASH_APPLY)
  if (k >= kept) return;
  float incl = dyn_dash[n + k];
  if (dyn_dash[2u * n + k] == 0.0) incl += dyn_dash[4u * n + 2u * blocks + gl_WorkGroupID.x];
  dyn_dash[dash_vertex_at(dyn_compact[k])] = incl - dyn_dash[k];
#endif
}
