// dyn_composite.frag.glsl — thesis §4.3.3 + §4.4.2: composite the pixel's
// list front to back in drawing order. Every line on the list is
// composited, however many: the list is walked once per line, each walk
// selecting the smallest order not yet composited (a line's entries share
// its order; its coverage is the largest over them), so no local array caps
// the count. Compositing stops at the first line that makes the pixel
// opaque (early termination: nothing below it can show). The walks run as
// one flat loop (llvmpipe ran a nested form's outer loop only once); its
// bound, kCompositeSteps list entries read, is far above what a pixel needs
// (n lines on a pixel read about n^2 entries); a pixel that reaches it is
// counted (`composite_truncated`, render --stats) and keeps what it has.
layout(location = 0) out vec4 o_color;

const int kCompositeSteps = 1 << 20;

void main() {
  uint pixel = uint(gl_FragCoord.y) * uint(u_viewport.x) + uint(gl_FragCoord.x);
  uint head = dyn_head[pixel];
  if (head == NONE) discard;
  vec4 acc = vec4(0.0);
  uint lo = 0u;  // orders below this are composited
  uint best = NONE, best_line = 0u;
  float best_cov = 0.0;
  uint n = head;
  bool finished = false;
  for (int step = 0; step < kCompositeSteps; ++step) {
    if (n == NONE) {  // a walk ends: composite the line it selected
      if (best == NONE) {
        finished = true;
        break;
      }
      vec4 c = unpackUnorm4x8(dyn_line_props(best_line).y);
      c.a *= best_cov;
      acc += (1.0 - acc.a) * vec4(c.rgb * c.a, c.a);
      if (acc.a >= 1.0) {
        finished = true;
        break;
      }
      lo = best + 1u;
      best = NONE;
      best_cov = 0.0;
      n = head;
      continue;
    }
    uvec4 e = dyn_node[n];
    n = e.z;
    if (e.x < lo) continue;
    float cov = uintBitsToFloat(e.w);
    if (e.x < best) {
      best = e.x;
      best_line = e.y;
      best_cov = cov;
    } else if (e.x == best) {
      best_cov = max(best_cov, cov);
    }
  }
  if (!finished) atomicAdd(composite_truncated, 1u);
  if (acc.a <= 0.0) discard;
  o_color = acc;
}
