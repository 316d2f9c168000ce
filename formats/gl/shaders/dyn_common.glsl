// dyn_common.glsl — per-frame buffers of the dynamic-line update (thesis
// §4.3, Fig. 4.3) and helpers shared by its passes. Bindings: the
// DECAL_SSBO_* of formats/gl/include/decal/gl/bindings.hpp. Positions are anchor-relative metres.

const uint NONE = 0xffffffffu;
const float QUANTUM_M = 0.001;

// per vertex: bit 31 keep, bits 0..5 frustum outcode
layout(std430, binding = DECAL_SSBO_DYN_FLAGS) buffer DynFlags { uint dyn_flags[]; };
// per vertex: keep flag, then exclusive prefix within its block
layout(std430, binding = DECAL_SSBO_DYN_SCAN) buffer DynScan { uint dyn_scan[]; };
// per block of 256 vertices: kept count, then exclusive prefix
layout(std430, binding = DECAL_SSBO_DYN_BLOCKS) buffer DynBlocks { uint dyn_block[]; };
// kept vertex indices in original order (stream compaction result)
layout(std430, binding = DECAL_SSBO_DYN_COMPACT) buffer DynCompact { uint dyn_compact[]; };
// per visible segment: (vertex a, vertex b, kept predecessor of a, kept successor of b)
layout(std430, binding = DECAL_SSBO_DYN_SEGMENTS) buffer DynSegments { uvec4 dyn_segment[]; };
// DrawArraysIndirectCommand (segment count as points), then counters
layout(std430, binding = DECAL_SSBO_DYN_COUNTERS) buffer DynCounters {
  uint draw_count; uint draw_instances; uint draw_first; uint draw_base;
  uint kept; uint list_nodes; uint list_capacity; uint n_vertices;
  uint composite_truncated;  // pixels whose composite reached its step bound
};
// per pixel: head of its linked list; per node: (order, line, next, 0)
layout(std430, binding = DECAL_SSBO_DYN_HEADS) buffer DynHeads { uint dyn_head[]; };
layout(std430, binding = DECAL_SSBO_DYN_NODES) buffer DynNodes { uvec4 dyn_node[]; };

// Dashes (dyn_dash.comp.glsl), n = u_vertex_count, B = its blocks of 256:
// per kept position k: [0, n) the screen length of the segment to the next
// kept vertex of its line, [n, 2n) the segmented prefix within its block,
// [2n, 3n) 1 where a line starts at or before k in its block; per vertex v:
// [3n, 4n) the line's screen length from its start to v (kept vertices);
// per block: [4n, 4n + 2B) (sum, line start seen), [4n + 2B, 4n + 3B) carry.
layout(std430, binding = DECAL_SSBO_DYN_DASH) buffer DynDash { float dyn_dash[]; };

uniform ivec2 u_anchor_q;      // quanta
uniform mat4 u_view_proj;      // anchor-relative world -> clip
uniform vec2 u_viewport;
uniform uint u_vertex_count;
uniform uint u_line_count;

uint dash_vertex_at(uint v) { return 3u * u_vertex_count + v; }
uniform float u_near;  // clip w of the near plane (perspective); 0: orthographic

// Pixel position of clip coordinates.
vec2 screen_of(vec4 c) { return (c.xy / c.w * 0.5 + 0.5) * u_viewport; }
// Screen length, pixels, of the part of the segment between clip points ca
// and cb that lies in front of the near plane (clip coordinates are linear
// along the segment).
float screen_length(vec4 ca, vec4 cb) {
  if (ca.w < u_near && cb.w < u_near) return 0.0;
  if (ca.w < u_near) ca = mix(ca, cb, (u_near - ca.w) / (cb.w - ca.w));
  else if (cb.w < u_near) cb = mix(cb, ca, (u_near - cb.w) / (ca.w - cb.w));
  return length(screen_of(cb) - screen_of(ca));
}

vec3 dyn_position(uint v) {
  ivec4 q = dyn_vertex(v);
  return vec3(vec2(q.xy - u_anchor_q) * QUANTUM_M, float(q.z) * QUANTUM_M);
}
