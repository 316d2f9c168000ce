// dash.glsl — dashed lines (formats/SPEC.md "Dashed lines"): the on/off rule
// of prep::dash_on and prep::dash_signed_distance (libprep/evaluate/dash.cpp)
// in float, over the table prep::dash_gpu_words writes: [0] = layer count N;
// layer L: [1 + 3L] = first word of its pattern, [2 + 3L] = its length (0:
// solid), [3 + 3L] = the period (f32 bits); the patterns as f32 bits. Bound
// as an SSBO in both binding modes (bindings.hpp DECAL_SSBO_DASH_TABLE), like
// the static lines' per-vertex along-line distances.
layout(std430, binding = DECAL_SSBO_DASH_TABLE) readonly buffer DashTable { uint d_dash[]; };
#ifdef DECAL_LINES
// per static-line vertex: the line's length from its first vertex, metres
layout(std430, binding = DECAL_SSBO_DASH_VERTEX) readonly buffer DashVertex { float d_dash_vertex[]; };
#endif

bool dash_solid(uint layer) { return layer >= d_dash[0] || d_dash[2u + 3u * layer] == 0u; }

// Distance from along-line position s to the nearest on/off boundary of the
// layer's pattern; `on`: s lies in an "on" interval [a, a + on) of
// r = s - P floor(s / P). Solid layers: on.
float dash_signed(uint layer, float s, out bool on) {
  on = true;
  if (dash_solid(layer)) return 3.0e38;
  uint first = d_dash[1u + 3u * layer], n = d_dash[2u + 3u * layer];
  float period = uintBitsToFloat(d_dash[3u + 3u * layer]);
  float r = s - period * floor(s / period);
  if (!(r >= 0.0 && r < period)) r = 0.0;
  float a = 0.0;
  for (uint i = 0u; i < n; ++i) {
    float len = uintBitsToFloat(d_dash[first + i]);
    if (r < a + len || i + 1u == n) {
      on = (i & 1u) == 0u;
      float d = min(r - a, a + len - r);
      return on ? d : -d;
    }
    a += len;
  }
  return 3.0e38;
}
