// dyn_composite.frag.glsl — thesis §4.3.3 + §4.4.2: sort the pixel's list
// by drawing order and composite front to back. The sort is an insertion
// sort into a small local array while walking the list; entries of a line
// already held are skipped (orders are unique per line, so repeats of the
// same line carry the same order), and the array is cut after the first
// opaque entry, since nothing below an opaque line can show (early
// termination: the rest of the list is never sorted in).
layout(location = 0) out vec4 o_color;

const int K = 8;

void main() {
  uint pixel = uint(gl_FragCoord.y) * uint(u_viewport.x) + uint(gl_FragCoord.x);
  uint head = dyn_head[pixel];
  if (head == NONE) discard;
  // Initialised: reading an unset element would be undefined, and the
  // compiler may exploit that (observed with llvmpipe).
  uint orders[K];
  uint lines[K];
  float covs[K];  // a line's coverage: the largest over its entries
  for (int i = 0; i < K; ++i) {
    orders[i] = NONE;
    lines[i] = 0u;
    covs[i] = 0.0;
  }
  int count = 0;
  uint n = head;
  for (int guard = 0; guard < 65536 && n != NONE; ++guard) {
    uvec4 e = dyn_node[n];
    n = e.z;
    // position of e.x in the sorted prefix
    int pos = count;
    int repeat = -1;
    for (int i = 0; i < K; ++i) {
      if (i >= count) break;
      if (orders[i] == e.x) { repeat = i; break; }
      if (orders[i] > e.x) { pos = i; break; }
    }
    float cov = uintBitsToFloat(e.w);
    if (repeat >= 0) {
      covs[repeat] = max(covs[repeat], cov);
      continue;
    }
    if (pos >= K) continue;
    // shift down (dropping the last when full) and insert
    int last = min(count, K - 1);
    for (int i = K - 1; i > 0; --i) {
      if (i > last || i <= pos) continue;
      orders[i] = orders[i - 1];
      lines[i] = lines[i - 1];
      covs[i] = covs[i - 1];
    }
    orders[pos] = e.x;
    lines[pos] = e.y;
    covs[pos] = cov;
    count = min(count + 1, K);
    // cut after the first opaque entry
    for (int i = 0; i < K; ++i) {
      if (i >= count) break;
      if (unpackUnorm4x8(dyn_line_props(lines[i]).y).a * covs[i] >= 1.0) { count = i + 1; break; }
    }
  }
  // Composited with constant indices: llvmpipe (Mesa 22.3) miscompiles this
  // loop with a dynamic index into the local arrays (only the first entry
  // was applied), so the steps are spelled out.
  vec4 acc = vec4(0.0);
#define DECAL_COMPOSITE_STEP(i) \
  if (count > i) { \
    vec4 c = unpackUnorm4x8(dyn_line_props(lines[i]).y); \
    c.a *= covs[i]; \
    acc += (1.0 - acc.a) * vec4(c.rgb * c.a, c.a); \
  }
  DECAL_COMPOSITE_STEP(0) DECAL_COMPOSITE_STEP(1) DECAL_COMPOSITE_STEP(2) DECAL_COMPOSITE_STEP(3)
  DECAL_COMPOSITE_STEP(4) DECAL_COMPOSITE_STEP(5) DECAL_COMPOSITE_STEP(6) DECAL_COMPOSITE_STEP(7)
  if (acc.a <= 0.0) discard;
  o_color = acc;
}
