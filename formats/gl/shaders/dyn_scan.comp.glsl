// dyn_scan.comp.glsl — stream compaction of the kept vertices (thesis §4.3.1
// used Thrust unique(); this is our own GLSL): a work-efficient exclusive
// scan in three dispatches selected by a define:
//   SCAN_LOCAL   per block of 256: exclusive prefix in place, block total out
//   SCAN_BLOCKS  one work group: exclusive prefix of the block totals, kept count
//   SCATTER      kept vertex v -> dyn_compact[block prefix + local prefix]
layout(local_size_x = 256) in;
shared uint s_sum[256];

// Inclusive Hillis–Steele scan of s_sum; returns this invocation's value.
uint scan_shared(uint x) {
  uint i = gl_LocalInvocationID.x;
  s_sum[i] = x;
  barrier();
  for (uint off = 1u; off < 256u; off <<= 1) {
    uint add = i >= off ? s_sum[i - off] : 0u;
    barrier();
    s_sum[i] += add;
    barrier();
  }
  return s_sum[i];
}

void main() {
  uint i = gl_LocalInvocationID.x;
#if defined(SCAN_LOCAL)
  uint v = gl_GlobalInvocationID.x;
  uint x = v < u_vertex_count ? dyn_scan[v] : 0u;
  uint incl = scan_shared(x);
  if (v < u_vertex_count) dyn_scan[v] = incl - x;
  if (i == 255u) dyn_block[gl_WorkGroupID.x] = incl;
#elif defined(SCAN_BLOCKS)
  uint blocks = (u_vertex_count + 255u) / 256u;
  uint carry = 0u;
  for (uint base = 0u; base < blocks; base += 256u) {
    uint b = base + i;
    uint x = b < blocks ? dyn_block[b] : 0u;
    uint incl = scan_shared(x);
    if (b < blocks) dyn_block[b] = carry + incl - x;
    uint total = s_sum[255];
    barrier();
    carry += total;
  }
  if (i == 0u) kept = carry;
#elif defined(SCATTER)
  uint v = gl_GlobalInvocationID.x;
  if (v < u_vertex_count && (dyn_flags[v] & 0x80000000u) != 0u)
    dyn_compact[dyn_block[gl_WorkGroupID.x] + dyn_scan[v]] = v;
#endif
}
